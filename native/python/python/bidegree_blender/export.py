"""USD export of an object's bidegree surface.

Uses :func:`bidegree.usd.export` (cage + result, creases, UVs) when the
``bidegree.usd`` module is available, else Blender's own USD exporter on a
temporary object holding the result.
"""

from __future__ import annotations

import importlib
import os
from typing import TYPE_CHECKING, Any

import bidegree

from . import evaluated_cage, mesh_io, object_materials
from .live import Settings, build_plan, check_geometry, evaluate_surface, write_full

if TYPE_CHECKING:  # pragma: no cover - typing only
    import bpy


def bidegree_usd() -> Any | None:
    """The ``bidegree.usd`` module if it exists and has ``export`` (else ``None``)."""
    try:
        mod = importlib.import_module("bidegree.usd")
    except ImportError:
        return None
    return mod if hasattr(mod, "export") else None


def export_cage_usd(cage: mesh_io.CageArrays, path: str, settings: Settings) -> None:
    """Subdivide ``cage`` and write cage + result with :func:`bidegree.usd.export` (Z up)."""
    usd = bidegree_usd()
    if usd is None:
        raise bidegree.InvalidInputError("bidegree.usd is not available")
    check_geometry(cage)
    bmesh = mesh_io.to_bidegree_mesh(
        cage, boundary=settings.boundary, use_creases=settings.use_creases, uv_map=cage.active_uv
    )
    result = bidegree.subdivide(
        bmesh,
        degree=settings.degree,
        levels=settings.levels,
        output=settings.output,
        memory_budget=settings.memory_budget,
        rules=settings.rules,
        limit=settings.limit,
        normals=settings.normals,
    )
    usd.export(path, bmesh, result, up_axis="Z")


def export_blender_usd(
    obj: bpy.types.Object, path: str, settings: Settings, cage: mesh_io.CageArrays
) -> None:
    """Fallback: write the result with Blender's USD exporter through a temporary object."""
    import bpy

    check_geometry(cage)
    plan, _ = build_plan(cage, settings)
    mesh = bpy.data.meshes.new(f"{obj.name}_bidegree")
    points, normals = evaluate_surface(plan, cage.points, settings)
    write_full(mesh, plan, points, cage, object_materials(obj), normals)
    tmp = bpy.data.objects.new(f"{obj.name}_bidegree", mesh)
    tmp.matrix_world = obj.matrix_world
    scene = bpy.context.scene
    scene.collection.objects.link(tmp)
    try:
        for other in bpy.context.view_layer.objects:
            other.select_set(False)
        tmp.select_set(True)
        bpy.ops.wm.usd_export(filepath=path, selected_objects_only=True)
    finally:
        bpy.data.objects.remove(tmp)
        bpy.data.meshes.remove(mesh)


def export_object_usd(
    obj: bpy.types.Object,
    path: str,
    settings: Settings,
    *,
    depsgraph: bpy.types.Depsgraph | None = None,
) -> str:
    """Export ``obj``'s bidegree surface to ``path`` (``.usdc``, ``.usda``, ``.usd``).

    The evaluated mesh (modifiers applied) is used as the cage.
    """
    path = os.path.abspath(path)
    cage = evaluated_cage(obj, depsgraph=depsgraph, use_creases=settings.use_creases)
    if bidegree_usd() is not None:
        export_cage_usd(cage, path, settings)
    else:
        export_blender_usd(obj, path, settings, cage)
    return path
