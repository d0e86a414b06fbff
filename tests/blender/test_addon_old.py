"""The bidegree Blender extension, installed from its built zip into headless bpy 5.x."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path
from types import ModuleType
from typing import Any

import numpy as np
import pytest

bpy = pytest.importorskip("bpy")

#: ``bidegree`` as imported from the installed extension's wheel (set by the autouse fixture,
#: after the extension was installed, so the installed copy is the one used).
bidegree: Any = None


@pytest.fixture(autouse=True)
def _bidegree_from_extension(addon: ModuleType) -> None:
    global bidegree
    import bidegree as module

    bidegree = module


ROOT = Path(__file__).resolve().parents[2]

# --------------------------------------------------------------------------- helpers


def make_object(scene: Any, name: str, points: Any, faces: Any, edges: Any = ()) -> Any:
    """A mesh object linked into ``scene`` (built with the plain, slow API on purpose)."""
    mesh = bpy.data.meshes.new(name)
    mesh.from_pydata([tuple(map(float, p)) for p in points], list(edges), [list(f) for f in faces])
    mesh.update()
    obj = bpy.data.objects.new(name, mesh)
    scene.collection.objects.link(obj)
    return obj


def cube(scene: Any, name: str = "Cube") -> Any:
    pts = [(x, y, z) for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)]
    faces = [
        (0, 1, 3, 2),
        (4, 6, 7, 5),
        (0, 4, 5, 1),
        (2, 3, 7, 6),
        (0, 2, 6, 4),
        (1, 5, 7, 3),
    ]
    return make_object(scene, name, pts, faces)


def evaluated_reference(obj: Any) -> tuple[np.ndarray, list[list[int]], Any]:
    """Points and faces of ``obj``'s evaluated mesh, read with the plain per-element API."""
    dg = bpy.context.evaluated_depsgraph_get()
    ev = obj.evaluated_get(dg)
    me = ev.to_mesh()
    try:
        points = np.array([tuple(v.co) for v in me.vertices], dtype=np.float32)
        faces = [list(p.vertices) for p in me.polygons]
        creases = None
        attr = me.attributes.get("crease_edge")
        if attr is not None:
            pairs = [(e.vertices[0], e.vertices[1], attr.data[e.index].value) for e in me.edges]
            pairs = [p for p in pairs if p[2] > 0]
            if pairs:
                creases = (
                    np.array([p[:2] for p in pairs], dtype=np.int64),
                    np.array([10.0 * p[2] ** 2 for p in pairs], dtype=np.float32),
                )
        return points, faces, creases
    finally:
        ev.to_mesh_clear()


def mesh_arrays(mesh: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Points, face sizes and corner vertices of a mesh (plain API)."""
    points = np.array([tuple(v.co) for v in mesh.vertices], dtype=np.float32)
    sizes = np.array([p.loop_total for p in mesh.polygons], dtype=np.int32)
    corners = np.array([i for p in mesh.polygons for i in p.vertices], dtype=np.int32)
    return points, sizes, corners


def assert_matches(mesh: Any, ref: Any) -> None:
    """``mesh`` equals the bidegree ``Result`` ``ref`` point for point and face for face."""
    points, sizes, corners = mesh_arrays(mesh)
    np.testing.assert_array_equal(sizes, np.asarray(ref.face_sizes))
    np.testing.assert_array_equal(corners, np.asarray(ref.face_indices))
    np.testing.assert_allclose(points, np.asarray(ref.points), rtol=0, atol=1e-6)


def snapshot(obj: Any) -> tuple[bytes, bytes, bytes, int]:
    points, sizes, corners = mesh_arrays(obj.data)
    return points.tobytes(), sizes.tobytes(), corners.tobytes(), len(obj.data.edges)


def faces_while_rendering(scene: Any, result: Any) -> list[int]:
    """Renders ``scene`` (Cycles, 1 sample, 16x16) and returns the face counts of ``result``
    seen by a ``render_pre`` handler that runs after the add-on's."""
    seen: list[int] = []

    def probe(_scene: Any, *_args: Any) -> None:
        seen.append(len(result.data.polygons))

    camera = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    camera.location = (0.0, -8.0, 0.0)
    camera.rotation_euler = (1.5708, 0.0, 0.0)
    scene.collection.objects.link(camera)
    scene.camera = camera
    scene.render.engine = "CYCLES"
    scene.cycles.samples = 1
    scene.cycles.device = "CPU"
    scene.render.resolution_x = scene.render.resolution_y = 16
    bpy.app.handlers.render_pre.append(probe)
    try:
        assert bpy.ops.render.render(write_still=False) == {"FINISHED"}
    finally:
        bpy.app.handlers.render_pre.remove(probe)
    return seen


def enable(obj: Any, **settings: Any) -> None:
    for key, value in settings.items():
        setattr(obj.bidegree, key, value)
    obj.bidegree.enabled = True


# --------------------------------------------------------------------------- tests


def test_installed_copy_is_used(
    addon: ModuleType, user_dir: str, bidegree_preimported: bool
) -> None:
    import bidegree_blender

    assert addon.__file__.startswith(user_dir), addon.__file__
    assert bidegree_blender.__file__.startswith(user_dir), bidegree_blender.__file__
    if bidegree_preimported:
        pytest.skip("bidegree was imported before the extension: run `pytest tests/blender` alone")
    assert bidegree.__file__.startswith(user_dir), bidegree.__file__


def test_panel_registered_in_modifier_tab(addon: ModuleType) -> None:
    panel = bpy.types.Panel.bl_rna_get_subclass_py("BIDEGREE_PT_surface")
    assert panel is not None
    assert panel.bl_context == "modifier"
    assert panel.bl_space_type == "PROPERTIES"
    assert panel.bl_region_type == "WINDOW"
    ops = sys.modules[addon.__name__ + ".operators"]
    assert ops.BIDEGREE_OT_apply.bl_options == {"REGISTER", "UNDO"}
    for name in ("bidegree_apply", "bidegree_export_usd", "bidegree_remove"):
        assert getattr(bpy.ops.object, name).get_rna_type() is not None
    props = bpy.types.Object.bl_rna.properties["bidegree"].fixed_type.properties
    assert props["degree"].default == 4 and props["degree"].hard_min == 1
    assert props["degree"].hard_max == 31
    assert props["levels"].default == 2 and props["render_levels"].default == 3


def test_bevelled_cube_matches_subdivide(addon: ModuleType, scene: Any) -> None:
    obj = cube(scene)
    bevel = obj.modifiers.new("Bevel", "BEVEL")
    bevel.width = 0.2
    bevel.segments = 2
    obj.location = (3.0, 0.0, 1.0)
    enable(obj)
    assert obj.bidegree.last_error == ""
    result = obj.bidegree.result
    assert result is not None and result.parent == obj

    points, faces, _ = evaluated_reference(obj)
    assert len(faces) > 6  # the bevel is in the cage
    ref = bidegree.subdivide(bidegree.Mesh(points, faces), degree=4, levels=2)
    assert_matches(result.data, ref)
    assert obj.bidegree.cage_faces == len(faces)
    assert obj.bidegree.result_faces == len(ref.face_sizes)

    bpy.context.view_layer.update()
    np.testing.assert_allclose(np.array(result.matrix_world), np.array(obj.matrix_world))
    assert obj.display_type == "WIRE" and obj.hide_render and not result.hide_render


def test_creases_uvs_materials_and_shading_survive(addon: ModuleType, scene: Any) -> None:
    obj = cube(scene)
    me = obj.data
    crease = me.attributes.new("crease_edge", "FLOAT", "EDGE")
    crease.data[0].value = 1.0
    crease.data[3].value = 0.5
    me.attributes.new("crease_vert", "FLOAT", "POINT").data[6].value = 0.8
    uv = me.uv_layers.new(name="UVMap")
    for i, loop in enumerate(uv.data):
        loop.uv = (0.1 * (i % 4), 0.05 * i)
    second = me.uv_layers.new(name="Second")
    for i, loop in enumerate(second.data):
        loop.uv = (1.0 - 0.02 * i, 0.5)
    red, blue = bpy.data.materials.new("Red"), bpy.data.materials.new("Blue")
    me.materials.append(red)
    me.materials.append(blue)
    mat_index = [0, 1, 1, 0, 1, 0]
    for poly, m in zip(me.polygons, mat_index, strict=True):
        poly.material_index = m
        poly.use_smooth = m == 1
    me.update()
    enable(obj)
    assert obj.bidegree.last_error == ""
    out = obj.bidegree.result.data

    points, faces, creases = evaluated_reference(obj)
    assert creases is not None and len(creases[0]) == 2
    uvs = np.array([tuple(d.uv) for d in me.uv_layers["UVMap"].data], dtype=np.float32)
    ref = bidegree.subdivide(
        bidegree.Mesh(
            points,
            faces,
            creases=creases,
            corners=(np.array([6]), np.array([10.0 * 0.8**2], dtype=np.float32)),
            uvs=uvs,
        ),
        4,
        2,
    )
    assert_matches(out, ref)
    smooth = bidegree.subdivide(bidegree.Mesh(points, faces), 4, 2)
    assert np.abs(np.asarray(smooth.points) - np.asarray(ref.points)).max() > 1e-3

    # UVs: every map, linearly interpolated (the active one equals Result.uvs).
    assert set(out.uv_layers.keys()) == {"UVMap", "Second"}
    got_uv = np.array([tuple(d.uv) for d in out.uv_layers["UVMap"].data], dtype=np.float32)
    np.testing.assert_allclose(got_uv, np.asarray(ref.uvs), atol=1e-6)
    got_second = np.array([tuple(d.uv) for d in out.uv_layers["Second"].data])
    assert np.allclose(got_second[:, 1], 0.5) and got_second[:, 0].std() > 0.01

    origin = np.asarray(ref.face_origin)
    got_mat = np.array([p.material_index for p in out.polygons])
    np.testing.assert_array_equal(got_mat, np.array(mat_index)[origin])
    got_smooth = np.array([p.use_smooth for p in out.polygons])
    np.testing.assert_array_equal(got_smooth, np.array(mat_index)[origin] == 1)
    assert [m.name for m in out.materials] == ["Red", "Blue"]


def test_moving_a_vertex_reuses_the_plan(addon: ModuleType, scene: Any) -> None:
    obj = cube(scene)
    enable(obj)
    stats = addon.CACHE.stats
    builds, reuses, skips = stats.plan_builds, stats.plan_reuses, stats.skips
    plan = addon.CACHE.plan((obj.session_uid, "viewport"))
    assert plan is not None

    # Nothing changed: no work.
    assert addon.update(obj) == "unchanged"
    assert stats.skips == skips + 1

    obj.data.vertices[0].co = (-1.5, -1.2, -1.1)
    obj.data.update()
    assert addon.update(obj) == "reused"
    assert stats.plan_builds == builds and stats.plan_reuses == reuses + 1
    assert addon.CACHE.plan((obj.session_uid, "viewport")) is plan
    points, faces, _ = evaluated_reference(obj)
    assert_matches(obj.bidegree.result.data, bidegree.subdivide(bidegree.Mesh(points, faces), 4, 2))

    # The depsgraph handler alone picks up an edit (background mode: processed at once).
    obj.data.vertices[7].co = (1.3, 1.0, 1.2)
    obj.data.update()
    bpy.context.view_layer.update()
    assert stats.plan_builds == builds and stats.plan_reuses == reuses + 2
    points, faces, _ = evaluated_reference(obj)
    assert_matches(obj.bidegree.result.data, bidegree.subdivide(bidegree.Mesh(points, faces), 4, 2))
    # ...and our own writes did not trigger further updates (no loop).
    bpy.context.view_layer.update()
    assert stats.plan_reuses == reuses + 2

    # A topology change rebuilds the plan.
    obj.modifiers.new("Tri", "TRIANGULATE")
    bpy.context.view_layer.update()
    addon.update(obj)
    assert stats.plan_builds == builds + 1
    points, faces, _ = evaluated_reference(obj)
    assert_matches(obj.bidegree.result.data, bidegree.subdivide(bidegree.Mesh(points, faces), 4, 2))

    # Settings changes rebuild too (degree 3).
    obj.bidegree.degree = 3
    assert stats.plan_builds == builds + 2
    assert_matches(obj.bidegree.result.data, bidegree.subdivide(bidegree.Mesh(points, faces), 3, 2))


def _non_manifold(scene: Any) -> Any:
    pts = [(0, 0, 0), (1, 0, 0), (0, 1, 0), (0, -1, 0), (0, 0, 1)]
    return make_object(scene, "Fan", pts, [(0, 1, 2), (1, 0, 3), (0, 1, 4)])


def _loose_edges(scene: Any) -> Any:
    pts = [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0), (3, 3, 3), (4, 4, 4)]
    return make_object(scene, "Loose", pts, [(0, 1, 2, 3)], edges=[(4, 5)])


def _zero_area(scene: Any) -> Any:
    pts = [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0), (2, 0, 0), (3, 0, 0), (4, 0, 0)]
    return make_object(scene, "Flat", pts, [(0, 1, 2, 3), (4, 5, 6)])


@pytest.mark.parametrize("make", [_non_manifold, _loose_edges, _zero_area])
def test_bad_meshes_leave_the_object_unchanged(addon: ModuleType, scene: Any, make: Any) -> None:
    obj = make(scene)
    before = snapshot(obj)
    errors = addon.CACHE.stats.errors
    enable(obj)
    assert obj.bidegree.last_error, "the error must be reported"
    assert obj.bidegree.result is None
    assert not [o for o in bpy.data.objects if o is not obj]
    assert snapshot(obj) == before and obj.display_type == "TEXTURED" and not obj.hide_render
    assert addon.CACHE.stats.errors == errors + 1
    import bidegree_blender

    with pytest.raises(bidegree.BidegreeError):
        bidegree_blender.subdivide_object(obj)
    assert snapshot(obj) == before


def test_huge_level_requests_are_refused(addon: ModuleType, scene: Any) -> None:
    import bidegree_blender

    obj = cube(scene)
    before = snapshot(obj)
    with pytest.raises(bidegree.LevelOutOfRangeError):
        bidegree_blender.subdivide_object(obj, levels=100000)
    # Through the panel: the property clamps to 16 levels, which is over the memory budget.
    obj.bidegree.levels = 100000
    assert obj.bidegree.levels == 16
    enable(obj)
    assert "MemoryBudget" in obj.bidegree.last_error
    assert obj.bidegree.result is None and snapshot(obj) == before
    # Back to a sane request: works, and the error is cleared.
    builds = addon.CACHE.stats.plan_builds
    # The property's update callback recomputes (in background mode: at once).
    obj.bidegree.levels = 1
    assert addon.CACHE.stats.plan_builds == builds + 1
    assert obj.bidegree.last_error == "" and obj.bidegree.result is not None
    assert addon.update(obj) == "unchanged"
    assert obj.bidegree.result_faces == 24


def test_render_levels_swap(addon: ModuleType, scene: Any) -> None:
    obj = cube(scene)
    enable(obj, levels=1, render_levels=2)
    result = obj.bidegree.result
    viewport_faces = len(result.data.polygons)
    live = sys.modules[addon.__name__ + ".live"]
    assert live.render_swap_in(scene) == 1
    assert len(result.data.polygons) == viewport_faces * 4
    live.render_swap_out()
    assert len(result.data.polygons) == viewport_faces


def test_render_uses_render_levels(addon: ModuleType, scene: Any) -> None:
    obj = cube(scene)
    enable(obj, levels=1, render_levels=2)
    result = obj.bidegree.result
    viewport_faces = len(result.data.polygons)
    seen = faces_while_rendering(scene, result)
    assert seen == [viewport_faces * 4]
    assert len(result.data.polygons) == viewport_faces


def test_apply_and_remove(addon: ModuleType, scene: Any) -> None:
    obj = cube(scene)
    obj.modifiers.new("Bevel", "BEVEL")
    enable(obj)
    expected = snapshot(obj.bidegree.result)
    with bpy.context.temp_override(object=obj, active_object=obj):
        assert bpy.ops.object.bidegree_apply() == {"FINISHED"}
    assert snapshot(obj) == expected
    assert len(obj.modifiers) == 0 and not obj.bidegree.enabled
    assert [o.name for o in bpy.data.objects] == [obj.name]
    assert obj.display_type == "TEXTURED" and not obj.hide_render

    other = cube(scene, "Other")
    enable(other)
    assert len(bpy.data.objects) == 3
    with bpy.context.temp_override(object=other, active_object=other):
        assert bpy.ops.object.bidegree_remove() == {"FINISHED"}
    assert len(bpy.data.objects) == 2 and other.display_type == "TEXTURED"


def test_duplicate_gets_its_own_result(addon: ModuleType, scene: Any) -> None:
    obj = cube(scene)
    enable(obj)
    original_result = obj.bidegree.result
    dup = obj.copy()  # what Shift+D does: the settings (and result pointer) are copied
    dup.data = obj.data.copy()
    scene.collection.objects.link(dup)
    dup.location.x = 5.0
    assert addon.update(dup) == "built"
    assert dup.bidegree.result is not None and dup.bidegree.result != original_result
    assert dup.bidegree.result.parent == dup and original_result.parent == obj
    assert obj.bidegree.result == original_result


def test_deleting_the_source_deletes_its_result(addon: ModuleType, scene: Any) -> None:
    obj = cube(scene)
    enable(obj)
    result_name = obj.bidegree.result.name
    obj.hide_viewport = True
    bpy.context.view_layer.update()
    assert bpy.data.objects[result_name].hide_viewport
    key = (obj.session_uid, "viewport")
    assert addon.CACHE.plan(key) is not None
    bpy.data.objects.remove(obj)
    bpy.context.view_layer.update()
    assert result_name not in bpy.data.objects
    assert addon.CACHE.plan(key) is None  # the plan's memory is released too


def test_export_usd_operator(addon: ModuleType, scene: Any, tmp_path: Path) -> None:
    obj = cube(scene)
    obj.modifiers.new("Bevel", "BEVEL")
    enable(obj)
    path = tmp_path / "cube.usda"
    with bpy.context.temp_override(object=obj, active_object=obj):
        assert bpy.ops.object.bidegree_export_usd(filepath=str(path)) == {"FINISHED"}
    text = path.read_text()
    assert "def Mesh" in text and "bidegree:degree = 4" in text
    import bidegree.usd
    from pxr import Usd, UsdGeom

    assert bidegree.usd.validate(path) == []
    stage = Usd.Stage.Open(str(path))
    usd_mesh = UsdGeom.Mesh(stage.GetPrimAtPath("/Bidegree/Result"))
    counts = list(usd_mesh.GetFaceVertexCountsAttr().Get())
    assert counts == [p.loop_total for p in obj.bidegree.result.data.polygons]


def test_batch_three_files_one_broken(addon: ModuleType, scene: Any, tmp_path: Path) -> None:
    good_obj = tmp_path / "good.obj"
    good_obj.write_text(
        "v -1 -1 -1\nv 1 -1 -1\nv 1 1 -1\nv -1 1 -1\nv -1 -1 1\nv 1 -1 1\nv 1 1 1\nv -1 1 1\n"
        "f 1 4 3 2\nf 5 6 7 8\nf 1 2 6 5\nf 2 3 7 6\nf 3 4 8 7\nf 4 1 5 8\n"
    )
    broken = tmp_path / "broken.obj"  # three faces on one edge: non-manifold
    broken.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 -1 0\nv 0 0 1\nf 1 2 3\nf 2 1 4\nf 1 2 5\n")
    blend = tmp_path / "scene.blend"
    obj = cube(scene, "BlendCube")
    obj.modifiers.new("Bevel", "BEVEL")
    bpy.data.libraries.write(str(blend), {scene})

    out = tmp_path / "out"
    env = dict(os.environ)
    env.pop("BLENDER_USER_RESOURCES", None)
    proc = subprocess.run(
        [
            sys.executable,
            "-m",
            "bidegree_blender.batch",
            str(good_obj),
            str(broken),
            str(blend),
            "--degree",
            "4",
            "--levels",
            "2",
            "--out",
            str(out),
            "--usd",
        ],
        capture_output=True,
        text=True,
        env=env,
        cwd=str(tmp_path),
        timeout=300,
        check=False,
    )
    lines = [ln for ln in proc.stdout.splitlines() if ln.startswith("[")]
    assert proc.returncode == 1, proc.stdout + proc.stderr
    assert len(lines) == 3, proc.stdout
    assert "FAILED" in lines[1] and "broken.obj" in lines[1]
    assert "FAILED" not in lines[0] and "FAILED" not in lines[2]
    assert sorted(p.name for p in out.glob("*.blend")) == [
        "good.bidegree.blend",
        "scene.bidegree.blend",
    ]
    assert len(list(out.glob("*.usd*"))) == 2


def test_limit_positions_and_normals(addon: ModuleType, scene: Any) -> None:
    obj = cube(scene)
    enable(obj, use_limit=True, use_limit_normals=True, degree=4, levels=2)
    assert obj.bidegree.last_error == ""
    points, faces, _ = evaluated_reference(obj)
    ref = bidegree.subdivide(
        bidegree.Mesh(points, faces), degree=4, levels=2, limit=True, normals=True
    )
    result = obj.bidegree.result.data
    assert_matches(result, ref)
    # The limit normals are the result's corner normals (custom normals).
    corner = np.zeros(3 * len(result.loops), dtype=np.float32)
    result.corner_normals.foreach_get("vector", corner)
    np.testing.assert_allclose(corner.reshape(-1, 3), ref.normals, atol=1e-5)
    # Moving a vertex re-evaluates both through the cached plan.
    obj.data.vertices[0].co = (-1.4, -1.1, -1.2)
    obj.data.update()
    assert addon.update(obj) == "reused"
    points, faces, _ = evaluated_reference(obj)
    ref = bidegree.subdivide(
        bidegree.Mesh(points, faces), degree=4, levels=2, limit=True, normals=True
    )
    assert_matches(result, ref)
    result.corner_normals.foreach_get("vector", corner)
    np.testing.assert_allclose(corner.reshape(-1, 3), ref.normals, atol=1e-5)
    # Turning the normals off removes the custom normals.
    obj.bidegree.use_limit_normals = False
    assert "custom_normal" not in obj.bidegree.result.data.attributes


def test_classic_rules_setting_matches_subdivide(addon: ModuleType, scene: Any) -> None:
    obj = cube(scene)
    enable(obj, rules="classic", degree=3, levels=2)
    assert obj.bidegree.last_error == ""
    points, faces, _ = evaluated_reference(obj)
    ref = bidegree.subdivide(bidegree.Mesh(points, faces), degree=3, levels=2, rules="classic")
    assert_matches(obj.bidegree.result.data, ref)


def test_adaptive_viewport_result(addon: ModuleType, scene: Any) -> None:
    obj = cube(scene)
    obj.data.vertices[7].co = (1.8, 1.6, 1.7)
    obj.data.update()
    enable(obj, adaptive=True, tolerance=0.003, levels=4, degree=3)
    assert obj.bidegree.last_error == ""
    result = obj.bidegree.result.data
    points, sizes, corners = mesh_arrays(result)
    assert (sizes == 3).all()

    ref_points, faces, _ = evaluated_reference(obj)
    ref = bidegree.subdivide_adaptive(
        bidegree.Mesh(ref_points, faces), degree=3, max_level=4, tolerance=0.003
    )
    assert (ref.leaves_per_level > 0).sum() >= 2
    np.testing.assert_array_equal(corners, ref.triangles.reshape(-1))
    np.testing.assert_allclose(points, ref.points, rtol=0, atol=1e-6)
    # Closed and crack-free: every edge has two triangles.
    assert 2 * len(result.edges) == 3 * len(sizes)
    assert obj.bidegree.result_faces == ref.num_triangles

    # Renders stay uniform; nothing changed means no work; turning it off is uniform again.
    assert not addon.live.settings_of(obj, render=True).adaptive
    assert addon.update(obj) == "unchanged"
    obj.bidegree.adaptive = False
    assert_matches(
        obj.bidegree.result.data, bidegree.subdivide(bidegree.Mesh(ref_points, faces), 3, 4)
    )


def test_adaptive_viewport_renders_uniform(addon: ModuleType, scene: Any) -> None:
    obj = cube(scene)
    enable(obj, adaptive=True, tolerance=0.01, levels=2, render_levels=2)
    result = obj.bidegree.result
    viewport_faces = len(result.data.polygons)
    assert all(p.loop_total == 3 for p in result.data.polygons)
    seen = faces_while_rendering(scene, result)
    assert seen == [6 * 4**2]  # uniform level 2 quads
    assert len(result.data.polygons) == viewport_faces


def test_adaptive_refuses_what_it_does_not_support(addon: ModuleType, scene: Any) -> None:
    obj = cube(scene)
    enable(obj, adaptive=True, tolerance=0.01, levels=2)
    assert obj.bidegree.last_error == ""
    before = snapshot(obj.bidegree.result)
    obj.bidegree.use_limit_normals = True
    assert "limit normals" in obj.bidegree.last_error
    assert snapshot(obj.bidegree.result) == before
