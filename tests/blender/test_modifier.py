"""bidegree as a real entry of ``obj.modifiers`` (issue 12): stack, toggles, animation, renders,
Apply, transforms, targets, collections, refusals, files and duplicates."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from util import (
    Probe,
    assert_surface,
    cage_reference,
    cube,
    cycles_coverage,
    evaluated,
    make_object,
    mesh_arrays,
    snapshot,
    update,
)

bpy = pytest.importorskip("bpy")

bidegree: Any = None
bidegree_blender: Any = None
modifier: Any = None


def subdivided(mesh: Any, **kw: Any) -> Any:
    """The surface of ``mesh`` that a modifier with the settings ``kw`` shows (primal, uniform,
    averaging: with its limit positions, on by default)."""
    return bidegree.options.Options(**{"limit": True, **kw}).subdivide(mesh)


def sort_rows(points: np.ndarray) -> np.ndarray:
    """``points`` in lexicographic order (for meshes equal up to vertex order)."""
    rounded = np.round(points, 4)
    return points[np.lexsort(rounded.T[::-1])]


def reference_object(scene: Any, result: Any, name: str = "Reference") -> Any:
    """A plain object whose mesh is ``result`` (to run reference modifiers on)."""
    sizes = np.asarray(result.face_sizes)
    idx = np.asarray(result.face_indices)
    starts = np.concatenate([[0], np.cumsum(sizes)[:-1]])
    faces = [idx[s : s + n].tolist() for s, n in zip(starts, sizes, strict=True)]
    return make_object(scene, name, np.asarray(result.points), faces)


# --------------------------------------------------------------------------- 0: the default


def test_default_is_subdivision_surfaces_limit_surface(scene: Any) -> None:
    """Limit Positions is on by default, as Subdivision Surface's Use Limit Surface: with the
    classic rules at degree 3 the surface is Blender's own default one, point for point."""
    obj = cube(scene)
    obj.data.vertices[7].co = (1.6, 1.3, 1.4)
    mod = bidegree_blender.add_modifier(obj, degree=3, levels=2, rules="classic")
    got = evaluated(obj, update())
    assert modifier.status(obj, mod).error == ""
    ref = bpy.data.objects.new("Subsurf", obj.data)
    scene.collection.objects.link(ref)
    sub = ref.modifiers.new("Subsurf", "SUBSURF")
    sub.levels = 2
    assert sub.use_limit_surface  # Blender's default
    want = evaluated(ref, update())
    assert len(got[0]) == len(want[0]) and len(got[1]) == len(want[1])
    # The same points in another order: each of Blender's has one of bidegree's within 1e-6
    # (measured 2.5e-7: float32), and no two share it.
    distance = np.linalg.norm(want[0][:, None, :] - got[0][None, :, :], axis=2)
    nearest = distance.argmin(axis=1)
    assert distance.min(axis=1).max() < 1e-6, distance.min(axis=1).max()
    assert len(set(nearest.tolist())) == len(nearest)
    refined = subdivided(cage_reference(obj, mod), degree=3, levels=2, rules="classic", limit=False)
    assert np.abs(np.asarray(refined.points) - got[0]).max() > 1e-2  # the limit made a difference


@pytest.mark.parametrize(
    "settings",
    [
        pytest.param({"output": "dual"}, id="dual"),
        pytest.param({"degree": 2, "rules": "classic"}, id="classic-2"),
        pytest.param({"adaptive": True, "tolerance": 0.01}, id="adaptive"),
        pytest.param({"levels": 0}, id="level-0"),
    ],
)
def test_limit_positions_left_out_where_the_surface_has_none(
    scene: Any, settings: dict[str, Any]
) -> None:
    """Where Options would refuse limit positions (and at level 0, which shows the cage, as
    Blender's modifier does), the default Limit Positions is left out instead of refusing."""
    obj = cube(scene)
    obj.data.vertices[7].co = (1.6, 1.3, 1.4)
    mod = bidegree_blender.add_modifier(obj, **settings)
    got = evaluated(obj, update())
    assert modifier.status(obj, mod).error == ""
    assert modifier.settings_of(mod).limit and not modifier.options_of(mod).limit
    cage = cage_reference(obj, mod)
    options = bidegree.options.Options(**settings)
    if options.adaptive:
        ref = options.subdivide_adaptive(cage)
        np.testing.assert_array_equal(got[2], ref.triangles.reshape(-1))
        np.testing.assert_allclose(got[0], ref.points, atol=1e-6)
        # Renders and exports are uniform: they have limit positions.
        assert modifier.options_of(mod, render=True).limit
        assert modifier.options_of(mod, uniform=True).limit
    else:
        assert_surface(got, options.subdivide(cage))
    if options.levels == 0:
        np.testing.assert_array_equal(got[0], np.asarray(cage.points, dtype=np.float32))
    # Back where the surface has them, the setting applies again.
    modifier.configure(mod, output="primal", rules="averaging", adaptive=False, levels=1)
    got = evaluated(obj, update())
    assert_surface(got, subdivided(cage_reference(obj, mod), degree=options.degree, levels=1))


# --------------------------------------------------------------------------- 1: the stack


def test_modifiers_after_act_on_the_surface(scene: Any) -> None:
    obj = cube(scene)
    mod = bidegree_blender.add_modifier(obj, degree=3, levels=2)
    assert list(obj.modifiers) == [mod] and mod.type == "NODES"
    displace = obj.modifiers.new("Displace", "DISPLACE")
    displace.strength = 0.3
    solidify = obj.modifiers.new("Solidify", "SOLIDIFY")
    solidify.thickness = 0.1
    got = evaluated(obj, update())

    ref = subdivided(cage_reference(obj, mod), degree=3, levels=2)
    other = reference_object(scene, ref)
    for m in (displace, solidify):
        copy = other.modifiers.new(m.name, m.type)
        for prop in ("strength", "thickness"):
            if hasattr(m, prop):
                setattr(copy, prop, getattr(m, prop))
    want = evaluated(other, update())
    assert len(got[0]) == 2 * len(ref.points)  # Solidify doubled the smooth surface
    np.testing.assert_array_equal(got[1], want[1])
    np.testing.assert_allclose(got[0], want[0], atol=1e-5)


def test_moving_it_in_the_stack(scene: Any) -> None:
    obj = cube(scene)
    bevel = obj.modifiers.new("Bevel", "BEVEL")
    bevel.width = 0.2
    mod = bidegree_blender.add_modifier(obj, degree=4, levels=1)
    # Bevel above: the bevelled cube is the cage.
    below = evaluated(obj, update())
    assert_surface(below, subdivided(cage_reference(obj, mod), degree=4, levels=1))
    assert len(below[1]) == int(cage_reference(obj, mod).face_sizes.sum())  # one quad per corner
    # bidegree first: the Bevel bevels the surface.
    with bpy.context.temp_override(object=obj):
        bpy.ops.object.modifier_move_to_index(modifier=mod.name, index=0)
    assert list(obj.modifiers) == [mod, bevel]
    above = evaluated(obj, update())
    ref = subdivided(cage_reference(obj, mod), degree=4, levels=1)
    assert len(ref.face_sizes) == 24
    other = reference_object(scene, ref)
    other.modifiers.new("Bevel", "BEVEL").width = 0.2
    want = evaluated(other, update())
    # The reference mesh numbers its edges otherwise, so the Bevel orders its output otherwise.
    assert sorted(above[1]) == sorted(want[1])
    np.testing.assert_allclose(sort_rows(above[0]), sort_rows(want[0]), atol=1e-5)


def test_toggles_viewport_and_render(scene: Any) -> None:
    obj = cube(scene)
    extra = obj.modifiers.new("Bevel", "BEVEL")  # a render-only modifier above bidegree
    extra.width = 0.3
    extra.show_viewport = False
    mod = bidegree_blender.add_modifier(obj, degree=3, levels=1, render_levels=2)
    viewport = evaluated(obj, update())
    assert len(viewport[1]) == 6 * 4  # the plain cube at level 1
    frames = Probe.render(scene)
    render = frames[0][obj.name]
    extra.show_viewport = True  # the reference cage of the render (bevelled)
    bevelled = cage_reference(obj, mod)
    extra.show_viewport = False
    assert_surface(render, subdivided(bevelled, degree=3, levels=2), atol=1e-5)

    # bidegree's own toggles: off in the viewport -> the cage; off for renders -> the cage.
    mod.show_viewport = False
    np.testing.assert_array_equal(evaluated(obj, update())[1], np.full(6, 4))
    mod.show_viewport = True
    mod.show_render = False
    frames = Probe.render(scene)
    assert len(frames[0][obj.name][1]) == len(bevelled.face_sizes)
    assert len(evaluated(obj, update())[1]) == 6 * 4
    mod.show_render = True
    # ... and the modifier above, now viewport-only: in the viewport, not in renders.
    extra.show_viewport, extra.show_render = True, False
    assert len(evaluated(obj, update())[1]) == int(bevelled.face_sizes.sum())
    assert len(Probe.render(scene)[0][obj.name][1]) == 6 * 16


def test_cycles_renders_the_render_surface(scene: Any) -> None:
    obj = cube(scene)
    mod = bidegree_blender.add_modifier(obj, degree=3, levels=1, render_levels=3)
    update()
    smooth = cycles_coverage(scene)
    mod.show_render = False  # the cage cube (its corners stick out) is rendered
    cage = cycles_coverage(scene)
    mod.show_render = True
    displace = obj.modifiers.new("Displace", "DISPLACE")  # after it, render only
    displace.strength = 0.6
    displace.show_viewport = False
    grown = cycles_coverage(scene)
    assert 0 < smooth < cage and smooth < grown
    assert len(evaluated(obj, update())[1]) == 24  # the viewport has neither


# --------------------------------------------------------------------------- 2: animation


def _shape_keyed_rig(scene: Any) -> tuple[Any, Any, Any]:
    """A cube with an animated shape key and an armature bending its top, frames 1..10."""
    obj = cube(scene)
    obj.shape_key_add(name="Basis")
    key = obj.shape_key_add(name="Stretch", from_mix=False)
    for point in key.data:
        point.co.x *= 1.5
    block = obj.data.shape_keys.key_blocks["Stretch"]
    block.value = 0.0
    block.keyframe_insert("value", frame=1)
    block.value = 1.0
    block.keyframe_insert("value", frame=10)

    arm_data = bpy.data.armatures.new("Rig")
    rig = bpy.data.objects.new("Rig", arm_data)
    scene.collection.objects.link(rig)
    bpy.context.view_layer.objects.active = rig
    bpy.ops.object.mode_set(mode="EDIT")
    bone = arm_data.edit_bones.new("Top")
    bone.head, bone.tail = (0, 0, 0), (0, 0, 1)
    bpy.ops.object.mode_set(mode="OBJECT")
    group = obj.vertex_groups.new(name="Top")
    group.add([i for i, p in enumerate(obj.data.vertices) if p.co.z > 0], 1.0, "REPLACE")
    arm = obj.modifiers.new("Armature", "ARMATURE")
    arm.object = rig
    pose = rig.pose.bones["Top"]
    pose.rotation_mode = "XYZ"
    pose.rotation_euler = (0, 0, 0)
    pose.keyframe_insert("rotation_euler", frame=1)
    pose.rotation_euler = (0.0, 0.6, 0.3)
    pose.keyframe_insert("rotation_euler", frame=10)
    mod = bidegree_blender.add_modifier(obj, degree=4, levels=2, render_levels=1)
    scene.frame_start, scene.frame_end = 1, 10
    return obj, rig, mod


def test_shape_key_and_armature_animation(scene: Any) -> None:
    obj, _rig, mod = _shape_keyed_rig(scene)
    stats = modifier.CACHE.stats
    builds = None
    seen = set()
    for frame in range(1, 11):
        scene.frame_set(frame)
        got = evaluated(obj)
        assert_surface(got, subdivided(cage_reference(obj, mod), degree=4, levels=2))
        seen.add(got[0].tobytes())
        if builds is None:
            builds = stats.plan_builds
    assert len(seen) == 10  # the surface moved every frame ...
    assert stats.plan_builds == builds  # ... through the cached plan


@pytest.mark.parametrize("render_levels", [1, 2])
def test_animation_render_has_per_frame_surfaces(scene: Any, render_levels: int) -> None:
    obj, _rig, mod = _shape_keyed_rig(scene)
    modifier.configure(mod, render_levels=render_levels)
    scene.frame_start, scene.frame_end = 2, 4
    frames = Probe.render(scene, animation=True)
    assert [f["frame"] for f in frames] == [2, 3, 4]
    for record in frames:
        scene.frame_set(record["frame"])
        ref = subdivided(cage_reference(obj, mod), degree=4, levels=render_levels)
        assert_surface(record[obj.name], ref, atol=1e-5)
    assert len({r[obj.name][0].tobytes() for r in frames}) == 3


# --------------------------------------------------------------------------- 3: Apply


#: Settings, and whether the surface has limit positions (Limit Positions is on by default and
#: left out where the surface has none: adaptive and dual output).
SETTINGS = [
    pytest.param({"degree": 3, "levels": 2, "rules": "classic"}, True, id="classic"),
    pytest.param({"degree": 4, "levels": 2, "limit": True, "normals": True}, True, id="limit"),
    pytest.param(
        {"degree": 3, "levels": 3, "adaptive": True, "tolerance": 0.01}, False, id="adaptive"
    ),
    pytest.param({"degree": 2, "levels": 2, "output": "dual"}, False, id="dual"),
    pytest.param(
        {"degree": 5, "levels": 1, "use_creases": False, "boundary": "edge-and-corner"},
        True,
        id="no-creases",
    ),
    pytest.param({"degree": 4, "levels": 2, "limit": False}, False, id="refined"),
]


@pytest.mark.parametrize(("settings", "limit"), SETTINGS)
def test_apply_bakes_what_is_shown(scene: Any, settings: dict[str, Any], limit: bool) -> None:
    obj = cube(scene)
    obj.data.vertices[7].co = (1.6, 1.3, 1.4)
    crease = obj.data.attributes.new("crease_edge", "FLOAT", "EDGE")
    crease.data[0].value = 1.0
    group = obj.vertex_groups.new(name="Weights")
    group.add([0, 1, 2, 3], 1.0, "REPLACE")
    cast = obj.modifiers.new("Cast", "CAST")  # deforms, above
    cast.factor = 0.2
    mod = bidegree_blender.add_modifier(obj, **settings)
    obj.modifiers.new("WeightedNormal", "WEIGHTED_NORMAL")  # after
    update()
    shown = mesh_arrays(modifier.holders(obj, mod)["viewport"].data)
    normals = None
    if settings.get("normals"):
        holder = modifier.holders(obj, mod)["viewport"].data
        normals = np.zeros(3 * len(holder.loops), dtype=np.float32)
        holder.corner_normals.foreach_get("vector", normals)
    # Every setting reached the surface: it is what the Options give for the cage.
    cage = cage_reference(obj, mod, crease=settings.get("use_creases", True))
    options = bidegree.options.Options(**{**settings, "limit": limit})
    if options.adaptive:
        ref = options.subdivide_adaptive(cage)
        np.testing.assert_array_equal(shown[2], ref.triangles.reshape(-1))
        np.testing.assert_allclose(shown[0], ref.points, atol=1e-6)
    else:
        mesh = bidegree.Mesh(
            cage.points,
            face_sizes=cage.face_sizes,
            face_indices=cage.face_indices,
            creases=cage.creases,
            boundary=options.boundary,
        )
        assert_surface(shown, options.subdivide(mesh))

    with bpy.context.temp_override(object=obj, active_object=obj):
        assert bpy.ops.object.modifier_apply(modifier=mod.name) == {"FINISHED"}
    applied = mesh_arrays(obj.data)
    for a, b in zip(applied, shown, strict=True):
        np.testing.assert_array_equal(a, b)  # bit for bit
    if normals is not None:
        got = np.zeros(3 * len(obj.data.loops), dtype=np.float32)
        obj.data.corner_normals.foreach_get("vector", got)
        np.testing.assert_allclose(got, normals, atol=1e-6)
    assert [m.type for m in obj.modifiers] == ["CAST", "WEIGHTED_NORMAL"]
    assert [g.name for g in obj.vertex_groups] == ["Weights"]
    update()
    assert not [ob for ob in bpy.data.objects if modifier.is_holder(ob)]


def test_apply_keeps_vertex_group_weights(scene: Any) -> None:
    obj = cube(scene)
    group = obj.vertex_groups.new(name="Top")
    weights = np.array([0.0, 0.25, 0.5, 1.0, 0.0, 0.5, 0.75, 1.0], dtype=np.float32)
    for i, w in enumerate(weights):
        group.add([i], float(w), "REPLACE")
    obj.vertex_groups.new(name="Empty")
    mod = bidegree_blender.add_modifier(obj, degree=3, levels=1)
    update()
    plan = bidegree.Plan(cage_reference(obj, mod), degree=3, levels=1)
    expected = np.clip(plan.evaluate(weights), 0, 1)
    with bpy.context.temp_override(object=obj, active_object=obj):
        assert bpy.ops.object.bidegree_apply() == {"FINISHED"}
    assert [g.name for g in obj.vertex_groups] == ["Top", "Empty"]
    got = np.zeros(len(obj.data.vertices), dtype=np.float32)
    for v in obj.data.vertices:
        for e in v.groups:
            if obj.vertex_groups[e.group].name == "Top":
                got[v.index] = e.weight
    np.testing.assert_allclose(got, expected, atol=1e-6)


def test_apply_refuses_shape_keys(scene: Any) -> None:
    obj = cube(scene)
    obj.shape_key_add(name="Basis")
    obj.shape_key_add(name="Key")
    mod = bidegree_blender.add_modifier(obj)
    update()
    before = snapshot(obj)
    with (
        bpy.context.temp_override(object=obj, active_object=obj),
        pytest.raises(RuntimeError, match="shape keys"),
    ):
        bpy.ops.object.modifier_apply(modifier=mod.name)
    assert snapshot(obj) == before and mod.name in obj.modifiers


# --------------------------------------------------------------------------- 4: transforms


def _world_surface(obj: Any) -> np.ndarray:
    points = evaluated(obj, update())[0].astype(np.float64)
    matrix = np.array(obj.matrix_world)
    return points @ matrix[:3, :3].T + matrix[:3, 3]


@pytest.mark.parametrize("how", ["scale", "location", "origin"])
def test_transforms_keep_the_surface_on_the_cage(scene: Any, how: str) -> None:
    obj = cube(scene)
    obj.data.vertices[0].co = (-1.5, -1.2, -1.0)
    obj.location = (2.0, -1.0, 0.5)
    obj.scale = (2.0, 1.0, 0.5)
    bidegree_blender.add_modifier(obj, degree=3, levels=2)
    before = _world_surface(obj)
    bpy.context.view_layer.objects.active = obj
    obj.select_set(True)
    with bpy.context.temp_override(
        object=obj, active_object=obj, selected_objects=[obj], selected_editable_objects=[obj]
    ):
        if how == "origin":
            assert bpy.ops.object.origin_set(type="ORIGIN_GEOMETRY") == {"FINISHED"}
        else:
            assert bpy.ops.object.transform_apply(
                location=how == "location", rotation=False, scale=how == "scale"
            ) == {"FINISHED"}
    np.testing.assert_allclose(_world_surface(obj), before, atol=1e-5)


# --------------------------------------------------------------------------- 6: targets


def test_object_info_and_boolean_see_the_surface(scene: Any) -> None:
    obj = cube(scene)
    mod = bidegree_blender.add_modifier(obj, degree=4, levels=2)
    update()
    surface = mesh_arrays(modifier.holders(obj, mod)["viewport"].data)

    viewer = make_object(scene, "Viewer", [(0, 0, 0)], [])
    group = bpy.data.node_groups.new("Info", "GeometryNodeTree")
    group.interface.new_socket("Geometry", in_out="OUTPUT", socket_type="NodeSocketGeometry")
    info = group.nodes.new("GeometryNodeObjectInfo")
    info.inputs["Object"].default_value = obj
    out = group.nodes.new("NodeGroupOutput")
    group.links.new(info.outputs["Geometry"], out.inputs[0])
    viewer.modifiers.new("Info", "NODES").node_group = group
    seen = evaluated(viewer, update())
    np.testing.assert_array_equal(seen[1], surface[1])
    np.testing.assert_allclose(seen[0], surface[0], atol=1e-6)

    cutter_target = cube(scene, "Cut")
    cutter_target.location = (1.0, 0.0, 0.0)
    boolean = cutter_target.modifiers.new("Boolean", "BOOLEAN")
    boolean.object = obj
    boolean.operation = "DIFFERENCE"
    plain = reference_object(
        scene,
        type(
            "R", (), {"points": surface[0], "face_sizes": surface[1], "face_indices": surface[2]}
        )(),
    )
    check = cube(scene, "Check")
    check.location = (1.0, 0.0, 0.0)
    check_bool = check.modifiers.new("Boolean", "BOOLEAN")
    check_bool.object = plain
    check_bool.operation = "DIFFERENCE"
    plain.hide_viewport = False
    depsgraph = update()
    got, want = evaluated(cutter_target, depsgraph), evaluated(check, depsgraph)
    assert len(got[1]) > 6
    np.testing.assert_array_equal(got[1], want[1])
    np.testing.assert_allclose(got[0], want[0], atol=1e-5)


# --------------------------------------------------------------------------- 7: collections


def test_collections_hide_the_surface(scene: Any) -> None:
    obj = cube(scene)
    mod = bidegree_blender.add_modifier(obj, degree=3, levels=2)
    depsgraph = update()
    faces = len(evaluated(obj, depsgraph)[1])
    moved = bpy.data.collections.new("Moved")
    scene.collection.children.link(moved)
    moved.objects.link(obj)
    scene.collection.objects.unlink(obj)
    depsgraph = update()
    assert len(evaluated(obj, depsgraph)[1]) == faces  # the surface moved with it
    # Holders are never drawn, rendered or exported themselves: the object is all there is.
    assert {ob.original.name for ob in depsgraph.objects} == {obj.name}
    assert not [h for h in modifier.holders(obj, mod).values() if h.users_collection]
    layer = bpy.context.view_layer.layer_collection.children["Moved"]
    layer.hide_viewport = True
    update()
    assert not obj.visible_get()
    layer.hide_viewport = False
    layer.exclude = True
    depsgraph = update()
    assert not [i.object.name for i in depsgraph.object_instances if i.object.type == "MESH"]
    layer.exclude = False
    moved.hide_render = True
    assert obj.name not in Probe.render(scene)[0]
    moved.hide_render = False
    assert len(Probe.render(scene)[0][obj.name][1]) == 6 * 4**3
    obj.hide_render = True
    assert obj.name not in Probe.render(scene)[0]


# --------------------------------------------------------------------------- 8: refusals


def _nan_point(scene: Any) -> Any:
    pts = [(0, 0, 0), (1, 0, 0), (1, 1, 0), (float("nan"), 1, 0)]
    return make_object(scene, "NaN", pts, [(0, 1, 2, 3)])


def test_refusals_show_the_cage_and_a_message(scene: Any) -> None:
    obj = cube(scene)
    mod = bidegree_blender.add_modifier(obj, degree=3, levels=2)
    update()
    assert len(evaluated(obj)[1]) == 96
    # Memory budget: 16 levels.
    before = snapshot(obj)
    modifier.configure(mod, levels=16)
    got = evaluated(obj, update())
    assert "MemoryBudget" in modifier.status(obj, mod).error
    assert modifier.get_input(mod, "Error") == modifier.status(obj, mod).error
    np.testing.assert_array_equal(got[1], np.full(6, 4))  # the cage, not the old surface
    assert snapshot(obj) == before
    modifier.configure(mod, levels=1)
    assert len(evaluated(obj, update())[1]) == 24 and modifier.status(obj, mod).error == ""

    # A refused mesh (a non-finite point: dirty topology is subdivided), on its own object.
    bad = _nan_point(scene)
    bad_mod = bidegree_blender.add_modifier(bad)
    before = snapshot(bad)
    got = evaluated(bad, update())
    assert "NonFinite" in modifier.status(bad, bad_mod).error
    assert len(got[1]) == 1 and snapshot(bad) == before

    # An empty mesh (no vertices at all).
    empty = make_object(scene, "Empty", [], [])
    empty_mod = bidegree_blender.add_modifier(empty)
    assert len(evaluated(empty, update())[0]) == 0
    assert "EmptyMesh" in modifier.status(empty, empty_mod).error


def test_a_good_surface_is_not_kept_after_a_refusal(scene: Any) -> None:
    obj = cube(scene)
    mod = bidegree_blender.add_modifier(obj, degree=3, levels=1)
    update()
    obj.data.vertices[1].co = (float("nan"), 0.0, 0.0)  # zero-area faces would subdivide
    obj.data.update()
    got = evaluated(obj, update())
    assert "NonFinite" in modifier.status(obj, mod).error
    np.testing.assert_array_equal(got[1], np.full(6, 4))


# --------------------------------------------------------------------------- 9: files


_WITHOUT_EXTENSION = r"""
import sys, bpy
bpy.ops.wm.open_mainfile(filepath=sys.argv[-1])
ob = bpy.data.objects["Cube"]
dg = bpy.context.evaluated_depsgraph_get()
print("FACES", len(ob.evaluated_get(dg).data.polygons))
class Probe(bpy.types.RenderEngine):
    bl_idname = "PROBE"
    bl_label = "probe"
    def render(self, depsgraph):
        print("RENDER", len(ob.evaluated_get(depsgraph).data.polygons))
bpy.utils.register_class(Probe)
scene = bpy.context.scene
cam = bpy.data.objects.new("Cam", bpy.data.cameras.new("Cam"))
scene.collection.objects.link(cam)
scene.camera = cam
scene.render.engine = "PROBE"
scene.render.resolution_x = scene.render.resolution_y = 4
bpy.ops.render.render()
# A setting changed where bidegree cannot recompute: the stale surface is not shown.
mod = ob.modifiers["bidegree"]
items = mod.node_group.interface.items_tree
ident = {i.name: i.identifier for i in items if i.item_type == "SOCKET"}
mod[ident["Degree"]] = 5
ob.update_tag()
dg = bpy.context.evaluated_depsgraph_get()
print("STALE", len(ob.evaluated_get(dg).data.polygons))
sys.stdout.flush()
import os
os._exit(0)  # bpy 4.2 can crash while freeing a Python-defined render engine at exit
"""


def test_file_without_the_extension_shows_and_renders_the_surface(
    scene: Any, tmp_path: Path
) -> None:
    obj = cube(scene)
    bidegree_blender.add_modifier(obj, degree=4, levels=2, render_levels=3)
    update()
    Probe.render(scene)  # fills the render surface: it is not saved
    path = tmp_path / "saved.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(path), copy=True)
    env = dict(os.environ)
    env.pop("BLENDER_USER_RESOURCES", None)  # a Blender without the extension
    proc = subprocess.run(
        [sys.executable, "-c", _WITHOUT_EXTENSION, str(path)],
        capture_output=True,
        text=True,
        env=env,
        timeout=300,
        check=False,
    )
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert "FACES 96" in proc.stdout and "RENDER 96" in proc.stdout, proc.stdout[-2000:]
    assert "STALE 6" in proc.stdout, proc.stdout[-2000:]  # the cage

    # With the extension: updates resume.
    bpy.ops.wm.open_mainfile(filepath=str(path))
    obj = bpy.data.objects["Cube"]
    mod = modifier.bidegree_modifiers(obj)[0]
    obj.data.vertices[0].co = (-2.0, -1.0, -1.0)
    obj.data.update()
    assert_surface(evaluated(obj, update()), subdivided(cage_reference(obj, mod), levels=2))


def _holders_and_orphans() -> tuple[int, list[str]]:
    holders = [ob for ob in bpy.data.objects if modifier.is_holder(ob)]
    orphans = [
        f"{kind}:{item.name}"
        for kind, coll in (("object", bpy.data.objects), ("mesh", bpy.data.meshes))
        for item in coll
        if item.users == 0
    ]
    return len(holders), orphans


def test_duplicates_delete_and_reload_leave_no_orphans(scene: Any, tmp_path: Path) -> None:
    obj = cube(scene)
    bidegree_blender.add_modifier(obj, degree=3, levels=1)
    update()
    assert _holders_and_orphans() == (2, [])
    for linked in (False, True):
        for ob in scene.objects:
            ob.select_set(ob == obj)
        bpy.context.view_layer.objects.active = obj
        with bpy.context.temp_override(
            object=obj, active_object=obj, selected_objects=[obj], selected_editable_objects=[obj]
        ):
            assert bpy.ops.object.duplicate(linked=linked) == {"FINISHED"}
    update()
    copies = [ob for ob in scene.objects if ob is not obj and not modifier.is_holder(ob)]
    assert len(copies) == 2 and copies[1].data == obj.data  # Alt+D shares the mesh
    holders = set()
    for ob in [obj, *copies]:
        (m,) = modifier.bidegree_modifiers(ob)
        own = modifier.holders(ob, m)
        holders |= {own["viewport"].name, own["render"].name}
        ob.location.x += 3.0
    assert len(holders) == 6 and _holders_and_orphans() == (6, [])
    copies[0].data.vertices[0].co = (-3.0, -1.0, -1.0)  # Shift+D copied the mesh: only its own
    copies[0].data.update()
    depsgraph = update()
    assert evaluated(copies[0], depsgraph)[0].min() < evaluated(obj, depsgraph)[0].min() - 0.1

    names = [obj.name, copies[0].name]
    path = tmp_path / "dups.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(path))
    bpy.ops.wm.open_mainfile(filepath=str(path))
    update()
    assert _holders_and_orphans() == (6, [])
    deleted = bpy.data.objects[names[1]]
    own_mesh = deleted.data
    bpy.data.objects.remove(deleted)
    bpy.data.meshes.remove(own_mesh)  # the user's mesh: Blender leaves it to Purge
    update()
    assert _holders_and_orphans() == (4, [])
    removed = bpy.data.objects[names[0]]
    removed.modifiers.remove(modifier.bidegree_modifiers(removed)[0])
    update()
    assert _holders_and_orphans() == (2, [])
