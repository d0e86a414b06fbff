"""The bidegree extension installed from its built zip into headless bpy: registration, the
live surface's data and cache, the one settings path (issue 15), typed errors (issue 18), the
batch."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path
from types import ModuleType
from typing import Any

import numpy as np
import pytest
from util import cage_reference, cube, evaluated, make_object, mesh_arrays, snapshot, update

bpy = pytest.importorskip("bpy")

#: The installed extension's modules (set by conftest's autouse ``_installed_modules``, after
#: the extension was installed, so the installed copies are the ones used).
bidegree: Any = None
bidegree_blender: Any = None
modifier: Any = None


ROOT = Path(__file__).resolve().parents[2]


def test_installed_copy_is_used(
    addon: ModuleType, user_dir: str, bidegree_preimported: bool
) -> None:
    assert addon.__file__.startswith(user_dir), addon.__file__
    assert bidegree_blender.__file__.startswith(user_dir), bidegree_blender.__file__
    if bidegree_preimported:
        pytest.skip("bidegree was imported before the extension: run `pytest tests/blender` alone")
    assert bidegree.__file__.startswith(user_dir), bidegree.__file__


def test_registration(addon: ModuleType, scene: Any) -> None:
    panel = bpy.types.Panel.bl_rna_get_subclass_py("BIDEGREE_PT_surface")
    assert panel is not None and panel.bl_context == "modifier"
    for name in ("bidegree_add", "bidegree_apply", "bidegree_export_usd"):
        assert getattr(bpy.ops.object, name).get_rna_type() is not None
    handlers = sys.modules[addon.__name__ + ".handlers"]
    for name, fn in handlers._HANDLERS:
        assert fn in getattr(bpy.app.handlers, name)
    obj = cube(scene)
    scene.render.use_lock_interface = False
    with bpy.context.temp_override(object=obj, active_object=obj, scene=scene):
        assert bpy.ops.object.bidegree_add() == {"FINISHED"}
    (mod,) = modifier.bidegree_modifiers(obj)
    assert obj.modifiers.active == mod and scene.render.use_lock_interface
    # The settings are the modifier's inputs, with the defaults of Options but Limit Positions,
    # which is on, as Subdivision Surface's Use Limit Surface.
    defaults = bidegree.options.Options(limit=True)
    # (Blender stores the tolerance as float32.)
    assert modifier.options_of(mod) == defaults.replace(tolerance=float(np.float32(1e-3)))
    assert modifier.get_input(mod, "Render Levels") == 3
    tree = mod.node_group
    hidden = {i.name for i in tree.interface.items_tree if getattr(i, "hide_in_modifier", False)}
    assert hidden == {"Surface", "Render Surface", "Error"}
    assert modifier.ensure_node_group() == tree  # one node group per file


def test_creases_uvs_materials_and_shading_survive(scene: Any) -> None:
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
    mod = bidegree_blender.add_modifier(obj)
    update()
    assert modifier.status(obj, mod).error == ""
    out = modifier.holders(obj, mod)["viewport"].data

    cage = cage_reference(obj, mod)
    uvs = np.array([tuple(d.uv) for d in me.uv_layers["UVMap"].data], dtype=np.float32)
    ref = bidegree.subdivide(
        bidegree.Mesh(
            cage.points,
            face_sizes=cage.face_sizes,
            face_indices=cage.face_indices,
            creases=cage.creases,
            corners=(np.array([6]), np.array([10.0 * 0.8**2], dtype=np.float32)),
            uvs=uvs,
        ),
        4,
        2,
        limit=True,
    )
    points, _sizes, corners = mesh_arrays(out)
    np.testing.assert_array_equal(corners, ref.face_indices)
    np.testing.assert_allclose(points, ref.points, atol=1e-6)
    smooth = bidegree.subdivide(
        bidegree.Mesh(cage.points, face_sizes=cage.face_sizes, face_indices=cage.face_indices),
        4,
        2,
        limit=True,
    )
    assert np.abs(np.asarray(smooth.points) - np.asarray(ref.points)).max() > 1e-3
    assert set(out.uv_layers.keys()) == {"UVMap", "Second"}
    got_uv = np.array([tuple(d.uv) for d in out.uv_layers["UVMap"].data], dtype=np.float32)
    np.testing.assert_allclose(got_uv, np.asarray(ref.uvs), atol=1e-6)
    origin = np.asarray(ref.face_origin)
    np.testing.assert_array_equal(
        [p.material_index for p in out.polygons], np.array(mat_index)[origin]
    )
    np.testing.assert_array_equal(
        [p.use_smooth for p in out.polygons], np.array(mat_index)[origin] == 1
    )
    assert [m.name for m in out.materials] == ["Red", "Blue"]
    # ... and reach the object's evaluated mesh through the node group.
    final = obj.evaluated_get(bpy.context.evaluated_depsgraph_get()).data
    assert set(final.uv_layers.keys()) == {"UVMap", "Second"}
    assert [p.material_index for p in final.polygons] == [p.material_index for p in out.polygons]


def test_edits_reuse_the_plan(scene: Any) -> None:
    obj = cube(scene)
    mod = bidegree_blender.add_modifier(obj)
    update()
    stats = modifier.CACHE.stats
    builds, reuses, skips = stats.plan_builds, stats.plan_reuses, stats.skips
    key = modifier.cache_key(obj, mod, "viewport")
    plan = modifier.CACHE.plan(key)
    assert plan is not None
    update()  # nothing changed: no work
    assert stats.plan_builds == builds and stats.plan_reuses == reuses
    obj.data.vertices[0].co = (-1.5, -1.2, -1.1)
    obj.data.update()
    got = evaluated(obj, update())
    assert stats.plan_builds == builds and stats.plan_reuses == reuses + 1
    assert modifier.CACHE.plan(key) is plan and stats.skips >= skips
    ref = bidegree.subdivide(cage_reference(obj, mod), 4, 2, limit=True)
    np.testing.assert_allclose(got[0], ref.points, atol=1e-6)
    # A topology change (a modifier above) and a settings change rebuild the plan.
    tri = obj.modifiers.new("Tri", "TRIANGULATE")
    with bpy.context.temp_override(object=obj):
        bpy.ops.object.modifier_move_to_index(modifier=tri.name, index=0)
    update()
    assert stats.plan_builds == builds + 1
    modifier.configure(mod, degree=3)
    got = evaluated(obj, update())
    assert stats.plan_builds == builds + 2
    np.testing.assert_allclose(
        got[0], bidegree.subdivide(cage_reference(obj, mod), 3, 2, limit=True).points, atol=1e-6
    )


def test_long_work_is_known_before_it_starts(addon: ModuleType, scene: Any) -> None:
    """What the GUI announces (status bar, progress cursor) before a large update blocks."""
    handlers = sys.modules[addon.__name__ + ".handlers"]
    obj = cube(scene)
    mod = bidegree_blender.add_modifier(obj, levels=10)
    assert modifier.begin_read([obj]) == 1
    try:
        assert modifier.estimated_faces() == 6 * 4**10 > handlers.PROGRESS_FACES
        assert not mod.show_viewport  # switched off for the cage read
    finally:
        modifier.end_read(None)
    assert mod.show_viewport and modifier.estimated_faces() == 0


def test_gui_reads_only_the_cages_that_change(addon: ModuleType, scene: Any) -> None:
    """The GUI's policy (handlers.PREDICT): updates that touch no bidegree object cost nothing,
    one that changed unexpectedly gets its surface from the follow-up evaluation."""
    handlers = sys.modules[addon.__name__ + ".handlers"]
    obj = cube(scene)
    other = cube(scene, "Other")
    saved = handlers.PREDICT
    handlers.PREDICT = True
    try:
        mod = bidegree_blender.add_modifier(obj, degree=3, levels=1)
        assert len(evaluated(obj, update())[1]) == 6  # not expected yet: the cage, for now
        assert modifier.stale_objects() == [obj]
        handlers._follow_up()  # the timer the GUI runs next
        assert len(evaluated(obj, update())[1]) == 24 and not modifier.stale_objects()
        stats = modifier.CACHE.stats
        reads = stats.plan_reuses + stats.skips + stats.plan_builds
        other.location.x += 1.0  # one read more (it was expected), then none
        update()
        for _ in range(3):
            other.location.x += 1.0
            update()
        assert stats.plan_reuses + stats.skips + stats.plan_builds == reads + 1
        obj.data.vertices[0].co.x -= 0.5
        obj.data.update()
        update()
        handlers._follow_up()
        got = evaluated(obj, update())
        np.testing.assert_allclose(
            got[0],
            bidegree.subdivide(cage_reference(obj, mod), 3, 1, limit=True).points,
            atol=1e-6,
        )
    finally:
        handlers.PREDICT = saved


# --------------------------------------------------------------------------- issue 15


def test_one_settings_path() -> None:
    """Settings of the modifier, the batch, the export and subdivide_object are Options."""
    import argparse
    import dataclasses

    from bidegree_blender import pipeline
    from bidegree_blender.batch import convert

    job_settings = {f.name: f.type for f in dataclasses.fields(convert.Job)}["settings"]
    assert job_settings in ("Options", bidegree.options.Options)
    options = bidegree.options.Options(
        degree=3, levels=1, rules="classic", limit=True, memory_budget=1 << 20
    )
    args = argparse.Namespace(
        degree=3,
        levels=1,
        rules="classic",
        limit=True,
        memory_budget=1 << 20,
        boundary=None,
        normals=False,
    )
    assert bidegree.options.Options.from_namespace(args) == options
    import inspect

    assert "options" in inspect.signature(pipeline.subdivide_object).parameters


def test_subdivide_object_takes_every_setting(scene: Any) -> None:
    obj = cube(scene)
    obj.data.vertices[7].co = (1.5, 1.2, 1.3)
    cage = cage_reference(obj, None)
    for options in (
        bidegree.options.Options(degree=3, levels=2, rules="classic", limit=True),
        bidegree.options.Options(degree=4, levels=1, limit=True, normals=True),
        bidegree.options.Options(degree=2, levels=2, output="dual", boundary="edge-and-corner"),
    ):
        mesh = bidegree_blender.subdivide_object(obj, options=options)
        try:
            ref = options.subdivide(
                bidegree.Mesh(
                    cage.points,
                    face_sizes=cage.face_sizes,
                    face_indices=cage.face_indices,
                    boundary=options.boundary,
                )
            )
            points, _sizes, corners = mesh_arrays(mesh)
            np.testing.assert_array_equal(corners, ref.face_indices)
            np.testing.assert_allclose(points, ref.points, atol=1e-6)
        finally:
            bpy.data.meshes.remove(mesh)
    with pytest.raises(bidegree.MemoryBudgetError):
        bidegree_blender.subdivide_object(obj, levels=8, memory_budget=1 << 20)


# --------------------------------------------------------------------------- issue 18


def test_typed_errors(scene: Any) -> None:
    obj = cube(scene)
    before = snapshot(obj)
    with pytest.raises(bidegree.InvalidInputError, match="degree"):
        bidegree_blender.subdivide_object(obj, degree="x")
    with pytest.raises(bidegree.InvalidInputError, match="rules"):
        bidegree_blender.subdivide_object(obj, rules="fancy")
    with pytest.raises(bidegree.LevelOutOfRangeError):
        bidegree_blender.subdivide_object(obj, levels=100000)
    with pytest.raises(bidegree.InvalidInputError, match="unknown bidegree setting"):
        bidegree_blender.add_modifier(obj, colour="red")
    assert not modifier.bidegree_modifiers(obj) and snapshot(obj) == before
    empty = make_object(scene, "Empty", [], [])
    with pytest.raises(bidegree.EmptyMeshError, match="no vertices"):
        bidegree_blender.subdivide_object(empty)
    lamp = bpy.data.objects.new("Lamp", bpy.data.lights.new("Lamp", "POINT"))
    with pytest.raises(bidegree.InvalidInputError, match="not a mesh"):
        bidegree_blender.subdivide_object(lamp)
    with pytest.raises(bidegree.InvalidInputError, match="mesh object"):
        bidegree_blender.add_modifier(lamp)
    bpy.data.lights.remove(lamp.data)


def _loose_edges(scene: Any) -> Any:
    pts = [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0), (3, 3, 3), (4, 4, 4)]
    return make_object(scene, "Loose", pts, [(0, 1, 2, 3)], edges=[(4, 5)])


def _zero_area(scene: Any) -> Any:
    pts = [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0), (2, 0, 0), (3, 0, 0), (4, 0, 0)]
    return make_object(scene, "Flat", pts, [(0, 1, 2, 3), (4, 5, 6)])


def _non_manifold(scene: Any) -> Any:
    pts = [(0, 0, 0), (1, 0, 0), (0, 1, 0), (0, -1, 0), (0, 0, 1)]
    return make_object(scene, "Fan", pts, [(0, 1, 2), (1, 0, 3), (0, 1, 4)])


def _flipped(scene: Any) -> Any:
    pts = [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0), (2, 0, 0), (2, 1, 0)]
    return make_object(scene, "Flipped", pts, [(0, 1, 2, 3), (1, 2, 5, 4)])


def _nan_point(scene: Any) -> Any:
    pts = [(0, 0, 0), (1, 0, 0), (1, 1, 0), (float("nan"), 1, 0)]
    return make_object(scene, "NaN", pts, [(0, 1, 2, 3)])


@pytest.mark.parametrize("make", [_loose_edges, _zero_area, _non_manifold, _flipped])
def test_dirty_meshes_subdivide(scene: Any, make: Any) -> None:
    """What Blender's Subdivision Surface modifier subdivides, the add-on does (issue 13); the
    loose edges are left out with a warning in the panel."""
    obj = make(scene)
    cage_faces = len(obj.data.polygons)
    mod = bidegree_blender.add_modifier(obj)
    got = evaluated(obj, update())
    status = modifier.status(obj, mod)
    assert status.error == ""
    assert len(got[1]) > cage_faces
    if make is _loose_edges:
        assert "loose edge" in status.warning
    out = bidegree_blender.subdivide_object(obj)
    try:
        assert len(out.polygons) > cage_faces
    finally:
        bpy.data.meshes.remove(out)


def test_bad_meshes_leave_the_object_unchanged(scene: Any) -> None:
    obj = _nan_point(scene)
    before = snapshot(obj)
    mod = bidegree_blender.add_modifier(obj)
    got = evaluated(obj, update())
    assert modifier.status(obj, mod).error
    assert snapshot(obj) == before and got[1].tolist() == mesh_arrays(obj.data)[1].tolist()
    with pytest.raises(bidegree.BidegreeError):
        bidegree_blender.subdivide_object(obj)
    assert snapshot(obj) == before


def test_adaptive_refuses_what_it_does_not_support(scene: Any) -> None:
    obj = cube(scene)
    mod = bidegree_blender.add_modifier(obj, adaptive=True, tolerance=0.01, levels=2)
    update()
    assert modifier.status(obj, mod).error == ""
    assert all(n == 3 for n in evaluated(obj)[1])
    modifier.configure(mod, normals=True)
    got = evaluated(obj, update())
    assert "limit normals" in modifier.status(obj, mod).error
    assert got[1].tolist() == [4] * 6  # the cage, not the last surface


def test_batch_three_files_one_broken(addon: ModuleType, scene: Any, tmp_path: Path) -> None:
    good_obj = tmp_path / "good.obj"
    good_obj.write_text(
        "v -1 -1 -1\nv 1 -1 -1\nv 1 1 -1\nv -1 1 -1\nv -1 -1 1\nv 1 -1 1\nv 1 1 1\nv -1 1 1\n"
        "f 1 4 3 2\nf 5 6 7 8\nf 1 2 6 5\nf 2 3 7 6\nf 3 4 8 7\nf 4 1 5 8\n"
    )
    # Only a loose edge: nothing to subdivide (Blender's OBJ importer drops what it cannot read,
    # faces on missing vertices and non-finite numbers included, so this is what stays broken).
    broken = tmp_path / "broken.obj"
    broken.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nl 1 2\n")
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
