"""Exports of an object with a bidegree modifier (issue 12, test 5): Blender's OBJ, glTF and USD
exporters write one mesh per object, the surface, with the object's transform; the panel's
Export USD writes the transform, the materials and every UV map, and validates."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest
from util import cube, update

bpy = pytest.importorskip("bpy")

modifier: Any = None
bidegree_blender: Any = None


def _scene_with_surface(scene: Any) -> tuple[Any, np.ndarray]:
    """A cube with two UV maps and two materials, moved, rotated and scaled, with a bidegree
    modifier; returns it and its surface in world space."""
    obj = cube(scene)
    me = obj.data
    for name, scale in (("UVMap", 0.1), ("Detail", 0.3)):
        layer = me.uv_layers.new(name=name)
        for i, loop in enumerate(layer.data):
            loop.uv = (scale * (i % 4), scale * (i // 4) * 0.25)
    for name, color in (("Red", (1, 0, 0, 1)), ("Blue", (0, 0, 1, 1))):
        mat = bpy.data.materials.new(name)
        mat.diffuse_color = color
        me.materials.append(mat)
    for i, poly in enumerate(me.polygons):
        poly.material_index = i % 2
    obj.location = (1.0, 2.0, 3.0)
    obj.rotation_euler = (0.3, 0.0, 0.5)
    obj.scale = (2.0, 1.0, 1.0)
    mod = bidegree_blender.add_modifier(obj, degree=3, levels=2)
    depsgraph = update()
    holder = modifier.holders(obj, mod)["viewport"].data
    local = np.array([tuple(v.co) for v in holder.vertices])
    matrix = np.array(obj.matrix_world)
    del depsgraph
    return obj, local @ matrix[:3, :3].T + matrix[:3, 3]


def _sorted(points: np.ndarray) -> np.ndarray:
    return points[np.lexsort(np.round(points, 4).T[::-1])]


def test_obj_export(scene: Any, tmp_path: Path) -> None:
    _obj, world = _scene_with_surface(scene)
    path = tmp_path / "out.obj"
    assert bpy.ops.wm.obj_export(filepath=str(path), forward_axis="Y", up_axis="Z") == {"FINISHED"}
    lines = path.read_text().splitlines()
    assert sum(1 for ln in lines if ln.startswith("o ")) == 1
    points = np.array([[float(x) for x in ln.split()[1:4]] for ln in lines if ln.startswith("v ")])
    assert len(points) == len(world)
    np.testing.assert_allclose(_sorted(points), _sorted(world), atol=1e-4)


_GLTF = r"""
import os, sys, bpy, addon_utils
bpy.ops.wm.open_mainfile(filepath=sys.argv[-2])
addon_utils.enable("io_scene_gltf2", default_set=True)
result = bpy.ops.export_scene.gltf(
    filepath=sys.argv[-1], export_format="GLTF_SEPARATE", export_apply=True
)
print("GLTF", result)
sys.stdout.flush()
os._exit(0)  # bpy 4.2's glTF add-on crashes the process at exit
"""


def test_gltf_export(scene: Any, tmp_path: Path) -> None:
    import json
    import os
    import subprocess
    import sys

    _obj, world = _scene_with_surface(scene)
    blend = tmp_path / "scene.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(blend), copy=True)
    path = tmp_path / "out.gltf"
    env = dict(os.environ)
    env.pop("BLENDER_USER_RESOURCES", None)
    # Its own process (the glTF add-on is Python; the saved surface needs no extension to show).
    # Apply Modifiers is glTF's own option (off by default, as for any modifier).
    proc = subprocess.run(
        [sys.executable, "-c", _GLTF, str(blend), str(path)],
        capture_output=True,
        text=True,
        env=env,
        timeout=300,
        check=False,
    )
    assert "GLTF {'FINISHED'}" in proc.stdout, proc.stdout[-2000:] + proc.stderr[-2000:]
    data = json.loads(path.read_text())
    assert len(data["meshes"]) == 1 and len(data["nodes"]) == 1
    node = data["nodes"][0]
    assert node["translation"] == pytest.approx([1.0, 3.0, -2.0], abs=1e-6)  # glTF is Y up
    # The surface's faces, one primitive per material (glTF splits vertices at UV seams and
    # between primitives, so there are at least as many as the surface has).
    primitives = data["meshes"][0]["primitives"]
    assert len(primitives) == 2
    counts = [data["accessors"][p["attributes"]["POSITION"]]["count"] for p in primitives]
    triangles = sum(data["accessors"][p["indices"]]["count"] // 3 for p in primitives)
    assert sum(counts) >= len(world) and triangles == 2 * 6 * 16


def test_usd_export(scene: Any, tmp_path: Path) -> None:
    from pxr import Usd, UsdGeom

    _obj, world = _scene_with_surface(scene)
    path = tmp_path / "out.usda"
    assert bpy.ops.wm.usd_export(filepath=str(path)) == {"FINISHED"}
    stage = Usd.Stage.Open(str(path))
    meshes = [p for p in stage.Traverse() if p.IsA(UsdGeom.Mesh)]
    assert len(meshes) == 1
    mesh = UsdGeom.Mesh(meshes[0])
    points = np.array(mesh.GetPointsAttr().Get())
    matrix = np.array(UsdGeom.Xformable(mesh).ComputeLocalToWorldTransform(Usd.TimeCode.Default()))
    transformed = points @ matrix[:3, :3] + matrix[3, :3]  # USD: row vectors
    np.testing.assert_allclose(_sorted(transformed), _sorted(world), atol=1e-4)


def test_panel_export_usd(scene: Any, tmp_path: Path) -> None:
    import bidegree.usd
    from pxr import Usd, UsdGeom, UsdShade

    obj, world = _scene_with_surface(scene)
    path = tmp_path / "panel.usda"
    with bpy.context.temp_override(object=obj, active_object=obj):
        assert bpy.ops.object.bidegree_export_usd(filepath=str(path)) == {"FINISHED"}
    assert bidegree.usd.validate(path) == []
    assert not list(tmp_path.glob(".*"))  # no temporary file left
    stage = Usd.Stage.Open(str(path))
    result = UsdGeom.Mesh(stage.GetPrimAtPath("/Bidegree/Result"))
    points = np.array(result.GetPointsAttr().Get())
    matrix = np.array(
        UsdGeom.Xformable(result).ComputeLocalToWorldTransform(Usd.TimeCode.Default())
    )
    # The file's points are in their own order (bidegree.usd's point_order): compare as sets.
    transformed = points @ matrix[:3, :3] + matrix[3, :3]
    np.testing.assert_allclose(_sorted(transformed), _sorted(world), atol=1e-4)
    primvars = UsdGeom.PrimvarsAPI(result)
    assert primvars.HasPrimvar("st") and primvars.HasPrimvar("Detail")
    for prim_path in ("/Bidegree/Result", "/Bidegree/Cage"):
        prim = stage.GetPrimAtPath(prim_path)
        subsets = UsdGeom.Subset.GetAllGeomSubsets(UsdGeom.Imageable(prim))
        bound = {
            UsdShade.MaterialBindingAPI(s.GetPrim()).ComputeBoundMaterial()[0].GetPath().name
            for s in subsets
        }
        assert bound == {"Red", "Blue"}, prim_path
    assert stage.GetPrimAtPath("/Bidegree/Result").GetAttribute("bidegree:degree").Get() == 3
