"""USD export of a bidegree surface with its cage (the panel's Export USD, the batch).

:func:`bidegree.usd.export` writes ``/Bidegree/Cage`` (a Catmull-Clark ``UsdGeom.Mesh`` with
creases, corners and boundary rule) and ``/Bidegree/Result`` (the surface, ``bidegree:*``
attributes). For an object this adds what the object has: its world transform on ``/Bidegree``,
every UV map as a face-varying primvar on both meshes (the active one as ``st``), and its
materials (``UsdPreviewSurface`` from each material's viewport colour, bound per face through
``GeomSubset``\\ s). The file is written under a temporary name and renamed.
"""

from __future__ import annotations

import importlib
import os
import re
import tempfile
from typing import TYPE_CHECKING, Any

import bidegree
import numpy as np
from bidegree.options import Options

from . import mesh_io, modifier, pipeline

if TYPE_CHECKING:  # pragma: no cover - typing only
    import bpy


def bidegree_usd() -> Any | None:
    """The ``bidegree.usd`` module if it exists and has ``export`` (else ``None``)."""
    try:
        mod = importlib.import_module("bidegree.usd")
    except ImportError:
        return None
    return mod if hasattr(mod, "export") else None


def _usd() -> Any:
    usd = bidegree_usd()
    if usd is None:
        raise bidegree.InvalidInputError("USD export needs usd-core (pip install usd-core)")
    return usd


def export_cage_usd(cage: mesh_io.CageArrays, path: str, options: Options) -> bidegree.Result:
    """Subdivide ``cage`` and write cage + result with :func:`bidegree.usd.export` (Z up);
    returns the result."""
    usd = _usd()
    pipeline.check_geometry(cage)
    bmesh = mesh_io.to_bidegree_mesh(
        cage, boundary=options.boundary, use_creases=options.use_creases, uv_map=cage.active_uv
    )
    result = options.subdivide(bmesh)
    usd.export(path, bmesh, result, up_axis="Z")
    return result


def _identifier(name: str, taken: set[str]) -> str:
    """A USD prim/primvar identifier for ``name`` that is not in ``taken``."""
    base = re.sub(r"\W", "_", name) or "_"
    if base[0].isdigit():
        base = f"_{base}"
    candidate, n = base, 1
    while candidate in taken:
        n += 1
        candidate = f"{base}_{n}"
    taken.add(candidate)
    return candidate


def _add_object_data(
    path: str,
    obj: bpy.types.Object,
    cage: mesh_io.CageArrays,
    result: bidegree.Result,
) -> None:
    """Add ``obj``'s transform, UV maps and materials to the stage written at ``path``."""
    from pxr import Gf, Sdf, Usd, UsdGeom, UsdShade, Vt

    stage = Usd.Stage.Open(path)
    root = stage.GetPrimAtPath("/Bidegree")
    # Blender's matrices act on column vectors, USD's on row vectors: transpose.
    matrix = np.array(obj.matrix_world, dtype=np.float64).T
    UsdGeom.Xformable(root).AddTransformOp().Set(Gf.Matrix4d(matrix.tolist()))

    meshes = {label: stage.GetPrimAtPath(f"/Bidegree/{label}") for label in ("Cage", "Result")}
    plan = result.plan
    names = {"st", "normals", "displayColor", "distance"}  # bidegree.usd's own primvars
    for name, (uvs, indices) in cage.uv_sets().items():
        if name == cage.active_uv:
            continue  # written as ``st`` by bidegree.usd
        primvar = _identifier(name, names)
        for label, prim in meshes.items():
            created = UsdGeom.PrimvarsAPI(prim).CreatePrimvar(
                primvar, Sdf.ValueTypeNames.TexCoord2fArray, UsdGeom.Tokens.faceVarying
            )
            if label == "Cage":
                # Indexed by Blender's UV topology, as the active map's ``st``.
                values = uvs
                created.SetIndices(Vt.IntArray.FromNumpy(indices.astype(np.int32)))
            else:
                values = plan.evaluate_face_varying(uvs, result.uv_mode, indices=indices)
            created.Set(Vt.Vec2fArray.FromNumpy(np.ascontiguousarray(values, dtype=np.float32)))

    materials = pipeline.object_materials(obj)
    if any(m is not None for m in materials):
        taken: set[str] = set()
        looks = UsdGeom.Scope.Define(stage, "/Bidegree/Materials")
        bound = []
        for mat in materials:
            if mat is None:
                bound.append(None)
                continue
            mpath = looks.GetPath().AppendChild(_identifier(mat.name, taken))
            material = UsdShade.Material.Define(stage, mpath)
            shader = UsdShade.Shader.Define(stage, mpath.AppendChild("PreviewSurface"))
            shader.CreateIdAttr("UsdPreviewSurface")
            color = tuple(float(c) for c in mat.diffuse_color[:3])
            shader.CreateInput("diffuseColor", Sdf.ValueTypeNames.Color3f).Set(Gf.Vec3f(*color))
            shader.CreateInput("roughness", Sdf.ValueTypeNames.Float).Set(float(mat.roughness))
            shader.CreateInput("metallic", Sdf.ValueTypeNames.Float).Set(float(mat.metallic))
            material.CreateSurfaceOutput().ConnectToSource(shader.ConnectableAPI(), "surface")
            bound.append(material)
        index = cage.material_index
        for label, prim in meshes.items():
            UsdShade.MaterialBindingAPI.Apply(prim)
            faces = np.zeros(len(cage.face_sizes), dtype=np.int64)
            if index is not None:
                faces = np.clip(index.astype(np.int64), 0, len(bound) - 1)
            if label == "Result":
                faces = faces[np.asarray(result.face_origin, dtype=np.int64)]
            used = sorted(set(np.unique(faces).tolist()))
            if len(used) == 1:
                if bound[used[0]] is not None:
                    UsdShade.MaterialBindingAPI(prim).Bind(bound[used[0]])
                continue
            for k in used:
                if bound[k] is None:
                    continue
                subset = UsdShade.MaterialBindingAPI(prim).CreateMaterialBindSubset(
                    f"material_{k}",
                    Vt.IntArray.FromNumpy(np.flatnonzero(faces == k).astype(np.int32)),
                )
                UsdShade.MaterialBindingAPI.Apply(subset.GetPrim())
                UsdShade.MaterialBindingAPI(subset.GetPrim()).Bind(bound[k])
    stage.GetRootLayer().Save()


def export_modifier_usd(
    obj: bpy.types.Object,
    mod: bpy.types.Modifier,
    path: str,
    *,
    depsgraph: bpy.types.Depsgraph | None = None,
) -> str:
    """Export the surface of the bidegree modifier ``mod`` of ``obj`` (its viewport settings,
    uniform levels; the cage at the modifier's place in the stack) with its cage to ``path``
    (``.usdc``, ``.usda``, ``.usd``); see the module docstring for what is written.

    Raises:
        bidegree.BidegreeError: a refused cage or request, a bad path; nothing is written.
    """
    import bpy

    _usd()  # usd-core is there before any work
    target = os.path.abspath(path)
    directory, filename = os.path.split(target)
    stem, ext = os.path.splitext(filename)
    if depsgraph is None:
        depsgraph = bpy.context.evaluated_depsgraph_get()
    options = modifier.options_of(mod, uniform=True)
    cage = modifier.read_cage(obj, mod, depsgraph)
    if not os.path.isdir(directory):
        raise bidegree.BidegreeIOError(f"{path}: directory {directory} does not exist")
    fd, tmp = tempfile.mkstemp(prefix=f".{stem}.", suffix=ext, dir=directory)
    os.close(fd)
    try:
        result = export_cage_usd(cage, tmp, options)
        _add_object_data(tmp, obj, cage, result)
        os.replace(tmp, target)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise
    return target
