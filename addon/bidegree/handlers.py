"""Blender's application handlers, wired to :mod:`bidegree_blender.modifier`.

* ``depsgraph_update_pre`` / ``_post`` and ``frame_change_pre`` / ``_post``: before an
  evaluation the visible bidegree modifiers are switched off (the evaluation gives their
  cages), after it the cages are read, the modifiers switched back on and the surfaces
  written; the depsgraph's second pass shows them. During a render the same happens with the
  render toggles and the render surfaces, frame by frame.
* ``load_post``, ``undo_post`` / ``redo_post``: the plans refer to data that was replaced.
* ``save_pre``: render surfaces are not saved (a file opened without the extension renders the
  viewport surface; with it, renders make them again).
"""

from __future__ import annotations

import sys
import threading
from typing import Any

import bpy
from bidegree_blender import modifier
from bpy.app.handlers import persistent

#: Above this many estimated result faces, a GUI update says so in the status bar first.
PROGRESS_FACES = 1_000_000
#: Read only the cages expected to change (the GUI: updates that touch no bidegree object, a
#: selection, cost bidegree nothing; an object that changed unexpectedly gets its surface one
#: event-loop turn later, from :func:`_follow_up`). Scripts and renders in background mode read
#: every visible cage, so the surface is there when ``view_layer.update()`` returns.
PREDICT = not bpy.app.background

_render = {"active": False, "warned": False}


def _say_long_work() -> bool:
    """In the GUI, announce an update whose result is large (status bar text and a progress
    cursor) before the work blocks; returns whether anything was announced."""
    if bpy.app.background:
        return False
    faces = modifier.estimated_faces()
    wm = bpy.context.window_manager
    if faces < PROGRESS_FACES or wm is None or not wm.windows:
        return False
    wm.progress_begin(0, 1)
    wm.progress_update(0)
    workspace = getattr(bpy.context, "workspace", None)
    if workspace is not None:
        workspace.status_text_set(f"bidegree: subdividing to about {faces:,} faces ...")
    return True


def _end_long_work() -> None:
    wm = bpy.context.window_manager
    wm.progress_end()
    workspace = getattr(bpy.context, "workspace", None)
    if workspace is not None:
        workspace.status_text_set(None)


def _viewport_objects(scene: bpy.types.Scene) -> list[bpy.types.Object]:
    """The objects whose cages this evaluation reads (see :data:`PREDICT`)."""
    if PREDICT:
        return modifier.expected_objects(scene)
    return modifier.viewport_objects(scene)


def _follow_up() -> None:
    """Timer: evaluate once more the objects that changed without their cages being read."""
    for ob in modifier.stale_objects():
        ob.update_tag()


def _end_read(depsgraph: bpy.types.Depsgraph) -> None:
    announced = _say_long_work()
    try:
        done = modifier.end_read(depsgraph)
    finally:
        if announced:
            _end_long_work()
    if PREDICT and depsgraph.mode == "VIEWPORT" and modifier.note_changes(depsgraph, done):
        if not bpy.app.timers.is_registered(_follow_up):
            bpy.app.timers.register(_follow_up, first_interval=0.0)


@persistent
def on_depsgraph_update_pre(scene: bpy.types.Scene, *_args: Any) -> None:
    """An evaluation starts: switch bidegree modifiers off for their cage read."""
    if threading.current_thread() is threading.main_thread():
        modifier.begin_read(_viewport_objects(scene))


@persistent
def on_depsgraph_update_post(scene: bpy.types.Scene, depsgraph: bpy.types.Depsgraph) -> None:
    """The cages were evaluated: surfaces in, modifiers back on; delete unused holders."""
    if modifier.busy() or depsgraph.mode != "VIEWPORT":
        return
    _end_read(depsgraph)
    modifier.cleanup()


@persistent
def on_frame_change_pre(scene: bpy.types.Scene, *_args: Any) -> None:
    """A frame is about to be evaluated, for a render or the viewport."""
    if _render["active"]:
        if not modifier.render_writes_allowed(scene):
            if not _render["warned"]:
                _render["warned"] = True
                print(
                    "bidegree: rendering in a background thread without Render > Lock "
                    "Interface: render levels are not computed, the viewport surface renders",
                    file=sys.stderr,
                )
            return
        modifier.begin_read(modifier.render_objects(scene), render=True)
    elif threading.current_thread() is threading.main_thread():
        modifier.begin_read(_viewport_objects(scene))


@persistent
def on_frame_change_post(scene: bpy.types.Scene, depsgraph: bpy.types.Depsgraph) -> None:
    """The frame's cages were evaluated: surfaces in, modifiers back on."""
    if not modifier.busy() and depsgraph is not None:
        _end_read(depsgraph)


@persistent
def on_render_init(*_args: Any) -> None:
    """A render (still or animation) starts."""
    _render["active"] = True
    _render["warned"] = False


@persistent
def on_render_done(*_args: Any) -> None:
    """The render finished or was cancelled: switch back anything still switched off."""
    _render["active"] = False
    modifier.end_read(None)


@persistent
def on_load_post(*_args: Any) -> None:
    """A new file: plans and statuses refer to the previous one's data."""
    modifier.reset()
    modifier.cleanup()


@persistent
def on_undo_post(*_args: Any) -> None:
    """Undo/redo replaced meshes behind the cache's back: everything updates again."""
    modifier.reset()


@persistent
def on_save_pre(*_args: Any) -> None:
    """Render surfaces are made by renders; saving them would only grow the file."""
    for ob in bpy.data.objects:
        if ob.get(modifier.HOLDER_TAG) == modifier.RENDER:
            modifier.invalidate(ob)
    modifier.cleanup()


_HANDLERS = (
    ("depsgraph_update_pre", on_depsgraph_update_pre),
    ("depsgraph_update_post", on_depsgraph_update_post),
    ("frame_change_pre", on_frame_change_pre),
    ("frame_change_post", on_frame_change_post),
    ("render_init", on_render_init),
    ("render_complete", on_render_done),
    ("render_cancel", on_render_done),
    ("load_post", on_load_post),
    ("undo_post", on_undo_post),
    ("redo_post", on_undo_post),
    ("save_pre", on_save_pre),
)


def register() -> None:
    """Install the handlers (idempotent)."""
    for name, fn in _HANDLERS:
        lst = getattr(bpy.app.handlers, name)
        if fn not in lst:
            lst.append(fn)


def unregister() -> None:
    """Remove the handlers and the timer, forget every cached plan."""
    for name, fn in _HANDLERS:
        lst = getattr(bpy.app.handlers, name)
        while fn in lst:
            lst.remove(fn)
    if bpy.app.timers.is_registered(_follow_up):
        bpy.app.timers.unregister(_follow_up)
    modifier.reset()
