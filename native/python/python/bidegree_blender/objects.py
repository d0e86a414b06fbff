"""Result objects of the live bidegree surface (bpy data logic, no GUI).

Mechanism: the source object (the one the user edits, the *cage*) keeps its
mesh and modifiers.  Its subdivided surface lives in a separate *result
object* that

* is parented to the source with an identity parent-inverse matrix, so the
  source's transform (and anything animating it) moves the result too;
* is linked into the same collections, not selectable, and carries the
  source's materials on its mesh (per-face material indices, flat/smooth
  shading and every UV map carry over through the result);
* replaces the display: the source is drawn as a wireframe cage
  (``display_type = 'WIRE'``) and hidden from renders (the result renders).

Removing the live result restores the source's display settings.
"""

from __future__ import annotations

from collections.abc import Hashable
from typing import TYPE_CHECKING, Any

from . import evaluated_cage, object_materials
from .live import LiveCache, Settings, UpdateReport

if TYPE_CHECKING:  # pragma: no cover - typing only
    import bpy

#: Custom property on a result object: the ``name_full`` of its source.
RESULT_TAG = "bidegree_result_of"
#: Custom property on a source object: its display settings before bidegree took over.
SAVED_DISPLAY = "bidegree_saved_display"


def cache_key(obj: bpy.types.Object, variant: str = "viewport") -> Hashable:
    """Cache key of ``obj`` (stable for the session, survives renames)."""
    return (obj.session_uid, variant)


def is_result_object(obj: bpy.types.Object) -> bool:
    """Whether ``obj`` is a bidegree result object."""
    return RESULT_TAG in obj.keys()


def ensure_result_object(
    obj: bpy.types.Object,
    result: bpy.types.Object | None,
    mesh: bpy.types.Mesh | None = None,
) -> bpy.types.Object:
    """Return ``result`` if it is a valid result of ``obj``, else create one (with ``mesh``)."""
    import bpy

    if (
        result is not None
        and result.name in bpy.data.objects
        and result.type == "MESH"
        and result.parent == obj
    ):
        if result.get(RESULT_TAG) != obj.name_full:  # the source was renamed
            result[RESULT_TAG] = obj.name_full
        return result
    # No result yet, or ``result`` belongs to another object (this one is a duplicate whose
    # settings still point at the original's result): make our own.
    name = f"{obj.name}.bidegree"
    if mesh is None:
        mesh = bpy.data.meshes.new(name)
    result = bpy.data.objects.new(name, mesh)
    result[RESULT_TAG] = obj.name_full
    collections = list(obj.users_collection) or [bpy.context.scene.collection]
    for coll in collections:
        coll.objects.link(result)
    result.parent = obj
    result.matrix_parent_inverse.identity()
    result.hide_select = True
    if SAVED_DISPLAY not in obj.keys():
        obj[SAVED_DISPLAY] = {"display_type": obj.display_type, "hide_render": obj.hide_render}
    obj.display_type = "WIRE"
    obj.hide_render = True
    return result


def remove_result_object(obj: bpy.types.Object | None, result: bpy.types.Object | None) -> None:
    """Delete ``result`` (and its meshes when unused) and restore ``obj``'s display settings."""
    import bpy

    if result is not None and result.name in bpy.data.objects:
        meshes = {result.data}
        render_mesh = bpy.data.meshes.get(result.data.name + ".render") if result.data else None
        if render_mesh is not None:
            meshes.add(render_mesh)
        bpy.data.objects.remove(result)
        for mesh in meshes:
            if mesh is not None and mesh.users == 0:
                bpy.data.meshes.remove(mesh)
    if obj is not None and SAVED_DISPLAY in obj.keys():
        saved = obj[SAVED_DISPLAY]
        obj.display_type = saved.get("display_type", "TEXTURED")
        obj.hide_render = bool(saved.get("hide_render", False))
        del obj[SAVED_DISPLAY]


def update_result(
    cache: LiveCache,
    obj: bpy.types.Object,
    result: bpy.types.Object,
    settings: Settings,
    *,
    depsgraph: bpy.types.Depsgraph | None = None,
    variant: str = "viewport",
    mesh: bpy.types.Mesh | None = None,
) -> UpdateReport:
    """Re-read ``obj``'s evaluated mesh and bring ``result``'s mesh (or ``mesh``) up to date.

    Raises ``bidegree.BidegreeError`` subclasses on bad input; the result mesh is
    then left as it was.
    """
    cage = evaluated_cage(obj, depsgraph=depsgraph, use_creases=settings.use_creases)
    target = mesh if mesh is not None else result.data
    return cache.update(
        cache_key(obj, variant), cage, settings, target, materials=object_materials(obj)
    )


def render_mesh_for(result: bpy.types.Object) -> bpy.types.Mesh:
    """The (possibly new) mesh datablock that holds ``result``'s render-level surface."""
    import bpy

    name = result.data.name + ".render"
    mesh = bpy.data.meshes.get(name)
    if mesh is None:
        mesh = bpy.data.meshes.new(name)
    return mesh


def bake_into_object(
    obj: bpy.types.Object, mesh: bpy.types.Mesh, result: bpy.types.Object | None
) -> None:
    """Make ``mesh`` the mesh of ``obj`` (modifiers are baked in, so they are removed).

    The old mesh is removed when nothing else uses it, and the live result
    object (if any) is deleted.
    """
    import bpy

    remove_result_object(obj, result)
    old = obj.data
    old_name = old.name
    obj.modifiers.clear()
    obj.data = mesh
    if old.users == 0:
        bpy.data.meshes.remove(old)
        mesh.name = old_name


def find_source(result: bpy.types.Object) -> Any:
    """The source object of a result object (or ``None`` when it was deleted)."""
    import bpy

    return bpy.data.objects.get(result.get(RESULT_TAG, ""))
