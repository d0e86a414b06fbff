"""Blender's application handlers, wired to :mod:`bidegree_blender.modifier`.

* ``depsgraph_update_post`` and ``frame_change_post`` (viewport): the bidegree objects that
  changed get new surfaces (the depsgraph's second pass shows them); duplicates get their own
  holders; holders nothing uses are deleted.
* ``frame_change_pre`` / ``frame_change_post`` during a render: render cages in, render
  surfaces out, frame by frame (see :func:`bidegree_blender.modifier.begin_render_frame`).
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

_render = {"active": False, "warned": False}


def _say_long_work(scene: bpy.types.Scene, objects: list[bpy.types.Object]) -> bool:
    """In the GUI, announce an update whose result is large (status bar text and a progress
    cursor) before the work blocks; returns whether anything was announced."""
    if bpy.app.background:
        return False
    faces = 0
    for ob in objects:
        for mod in modifier.bidegree_modifiers(ob):
            try:
                levels = modifier.options_of(mod).levels
            except Exception:  # a bad setting is reported by the update itself
                continue
            faces += len(ob.data.polygons) * 4 ** min(levels, 16)
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


def _update_viewport(scene: bpy.types.Scene, depsgraph: bpy.types.Depsgraph) -> None:
    objects = modifier.changed_objects(depsgraph)
    for ob in modifier.pending_objects(scene):
        if ob not in objects:
            objects.append(ob)
    if not objects:
        return
    announced = _say_long_work(scene, objects)
    try:
        modifier.update_viewport(depsgraph, objects)
    finally:
        if announced:
            _end_long_work()


@persistent
def on_depsgraph_update_post(scene: bpy.types.Scene, depsgraph: bpy.types.Depsgraph) -> None:
    """Edits, setting changes, new or duplicated modifiers: update those surfaces."""
    if modifier.busy() or depsgraph.mode != "VIEWPORT":
        return
    _update_viewport(scene, depsgraph)
    if any(
        isinstance(getattr(u.id, "original", u.id), (bpy.types.Collection, bpy.types.Scene))
        for u in depsgraph.updates
    ):
        modifier.cleanup()  # objects or modifiers removed


@persistent
def on_frame_change_pre(scene: bpy.types.Scene, *_args: Any) -> None:
    """A render frame is about to be evaluated: switch bidegree off for its cage read."""
    if _render["active"] and not modifier.busy():
        if not modifier.render_writes_allowed(scene) and not _render["warned"]:
            _render["warned"] = True
            print(
                "bidegree: rendering in a background thread without Render > Lock Interface: "
                "render levels are not computed, the viewport surface is rendered",
                file=sys.stderr,
            )
        modifier.begin_render_frame(scene)


@persistent
def on_frame_change_post(scene: bpy.types.Scene, depsgraph: bpy.types.Depsgraph) -> None:
    """A frame was evaluated: render surfaces for a render, else the viewport's."""
    if modifier.busy() or depsgraph is None:
        return
    if depsgraph.mode == "RENDER":
        modifier.end_render_frame(depsgraph)
    elif threading.current_thread() is threading.main_thread():
        _update_viewport(scene, depsgraph)


@persistent
def on_render_init(*_args: Any) -> None:
    """A render (still or animation) starts."""
    _render["active"] = True
    _render["warned"] = False


@persistent
def on_render_done(*_args: Any) -> None:
    """The render finished or was cancelled: switch back anything still switched off."""
    _render["active"] = False
    modifier.end_render_frame(None)


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
    """Remove the handlers and forget every cached plan."""
    for name, fn in _HANDLERS:
        lst = getattr(bpy.app.handlers, name)
        while fn in lst:
            lst.remove(fn)
    modifier.reset()
