"""Live result mechanism: explicit ``update(obj)``, depsgraph/render handlers, GUI timer.

* ``update(obj)`` is the single entry point that (re)computes an object's live
  result; everything else ends up calling it.  It works in headless ``bpy``
  (where timers never fire and handlers only fire when something evaluates the
  depsgraph).
* ``depsgraph_update_post`` marks enabled objects whose geometry changed as
  dirty.  In the GUI a timer processes them shortly after (outside the
  depsgraph callback); in background mode they are processed right away.
* A re-entrancy guard (``_busy``) drops the depsgraph updates caused by our
  own writes, and :class:`bidegree_blender.LiveCache` turns an update without
  any real change into a no-op, so there is no update loop.
* ``render_pre`` swaps each result to a render-level mesh (computed through a
  separate cached plan), ``render_post`` / ``render_cancel`` swap it back.
"""

from __future__ import annotations

import threading
from typing import Any

import bpy
from bidegree_blender import LiveCache, Settings, objects
from bpy.app.handlers import persistent

import bidegree

#: One plan cache for the whole session, keyed by (object session uid, variant).
CACHE = LiveCache()

_busy = False
_dirty: set[str] = set()
_timer_registered = False
_render_swaps: dict[str, str] = {}

#: Above this many estimated result faces, progress is reported in the GUI.
PROGRESS_FACES = 500_000


def settings_of(obj: bpy.types.Object, *, render: bool = False) -> Settings:
    """The :class:`bidegree_blender.Settings` of ``obj`` (viewport or render levels)."""
    p = obj.bidegree
    return Settings(
        degree=int(p.degree),
        levels=int(p.render_levels if render else p.levels),
        output=str(p.output),
        boundary=str(p.boundary),
        use_creases=bool(p.use_creases),
        rules=str(p.rules),
        limit=bool(p.use_limit),
        normals=bool(p.use_limit_normals),
        # Adaptive subdivision is a viewport option: renders stay uniform.
        adaptive=bool(p.adaptive) and not render,
        tolerance=float(p.tolerance),
    )


def _set_if_changed(props: Any, name: str, value: Any) -> None:
    """Assign an RNA property only when it differs (every write triggers a depsgraph update)."""
    if getattr(props, name) != value:
        setattr(props, name, value)


def _progress_begin(context: bpy.types.Context, text: str) -> bool:
    wm = getattr(context, "window_manager", None)
    if bpy.app.background or wm is None or not wm.windows:
        return False
    wm.progress_begin(0, 100)
    wm.progress_update(10)
    workspace = getattr(context, "workspace", None)
    if workspace is not None:
        workspace.status_text_set(text)
    return True


def _progress_end(context: bpy.types.Context) -> None:
    wm = context.window_manager
    wm.progress_update(100)
    wm.progress_end()
    workspace = getattr(context, "workspace", None)
    if workspace is not None:
        workspace.status_text_set(None)


def _estimated_faces(obj: bpy.types.Object, settings: Settings) -> int:
    """Rough face count of the result: cage faces * 4**levels (for the progress decision only)."""
    data = obj.data
    cage_faces = len(data.polygons) if isinstance(data, bpy.types.Mesh) else 0
    return cage_faces * 4 ** min(settings.levels, 16)


def update(
    obj: bpy.types.Object,
    *,
    depsgraph: bpy.types.Depsgraph | None = None,
    raise_errors: bool = False,
) -> str:
    """(Re)compute the live result of ``obj`` now and return what was done.

    Returns one of ``"built"``, ``"reused"``, ``"rewritten"``, ``"unchanged"``,
    ``"disabled"`` or ``"error"``.  Errors (bad mesh, memory budget, ...) are
    recorded in ``obj.bidegree.last_error`` and leave the source object and the
    previous result untouched; with ``raise_errors`` they are re-raised.
    """
    global _busy
    props = obj.bidegree
    if not props.enabled or obj.type != "MESH":
        return "disabled"
    if _busy:
        return "busy"
    _busy = True
    context = bpy.context
    settings = settings_of(obj)
    progress = False
    try:
        if _estimated_faces(obj, settings) > PROGRESS_FACES:
            progress = _progress_begin(context, f"bidegree: subdividing {obj.name} ...")
        try:
            if depsgraph is None:
                depsgraph = context.evaluated_depsgraph_get()
            result = props.result
            created = result is None or result.name not in bpy.data.objects
            if created:
                # Validate before creating anything: compute into a scratch mesh first.
                scratch = bpy.data.meshes.new(f"{obj.name}.bidegree")
                try:
                    report = objects.update_result(
                        CACHE, obj, None, settings, depsgraph=depsgraph, mesh=scratch
                    )
                except BaseException:
                    bpy.data.meshes.remove(scratch)
                    raise
                result = objects.ensure_result_object(obj, None, scratch)
                props.result = result
            else:
                mine = objects.ensure_result_object(obj, result)
                if mine != result:  # obj is a duplicate: now it has a result of its own
                    props.result = mine
                report = objects.update_result(CACHE, obj, mine, settings, depsgraph=depsgraph)
        except bidegree.BidegreeError as exc:
            _set_if_changed(props, "last_error", f"{type(exc).__name__}: {exc}")
            if raise_errors:
                raise
            return "error"
        if report.action != "unchanged" or created:
            _set_if_changed(props, "last_error", "")
            _set_if_changed(props, "last_warning", "; ".join(report.warnings)[:1000])
            _set_if_changed(props, "cage_faces", report.cage_faces)
            _set_if_changed(props, "result_faces", report.result_faces)
            props.last_update_ms = round(report.seconds * 1000.0, 3)
            _set_if_changed(props, "last_action", report.action)
        return report.action
    finally:
        if progress:
            _progress_end(context)
        _busy = False


def request_update(obj: bpy.types.Object) -> None:
    """Schedule an update of ``obj`` (now in background mode, soon via a timer in the GUI)."""
    if not obj.bidegree.enabled:
        return
    _dirty.add(obj.name_full)
    _schedule()


def _schedule() -> None:
    global _timer_registered
    if bpy.app.background:
        process_pending()
        return
    if not _timer_registered:
        bpy.app.timers.register(_timer, first_interval=0.01)
        _timer_registered = True


def _timer() -> None:
    """GUI timer: process dirty objects (returns ``None`` so it runs once per request)."""
    global _timer_registered
    _timer_registered = False
    process_pending()


def process_pending() -> None:
    """Update every object marked dirty (skipping ones deleted or disabled since)."""
    names = list(_dirty)
    _dirty.clear()
    for name in names:
        obj = bpy.data.objects.get(name)
        if obj is not None and obj.bidegree.enabled:
            update(obj)


def remove(obj: bpy.types.Object) -> None:
    """Remove ``obj``'s live result and forget its cached plans."""
    props = obj.bidegree
    objects.remove_result_object(obj, props.result)
    props.result = None
    for variant in ("viewport", "render"):
        CACHE.discard(objects.cache_key(obj, variant))
    _set_if_changed(props, "result_faces", 0)
    _set_if_changed(props, "last_action", "")


def _cleanup_orphans(scene: bpy.types.Scene) -> None:
    """Delete result objects whose source object was deleted (it unparents its children),
    and forget the cached plans of objects that are gone or no longer enabled."""
    for ob in list(scene.objects):
        if not objects.is_result_object(ob) or ob.parent is not None:
            continue
        source = objects.find_source(ob)
        if source is None or source.users == 0 or scene.objects.get(source.name) is None:
            objects.remove_result_object(None, ob)
    if len(CACHE):
        alive = {
            ob.session_uid
            for ob in bpy.data.objects
            if ob.type == "MESH" and ob.users and ob.bidegree.enabled
        }
        CACHE.retain(lambda key: key[0] in alive)


def _sync_visibility(source: bpy.types.Object, result: bpy.types.Object) -> None:
    """Hiding the source (H, or the monitor toggle) hides its result too."""
    if result.hide_viewport != source.hide_viewport:
        result.hide_viewport = source.hide_viewport
    try:
        hidden = source.hide_get()
        if result.hide_get() != hidden:
            result.hide_set(hidden)
    except RuntimeError:  # not in the current view layer
        pass


@persistent
def on_depsgraph_update(scene: bpy.types.Scene, depsgraph: bpy.types.Depsgraph) -> None:
    """Mark enabled objects whose geometry (or mesh) changed as dirty; housekeeping."""
    if _busy:
        return
    changed_objects: set[str] = set()
    changed_data: set[str] = set()
    any_object = False
    for upd in depsgraph.updates:
        idv = upd.id
        orig = getattr(idv, "original", idv)
        if isinstance(orig, bpy.types.Object):
            any_object = True
            if upd.is_updated_geometry:
                changed_objects.add(orig.name_full)
        elif isinstance(orig, bpy.types.Mesh):
            changed_data.add(orig.name_full)
        elif isinstance(orig, (bpy.types.Collection, bpy.types.Scene)):
            any_object = True  # objects added/removed/relinked: housekeeping
    if not any_object and not changed_data:
        return
    any_dirty = False
    for ob in scene.objects:
        if ob.type != "MESH" or objects.is_result_object(ob) or not ob.bidegree.enabled:
            continue
        if ob.name_full in changed_objects or (
            ob.data is not None and ob.data.name_full in changed_data
        ):
            _dirty.add(ob.name_full)
            any_dirty = True
        result = ob.bidegree.result
        if result is not None and result.parent == ob:
            _sync_visibility(ob, result)
    if any_dirty:
        _schedule()
    _cleanup_orphans(scene)


@persistent
def on_load_post(*_args: Any) -> None:
    """A new file was loaded: cached plans refer to a previous session's objects."""
    CACHE.clear()
    _dirty.clear()
    _render_swaps.clear()


@persistent
def on_undo_post(*_args: Any) -> None:
    """Undo/redo restores meshes behind the cache's back: force a rewrite on next update."""
    CACHE.clear()
    for ob in bpy.context.scene.objects if bpy.context.scene else ():
        if ob.type == "MESH" and ob.bidegree.enabled:
            _dirty.add(ob.name_full)
    if _dirty:
        _schedule()


def render_swap_in(scene: bpy.types.Scene) -> int:
    """Give every enabled object's result its render-level mesh; returns how many were swapped."""
    global _busy
    if threading.current_thread() is not threading.main_thread() and not bpy.app.background:
        # Blender data must not be modified from the render thread; the viewport mesh renders.
        return 0
    swapped = 0
    depsgraph = bpy.context.evaluated_depsgraph_get()
    for ob in scene.objects:
        if ob.type != "MESH" or objects.is_result_object(ob) or not ob.bidegree.enabled:
            continue
        props = ob.bidegree
        result = props.result
        if (
            result is None
            # An adaptive viewport result is swapped for the uniform render result even at
            # equal levels.
            or (props.render_levels == props.levels and not props.adaptive)
            or result.name_full in _render_swaps
        ):
            continue
        mesh = objects.render_mesh_for(result)
        _busy = True
        try:
            objects.update_result(
                CACHE,
                ob,
                result,
                settings_of(ob, render=True),
                depsgraph=depsgraph,
                variant="render",
                mesh=mesh,
            )
        except bidegree.BidegreeError as exc:
            props.last_error = f"render levels: {type(exc).__name__}: {exc}"
            continue
        finally:
            _busy = False
        _render_swaps[result.name_full] = result.data.name_full
        result.data = mesh
        swapped += 1
    return swapped


def render_swap_out() -> None:
    """Give every result its viewport mesh back (after rendering)."""
    global _busy
    if threading.current_thread() is not threading.main_thread() and not bpy.app.background:
        return
    _busy = True
    try:
        for result_name, mesh_name in list(_render_swaps.items()):
            result = bpy.data.objects.get(result_name)
            mesh = bpy.data.meshes.get(mesh_name)
            if result is not None and mesh is not None:
                result.data = mesh
        _render_swaps.clear()
    finally:
        _busy = False


@persistent
def on_render_pre(scene: bpy.types.Scene, *_args: Any) -> None:
    """Rendering starts: use render levels."""
    render_swap_in(scene)


@persistent
def on_render_post(scene: bpy.types.Scene, *_args: Any) -> None:
    """Rendering finished or was cancelled: back to viewport levels."""
    render_swap_out()


_HANDLERS = (
    ("depsgraph_update_post", on_depsgraph_update),
    ("load_post", on_load_post),
    ("undo_post", on_undo_post),
    ("redo_post", on_undo_post),
    ("render_pre", on_render_pre),
    ("render_post", on_render_post),
    ("render_cancel", on_render_post),
)


def register() -> None:
    """Install the handlers (idempotent)."""
    for name, fn in _HANDLERS:
        lst = getattr(bpy.app.handlers, name)
        if fn not in lst:
            lst.append(fn)


def unregister() -> None:
    """Remove the handlers and the timer, forget every cached plan."""
    global _timer_registered
    for name, fn in _HANDLERS:
        lst = getattr(bpy.app.handlers, name)
        while fn in lst:
            lst.remove(fn)
    if _timer_registered and bpy.app.timers.is_registered(_timer):
        bpy.app.timers.unregister(_timer)
    _timer_registered = False
    CACHE.clear()
    _dirty.clear()
