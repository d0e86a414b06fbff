"""Every Blender attribute on the surface (issue 14, Blender part): point, corner, face and edge
domains, vertex and edge creases, custom normals, the UV Smooth setting, Apply.

References are independent of the add-on's reading path: the cage arrays come from the plain
per-element API, point and corner values from the core's own ``Plan.evaluate`` /
``evaluate_face_varying`` on the same cage, child edges and nearest vertices from geometry
(degree 1: the surface is the cage's bilinear refinement), custom normals from Blender's
Subdivision Surface.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest
from util import CUBE_FACES, CUBE_POINTS, make_object, update

bpy = pytest.importorskip("bpy")

bidegree: Any = None
bidegree_blender: Any = None
modifier: Any = None


def grid(scene: Any, n: int = 3, name: str = "Grid") -> Any:
    """An n x n grid of unit quads in the plane z = 0 (open: it has a boundary)."""
    points = [(float(x), float(y), 0.0) for y in range(n + 1) for x in range(n + 1)]
    faces = [
        (y * (n + 1) + x, y * (n + 1) + x + 1, (y + 1) * (n + 1) + x + 1, (y + 1) * (n + 1) + x)
        for y in range(n)
        for x in range(n)
    ]
    return make_object(scene, name, points, faces)


def get(mesh: Any, name: str) -> np.ndarray:
    """An attribute's values with the per-element API (no ``foreach_get``)."""
    attr = mesh.attributes[name]
    prop = {"FLOAT_VECTOR": "vector", "FLOAT2": "vector", "FLOAT_COLOR": "color"}.get(
        attr.data_type, "color" if attr.data_type == "BYTE_COLOR" else "value"
    )
    return np.array([np.asarray(getattr(d, prop)) for d in attr.data])


def put(mesh: Any, name: str, data_type: str, domain: str, values: Any) -> None:
    attr = mesh.attributes.new(name, data_type, domain)
    prop = {"FLOAT_VECTOR": "vector", "FLOAT2": "vector"}.get(data_type, "value")
    if data_type in ("FLOAT_COLOR", "BYTE_COLOR"):
        prop = "color"
    for d, v in zip(attr.data, values, strict=True):
        setattr(d, prop, v.tolist() if isinstance(v, np.ndarray) else v)


def plain_cage(mesh: Any) -> Any:
    points = np.array([tuple(v.co) for v in mesh.vertices], dtype=np.float64)
    faces = [list(p.vertices) for p in mesh.polygons]
    return bidegree.Mesh(points, faces)


def subdivided(obj: Any, **settings: Any) -> Any:
    return bidegree_blender.subdivide_object(obj, **settings)


# --------------------------------------------------------------------------- point domain


def test_point_attributes_are_the_scheme_applied(scene: Any) -> None:
    obj = make_object(scene, "Cube", CUBE_POINTS, CUBE_FACES)
    rng = np.random.default_rng(1)
    weight = rng.random(8).astype(np.float32)
    vector = rng.normal(size=(8, 3)).astype(np.float32)
    colour = rng.random((8, 4)).astype(np.float32)
    me = obj.data
    put(me, "weight", "FLOAT", "POINT", weight)
    put(me, "offset", "FLOAT_VECTOR", "POINT", vector)
    put(me, "paint", "FLOAT_COLOR", "POINT", colour)
    put(me, "label", "INT", "POINT", np.arange(8) * 10)
    put(me, "mask", "BOOLEAN", "POINT", [bool(i % 2) for i in range(8)])
    me.color_attributes.new("second", "BYTE_COLOR", "CORNER")
    me.color_attributes.active_color_name = "second"
    me.color_attributes.default_color_name = "paint"
    result = subdivided(obj, degree=4, levels=2)
    assert result.color_attributes.active_color_name == "second"
    assert result.color_attributes.default_color_name == "paint"
    plan = bidegree.Plan(plain_cage(me), degree=4, levels=2)
    stacked = np.concatenate([weight[:, None], vector, colour], axis=1).astype(np.float64)
    expected = plan.evaluate(stacked)
    np.testing.assert_allclose(get(result, "weight"), expected[:, 0], atol=1e-6)
    np.testing.assert_allclose(get(result, "offset"), expected[:, 1:4], atol=1e-6)
    np.testing.assert_allclose(get(result, "paint"), expected[:, 4:8], atol=1e-6)
    # Integers and booleans: a value of a vertex of the origin face, the cage vertex's own at
    # the cage vertices.
    labels, mask = get(result, "label"), get(result, "mask")
    assert set(labels.tolist()) <= set(range(0, 80, 10))
    np.testing.assert_array_equal(mask, (labels // 10) % 2 == 1)
    bpy.data.meshes.remove(result)


def test_integers_take_the_nearest_vertex_of_the_face(scene: Any) -> None:
    # Degree 1 on a flat grid: the surface is the cage's bilinear refinement, so the nearest
    # cage vertex of a point's face is a matter of geometry.
    obj = grid(scene, 2)
    put(obj.data, "label", "INT", "POINT", np.arange(9) * 7)
    result = subdivided(obj, degree=1, levels=3)
    points = np.array([tuple(v.co) for v in result.vertices])
    labels = get(result, "label")
    cage = np.array([tuple(v.co) for v in obj.data.vertices])
    distance = np.linalg.norm(points[:, None, :2] - cage[None, :, :2], axis=2)
    # Points within a unit square: the nearest corner is the nearest grid vertex; skip ties.
    order = np.sort(distance, axis=1)
    clear = order[:, 1] - order[:, 0] > 1e-6
    assert clear.sum() > len(points) // 2
    np.testing.assert_array_equal(labels[clear], 7 * np.argmin(distance, axis=1)[clear])
    bpy.data.meshes.remove(result)


# --------------------------------------------------------------------------- corner, face


def test_corner_and_face_attributes(scene: Any) -> None:
    obj = make_object(scene, "Cube", CUBE_POINTS, CUBE_FACES)
    me = obj.data
    rng = np.random.default_rng(2)
    colours = rng.random((24, 4)).astype(np.float32)
    put(me, "corner_paint", "FLOAT_COLOR", "CORNER", colours)
    put(me, "corner_id", "INT", "CORNER", np.arange(24))
    me.uv_layers.new(name="UVMap")
    uvs = rng.random((24, 2)).astype(np.float32)
    for d, uv in zip(me.uv_layers["UVMap"].data, uvs, strict=True):
        d.uv = uv.tolist()
    put(me, "face_weight", "FLOAT", "FACE", np.arange(6) / 6)
    put(me, "face_id", "INT", "FACE", np.arange(6) + 100)
    result = subdivided(obj, degree=3, levels=2)
    plan = bidegree.Plan(plain_cage(me), degree=3, levels=2)
    np.testing.assert_allclose(
        get(result, "corner_paint"),
        plan.evaluate_face_varying(colours.astype(np.float64)),
        atol=1e-6,
    )
    np.testing.assert_allclose(
        get(result, "UVMap"), plan.evaluate_face_varying(uvs.astype(np.float64)), atol=1e-6
    )
    # Corner integers: a corner of the origin face.
    corner_id = get(result, "corner_id")
    origin = np.repeat(np.asarray(plan.face_origin), 4)
    assert ((corner_id // 4) == origin).all()
    face_origin = np.asarray(plan.face_origin)
    np.testing.assert_allclose(get(result, "face_weight"), face_origin / 6, atol=1e-7)
    np.testing.assert_array_equal(get(result, "face_id"), face_origin + 100)
    bpy.data.meshes.remove(result)


# --------------------------------------------------------------------------- edges and creases


def _on_segment(points: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    ab = b - a
    t = (points - a) @ ab / (ab @ ab)
    return (
        (np.linalg.norm(a + t[:, None] * ab - points, axis=1) < 1e-6) & (t > -1e-6) & (t < 1 + 1e-6)
    )


def test_edge_flags_sit_on_the_child_edges_of_their_edge(scene: Any) -> None:
    obj = make_object(scene, "Cube", CUBE_POINTS, CUBE_FACES)
    me = obj.data
    flagged = [0, 5]
    me.edges[flagged[0]].use_seam = True
    put(me, "sharp_edge", "BOOLEAN", "EDGE", [i in flagged for i in range(len(me.edges))])
    put(me, "edge_value", "FLOAT", "EDGE", np.arange(len(me.edges), dtype=np.float32) + 1)
    levels = 2
    result = subdivided(obj, degree=1, levels=levels)  # bilinear: child edges are on the edge
    points = np.array([tuple(v.co) for v in result.vertices])
    edges = np.array([tuple(e.vertices) for e in result.edges])
    sharp = get(result, "sharp_edge")
    value = get(result, "edge_value")
    seam = np.array([e.use_seam for e in result.edges])
    for i, e in enumerate(me.edges):
        a, b = (np.array(me.vertices[v].co) for v in e.vertices)
        on = _on_segment(points, a, b)
        children = on[edges[:, 0]] & on[edges[:, 1]]
        assert children.sum() == 2**levels
        np.testing.assert_array_equal(value[children], i + 1)
        assert sharp[children].all() == (i in flagged)
        assert seam[children].all() == (i == flagged[0])
    interior = ~np.isin(np.arange(len(edges)), np.flatnonzero(value > 0))
    assert interior.sum() == len(edges) - 2**levels * len(me.edges)
    assert not sharp[interior].any() and not seam[interior].any()
    assert sharp.sum() == 2**levels * len(flagged)
    bpy.data.meshes.remove(result)


@pytest.mark.parametrize("rules", ["averaging", "classic"])
def test_creases_are_lowered_so_that_the_surface_subdivides_on(scene: Any, rules: str) -> None:
    obj = make_object(scene, "Cube", CUBE_POINTS, CUBE_FACES)
    me = obj.data
    crease = np.zeros(len(me.edges), dtype=np.float32)
    crease[[0, 3]] = (0.9, 1.0)
    put(me, "crease_edge", "FLOAT", "EDGE", crease)
    put(me, "crease_vert", "FLOAT", "POINT", [0.8 if i == 6 else 0.0 for i in range(8)])
    levels = 2
    result = subdivided(obj, degree=3, levels=levels, rules=rules)
    out_crease = get(result, "crease_edge")
    expected = {0.9: np.sqrt((10 * 0.81 - levels) / 10), 1.0: 1.0}
    nonzero = np.unique(np.round(out_crease[out_crease > 0], 6))
    np.testing.assert_allclose(nonzero, sorted(expected.values()), atol=1e-6)
    assert (out_crease > 0).sum() == 2 * 2**levels
    vertex = get(result, "crease_vert")
    assert (vertex > 0).sum() == 1
    np.testing.assert_allclose(vertex.max(), np.sqrt((6.4 - levels) / 10), atol=1e-6)
    assert np.allclose(np.array(result.vertices[int(np.argmax(vertex))].co), CUBE_POINTS[6])

    # The surface with its creases, one level further, is the cage two levels further.
    pts = np.array([tuple(v.co) for v in result.vertices], dtype=np.float64)
    edges = np.array([tuple(e.vertices) for e in result.edges])
    sel = out_crease > 0
    vsel = np.flatnonzero(vertex > 0)
    again = bidegree.Mesh(
        pts,
        [list(p.vertices) for p in result.polygons],
        creases=(edges[sel], 10 * out_crease[sel].astype(np.float64) ** 2),
        corners=(vsel, 10 * vertex[vsel].astype(np.float64) ** 2),
    )
    cage = bidegree.Mesh(
        np.array(CUBE_POINTS, dtype=np.float64),
        CUBE_FACES,
        creases=(
            np.array([tuple(me.edges[i].vertices) for i in (0, 3)]),
            10 * crease[[0, 3]].astype(np.float64) ** 2,
        ),
        corners=(np.array([6]), np.array([6.4])),
    )
    one_more = bidegree.subdivide(again, degree=3, levels=1, rules=rules).points
    direct = bidegree.subdivide(cage, degree=3, levels=levels + 1, rules=rules).points

    def rows(p: np.ndarray) -> np.ndarray:
        return p[np.lexsort(np.round(p, 4).T[::-1])]

    # float32 positions and creases in Blender: 1e-5.
    np.testing.assert_allclose(rows(one_more), rows(direct), atol=1e-5)
    bpy.data.meshes.remove(result)


def test_dual_output_edges(scene: Any) -> None:
    obj = grid(scene, 2)
    put(obj.data, "edge_value", "FLOAT", "EDGE", np.ones(len(obj.data.edges), np.float32))
    put(obj.data, "crease_vert", "FLOAT", "POINT", np.full(9, 0.5, np.float32))
    result = subdivided(obj, degree=2, levels=2, output="dual")
    plan = bidegree.Plan(plain_cage(obj.data), degree=2, levels=2, output="dual")
    origin = np.asarray(plan.edge_origin)
    value = get(result, "edge_value")
    # Only boundary edges lie on cage edges; each of them is on the boundary.
    np.testing.assert_array_equal(value > 0, origin >= 0)
    counts = np.bincount(np.asarray(plan.corner_edges), minlength=len(origin))
    assert (counts[origin >= 0] == 1).all() and (origin >= 0).any()
    # No dual vertex is a cage vertex: no vertex crease.
    assert not get(result, "crease_vert").any()
    bpy.data.meshes.remove(result)


# --------------------------------------------------------------------------- custom normals


def test_custom_normals_match_subsurf(scene: Any) -> None:
    obj = make_object(scene, "Cube", CUBE_POINTS, CUBE_FACES)
    me = obj.data
    rng = np.random.default_rng(3)
    normals = rng.normal(size=(len(me.loops), 3))
    normals[:, 2] += 3.0
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    me.normals_split_custom_set(normals.astype(np.float32).tolist())
    assert me.has_custom_normals
    result = subdivided(obj, degree=3, levels=2, rules="classic")
    got = np.zeros(3 * len(result.loops), dtype=np.float32)
    result.corner_normals.foreach_get("vector", got)
    got = got.reshape(-1, 3)
    np.testing.assert_allclose(np.linalg.norm(got, axis=1), 1.0, atol=1e-5)

    sub = obj.modifiers.new("Subsurf", "SUBSURF")
    sub.levels = 2
    sub.use_custom_normals = True
    sub.use_limit_surface = False  # the refined points, as bidegree without Limit Positions
    ev = obj.evaluated_get(update())
    ref = ev.to_mesh()
    try:
        ref_normals = np.zeros(3 * len(ref.loops), dtype=np.float32)
        ref.corner_normals.foreach_get("vector", ref_normals)
        ref_normals = ref_normals.reshape(-1, 3)

        def keyed(mesh: Any, values: np.ndarray) -> dict[tuple, np.ndarray]:
            pts = np.array([tuple(v.co) for v in mesh.vertices])
            out = {}
            for p in mesh.polygons:
                centre = pts[list(p.vertices)].mean(axis=0)
                for li in p.loop_indices:
                    v = mesh.loops[li].vertex_index
                    out[tuple(np.round(np.concatenate([pts[v], centre]), 4))] = values[li]
            return out

        mine, theirs = keyed(result, got), keyed(ref, ref_normals)
        assert mine.keys() == theirs.keys()
        # Both mix the same float32 corner normals bilinearly and normalize (rounding: 1e-6).
        # Subsurf then sets them with Blender's encoding into per-fan normal spaces: 16-bit
        # angles (measured up to 1.2e-4) and, at a few corners whose fan neighbours' normals
        # nearly agree, their average (measured 4e-3 at one corner of 96). Blender 5 shows
        # bidegree's free custom normals unencoded; Blender 4.2 encodes them too.
        diff = np.array([float(np.abs(mine[k] - theirs[k]).max()) for k in mine])
        assert np.quantile(diff, 0.95) < 2e-4, np.quantile(diff, 0.95)
        assert diff.max() < 1e-2, diff.max()
    finally:
        ev.to_mesh_clear()
    bpy.data.meshes.remove(result)


def test_limit_normals_are_per_vertex_where_that_is_exact(scene: Any) -> None:
    """Limit Normals per vertex (Blender 5's point custom normals) where no vertex's corners
    differ, per corner once a sharp crease splits some; either way Blender's corner normals
    are the limit surface's."""
    obj = make_object(scene, "Cube", CUBE_POINTS, CUBE_FACES)
    obj.data.vertices[7].co = (1.6, 1.3, 1.4)
    points = np.array([tuple(v.co) for v in obj.data.vertices], dtype=np.float32)
    edge = tuple(obj.data.edges[0].vertices)
    # Blender 4 encodes custom normals (16-bit angles in normal spaces, above).
    atol = 1e-6 if bpy.app.version >= (5, 0, 0) else 1e-2
    # The modifier's update of positions alone keeps them per vertex.
    mod = bidegree_blender.add_modifier(obj, normals=True)
    update()
    obj.data.vertices[0].co = (-1.3, -1.1, -1.0)
    obj.data.update()
    update()
    modifier = bidegree_blender.modifier
    assert modifier.status(obj, mod).action == "reused", modifier.status(obj, mod)
    shown = modifier.holders(obj, mod)["viewport"].data
    if bpy.app.version >= (5, 0, 0):
        assert shown.attributes["custom_normal"].domain == "POINT"
    moved = np.array([tuple(v.co) for v in obj.data.vertices], dtype=np.float32)
    _, want = bidegree.Plan(bidegree.Mesh(moved, CUBE_FACES), 4, 2).limit_surface(moved)
    got = np.zeros(3 * len(shown.loops), dtype=np.float32)
    shown.corner_normals.foreach_get("vector", got)
    np.testing.assert_allclose(got.reshape(-1, 3), want, rtol=0, atol=atol)
    obj.modifiers.remove(mod)
    obj.data.vertices[0].co = CUBE_POINTS[0]
    for sharp in (False, True):
        if sharp:
            obj.data.attributes.new("crease_edge", "FLOAT", "EDGE").data[0].value = 1.0
        result = subdivided(obj, degree=4, levels=2, limit=True, normals=True)
        creases = (np.array([edge]), np.array([10.0], dtype=np.float32)) if sharp else None
        plan = bidegree.Plan(bidegree.Mesh(points, CUBE_FACES, creases=creases), 4, 2)
        assert plan.limit_normals_split == sharp
        _, want = plan.limit_surface(points)
        got = np.zeros(3 * len(result.loops), dtype=np.float32)
        result.corner_normals.foreach_get("vector", got)
        if bpy.app.version >= (5, 0, 0):
            domain = result.attributes["custom_normal"].domain
            assert domain == ("CORNER" if sharp else "POINT")
        np.testing.assert_allclose(got.reshape(-1, 3), want, rtol=0, atol=atol)
        bpy.data.meshes.remove(result)


# --------------------------------------------------------------------------- adaptive output


def test_adaptive_output_carries_point_corner_face_attributes(scene: Any) -> None:
    obj = grid(scene, 4)
    me = obj.data
    me.vertices[12].co.z = 1.5  # a bump in the middle: uneven refinement
    nv, nc, nf = len(me.vertices), len(me.loops), len(me.polygons)
    rng = np.random.default_rng(4)
    weight = rng.random(nv).astype(np.float32)
    colours = rng.random((nc, 4)).astype(np.float32)
    put(me, "weight", "FLOAT", "POINT", weight)
    put(me, "corner_paint", "FLOAT_COLOR", "CORNER", colours)
    put(me, "face_weight", "FLOAT", "FACE", np.arange(nf) / nf)
    ne = len(me.edges)
    put(me, "corner_id", "INT", "CORNER", np.arange(nc))
    put(me, "label", "INT", "POINT", np.arange(nv) * 10)
    put(me, "edge_value", "FLOAT", "EDGE", np.arange(ne, dtype=np.float32) + 1)
    put(me, "sharp_edge", "BOOLEAN", "EDGE", [e % 7 == 0 for e in range(ne)])
    me.uv_layers.new(name="UVMap")
    uvs = rng.random((nc, 2)).astype(np.float32)
    for d, uv in zip(me.uv_layers["UVMap"].data, uvs, strict=True):
        d.uv = uv.tolist()
    normals = rng.normal(size=(nc, 3))
    normals[:, 2] += 3.0
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    me.normals_split_custom_set(normals.astype(np.float32).tolist())
    # The corner normals Blender has for them (its normal-space encoding moves them a little).
    normals = np.zeros(3 * nc, dtype=np.float32)
    me.corner_normals.foreach_get("vector", normals)
    normals = normals.reshape(-1, 3)
    group = obj.vertex_groups.new(name="group")
    for v in range(nv):
        group.add([v], float(weight[nv - 1 - v]), "REPLACE")
    from bidegree.options import Options

    options = Options(degree=3, levels=3, adaptive=True, tolerance=0.01, uv_mode="corners-plus1")
    result = subdivided(obj, options=options)
    cage = plain_cage(me)
    ref = bidegree.subdivide_adaptive(
        cage,
        degree=3,
        max_level=3,
        tolerance=0.01,
        uv_mode="corners-plus1",
        vertex_values=np.stack([weight, weight[::-1]], axis=1).astype(np.float64),
        face_varying={
            "uv": uvs.astype(np.float64),
            "paint": colours.astype(np.float64),
            "normals": (normals.astype(np.float32).astype(np.float64), "all"),
        },
    )
    assert len(set(ref.triangle_level.tolist())) >= 2
    assert len(result.polygons) == ref.num_triangles
    np.testing.assert_allclose(get(result, "weight"), ref.vertex_values[:, 0], atol=1e-6)
    np.testing.assert_allclose(get(result, "corner_paint"), ref.face_varying["paint"], atol=1e-6)
    np.testing.assert_allclose(get(result, "UVMap"), ref.face_varying["uv"], atol=1e-6)
    np.testing.assert_allclose(get(result, "face_weight"), ref.face_origin / nf, atol=1e-7)
    # Integers: a corner of the origin face; a vertex of the face of the vertex's first corner.
    corner_id = get(result, "corner_id")
    assert ((corner_id // 4) == np.repeat(ref.face_origin, 3)).all()
    labels = get(result, "label") // 10
    first = {int(v): c for c, v in reversed(list(enumerate(ref.triangles.reshape(-1))))}
    for v, c in first.items():
        assert labels[v] in me.polygons[int(ref.face_origin[c // 3])].vertices
    # Edge values on the triangle edges along their cage edge (by vertex pair), 0 elsewhere.
    cage_edge = {tuple(sorted(e.vertices)): e.index for e in me.edges}
    expected: dict[tuple[int, int], float] = {}
    tris = ref.triangles
    for c, o in enumerate(ref.edge_origin.tolist()):
        pair = tuple(sorted((int(tris[c // 3, c % 3]), int(tris[c // 3, (c % 3 + 1) % 3]))))
        value = 0.0 if o < 0 else float(cage_edge[tuple(ref.cage_edges[o].tolist())] + 1)
        assert expected.setdefault(pair, value) == value
    got_values = get(result, "edge_value")
    sharp = get(result, "sharp_edge")
    pairs = [tuple(sorted(e.vertices)) for e in result.edges]
    np.testing.assert_array_equal(got_values, [expected[p] for p in pairs])
    np.testing.assert_array_equal(
        sharp, [expected[p] > 0 and (expected[p] - 1) % 7 == 0 for p in pairs]
    )
    assert (got_values > 0).sum() > 2 * ne  # every cage edge split at least once
    got = np.zeros(3 * len(result.loops), dtype=np.float32)
    result.corner_normals.foreach_get("vector", got)
    want = ref.face_varying["normals"]
    want /= np.linalg.norm(want, axis=1, keepdims=True)
    # Blender 4.2 keeps custom normals as 16-bit corner-space angles (9.2e-5 apart here; 5.0
    # stores them as floats).
    np.testing.assert_allclose(got.reshape(-1, 3), want, atol=2e-4)
    bpy.data.meshes.remove(result)
    # Vertex groups: the weights through the same levels (the surface's holder has them).
    from bidegree_blender import pipeline

    surface, _ = pipeline.adaptive_surface(pipeline.evaluated_cage(obj), options)
    np.testing.assert_allclose(surface.vertex_groups["group"], ref.vertex_values[:, 1], atol=1e-6)


def test_adaptive_vertex_creases_are_the_uniform_ones_at_each_vertex_level(scene: Any) -> None:
    """Each vertex of the adaptive surface has, bit for bit, the vertex crease of the uniform
    surface at its level (the cage vertex's crease lowered by that level; 0 elsewhere)."""
    obj = grid(scene, 4)
    me = obj.data
    me.vertices[12].co.z = 1.5  # a bump in the middle: uneven refinement
    crease = np.zeros(len(me.vertices), dtype=np.float32)
    crease[[6, 12, 18, 3]] = (1.0, 0.8, 0.8, 0.25)  # sharpness 10, 6.4, 6.4, 0.625
    put(me, "crease_vert", "FLOAT", "POINT", crease)
    from bidegree.options import Options

    options = Options(degree=3, levels=3, adaptive=True, tolerance=0.01)
    result = subdivided(obj, options=options)
    got = get(result, "crease_vert").astype(np.float32)
    plain = plain_cage(me)
    at = np.flatnonzero(crease)
    cage = bidegree.Mesh(
        plain.points,
        face_sizes=plain.face_sizes,
        face_indices=plain.face_indices,
        corners=(at, 10 * crease[at].astype(np.float64) ** 2),
    )
    ref = bidegree.subdivide_adaptive(cage, degree=3, max_level=3, tolerance=0.01)
    assert len(result.polygons) == ref.num_triangles
    points = np.array([tuple(v.co) for v in result.vertices])
    np.testing.assert_allclose(points, ref.points, atol=1e-5)
    levels = np.unique(ref.vertex_level[ref.cage_vertex >= 0])
    assert len(levels) >= 2  # the creased vertices sit at different levels
    for level in np.unique(ref.vertex_level):
        uniform = subdivided(obj, degree=3, levels=int(level))
        want = get(uniform, "crease_vert").astype(np.float32)
        bpy.data.meshes.remove(uniform)
        mine = ref.vertex_level == level
        np.testing.assert_array_equal(
            got[mine].view(np.uint32), want[ref.vertex_id[mine]].view(np.uint32)
        )
    centre = got[np.flatnonzero(ref.cage_vertex == 12)]
    assert 0 < centre[0] < 0.75  # 6.4 lowered by its level, not the cage's crease
    assert (got > 0).sum() == 3  # 0.625 is gone after one level
    bpy.data.meshes.remove(result)


# --------------------------------------------------------------------------- the modifier


def test_apply_keeps_every_attribute(scene: Any) -> None:
    obj = make_object(scene, "Cube", CUBE_POINTS, CUBE_FACES)
    me = obj.data
    put(me, "weight", "FLOAT", "POINT", np.linspace(0, 1, 8))
    put(me, "label", "INT", "POINT", np.arange(8))
    put(me, "sharp_edge", "BOOLEAN", "EDGE", [i == 2 for i in range(len(me.edges))])
    put(me, "face_id", "INT", "FACE", np.arange(6))
    put(me, "corner_paint", "FLOAT_COLOR", "CORNER", np.random.default_rng(4).random((24, 4)))
    expected = subdivided(obj, degree=3, levels=1)
    mod = bidegree_blender.add_modifier(obj, degree=3, levels=1)
    name = mod.name  # the modifier is gone after Apply
    update()
    with bpy.context.temp_override(object=obj, active_object=obj):
        assert bpy.ops.object.bidegree_apply() == {"FINISHED"}
    assert len(obj.data.vertices) == len(expected.vertices)
    for attr in ("weight", "label", "sharp_edge", "face_id", "corner_paint"):
        np.testing.assert_array_equal(get(obj.data, attr), get(expected, attr), err_msg=attr)
    assert name not in obj.modifiers
    bpy.data.meshes.remove(expected)


def test_uv_smooth_menu(scene: Any) -> None:
    from bidegree_blender import attributes

    obj = make_object(scene, "Cube", CUBE_POINTS, CUBE_FACES)
    me = obj.data
    me.uv_layers.new(name="UVMap")
    uvs = np.random.default_rng(5).random((24, 2)).astype(np.float32)
    for d, uv in zip(me.uv_layers["UVMap"].data, uvs, strict=True):
        d.uv = uv.tolist()
    mod = bidegree_blender.add_modifier(obj, degree=3, levels=1)
    assert modifier.uv_smooth(mod) == "Keep Boundaries"  # Blender's default
    items = [
        i[0]
        for i in mod.id_properties_ui(
            modifier._identifiers(mod.node_group)[modifier.UV_SMOOTH_INPUT]
        ).as_dict()["items"]
    ]
    assert items == list(attributes.UV_SMOOTH)  # Blender's six names, in its order
    for mode in ("corners-only", "boundaries"):
        modifier.configure(mod, uv_mode=mode)
        assert attributes.UV_SMOOTH[modifier.uv_smooth(mod)] == mode
        depsgraph = update()
        ev = obj.evaluated_get(depsgraph).to_mesh()
        try:
            # The node group's stamp matches the holder: the surface is shown, not the cage.
            assert len(ev.polygons) == 24
            shown = get(ev, "UVMap")
        finally:
            obj.evaluated_get(depsgraph).to_mesh_clear()
        options = modifier.options_of(mod)
        plan = bidegree.Plan(plain_cage(me), degree=3, levels=1)
        expected = attributes.face_varying(plan, uvs.astype(np.float64), options.uv_mode)
        np.testing.assert_allclose(shown, expected, atol=1e-6)
    with pytest.raises(bidegree.InvalidInputError):
        modifier.configure(mod, uv_mode="smooth")
