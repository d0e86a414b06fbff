"""bpy-facing logic of bidegree (used by the Blender extension and the batch tool).

Nothing in here registers classes or handlers; the extension (``addon/bidegree``)
is a thin layer over these functions so that they can be used from plain
``bpy`` scripts too::

    import bpy, bidegree_blender
    mesh = bidegree_blender.subdivide_object(bpy.data.objects["Cube"], degree=4, levels=2)
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import bidegree

from . import mesh_io
from .live import (
    LiveCache,
    Settings,
    build_plan,
    check_geometry,
    evaluate_surface,
    write_full,
)

if TYPE_CHECKING:  # pragma: no cover - typing only
    import bpy

__all__ = [
    "LiveCache",
    "Settings",
    "evaluated_cage",
    "mesh_io",
    "object_materials",
    "subdivide_object",
]


def object_materials(obj: bpy.types.Object) -> list[Any]:
    """Materials of ``obj``'s slots in order (object-linked slots included)."""
    return [slot.material for slot in obj.material_slots]


def evaluated_cage(
    obj: bpy.types.Object,
    *,
    depsgraph: bpy.types.Depsgraph | None = None,
    use_creases: bool = True,
) -> mesh_io.CageArrays:
    """Read ``obj``'s evaluated mesh (all its modifiers applied) into numpy arrays.

    The temporary evaluated mesh is freed before returning.
    """
    import bpy

    if obj is None or obj.type != "MESH":
        kind = getattr(obj, "type", None)
        raise bidegree.InvalidInputError(
            f"object {getattr(obj, 'name', obj)!r} is not a mesh object (type {kind})"
        )
    if depsgraph is None:
        depsgraph = bpy.context.evaluated_depsgraph_get()
    eval_obj = obj.evaluated_get(depsgraph)
    tmp = eval_obj.to_mesh()
    try:
        return mesh_io.read_mesh(tmp, use_creases=use_creases)
    finally:
        eval_obj.to_mesh_clear()


def subdivide_object(
    obj: bpy.types.Object,
    degree: int = 4,
    levels: int = 2,
    output: str = "primal",
    boundary: str = "edge-only",
    use_creases: bool = True,
    depsgraph: bpy.types.Depsgraph | None = None,
    *,
    name: str | None = None,
    memory_budget: int | None = None,
    rules: str = "averaging",
    limit: bool = False,
    normals: bool = False,
) -> bpy.types.Mesh:
    """Subdivide ``obj``'s evaluated mesh and return a new mesh datablock.

    Modifiers of ``obj`` are honoured (the evaluated mesh is used).  Materials,
    per-face material indices, flat/smooth shading (through ``face_origin``)
    and every UV map (linear interpolation) carry over; edge and vertex
    creases shape the surface (sharpness ``10 * c**2``).  ``limit`` puts the
    vertices on the limit surface, ``normals`` writes its limit normals as
    custom normals.

    Raises:
        bidegree.BidegreeError: a subclass describing bad input (non-manifold
            edge, loose edges, zero-area face, degree/level out of range,
            memory budget, ...).  Nothing is created and ``obj`` is untouched.
    """
    import bpy

    settings = Settings(
        degree=int(degree),
        levels=int(levels),
        output=str(output),
        boundary=str(boundary),
        use_creases=bool(use_creases),
        memory_budget=memory_budget,
        rules=str(rules),
        limit=bool(limit),
        normals=bool(normals),
    )
    cage = evaluated_cage(obj, depsgraph=depsgraph, use_creases=settings.use_creases)
    check_geometry(cage)
    plan, _notes = build_plan(cage, settings)
    points, corner_normals = evaluate_surface(plan, cage.points, settings)
    mesh = bpy.data.meshes.new(name or f"{obj.name}_bidegree")
    try:
        write_full(mesh, plan, points, cage, object_materials(obj), corner_normals)
    except BaseException:
        bpy.data.meshes.remove(mesh)
        raise
    return mesh
