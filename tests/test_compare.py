"""bidegree vs OpenSubdiv (real bpy, real usd-core): distances, surfaces, report, CLI hook."""

from __future__ import annotations

import argparse
from pathlib import Path

import bidegree
import numpy as np
import pytest
from bidegree import compare, usd
from cages import CUBE_FACES, CUBE_POINTS, cube, torus
from pxr import Usd, UsdGeom

# ------------------------------------------------------------------------------------------
# geometry


def test_point_triangle_distance_regions() -> None:
    a, b, c = np.array([0.0, 0, 0]), np.array([2.0, 0, 0]), np.array([0.0, 2, 0])
    cases = [
        ([0.5, 0.5, 3.0], 3.0),  # above the interior
        ([0.5, 0.5, -0.25], 0.25),  # below the interior
        ([1.0, -2.0, 0.0], 2.0),  # beyond edge ab
        ([2.0, 2.0, 0.0], np.sqrt(2.0)),  # beyond edge bc (nearest (1, 1, 0))
        ([-1.0, -1.0, 1.0], np.sqrt(3.0)),  # beyond vertex a
        ([3.0, -1.0, 0.0], np.sqrt(2.0)),  # beyond vertex b
        ([0.0, 2.0, 0.0], 0.0),  # on vertex c
    ]
    p = np.array([q for q, _ in cases])
    want = np.array([d for _, d in cases])
    got = compare.point_triangle_distances(
        p, np.tile(a, (len(p), 1)), np.tile(b, (len(p), 1)), np.tile(c, (len(p), 1))
    )
    np.testing.assert_allclose(got, want, atol=1e-12)
    # degenerate triangles: a segment and a point
    seg = compare.point_triangle_distances(
        np.array([[1.0, 1.0, 0.0]]),
        np.zeros((1, 3)),
        np.array([[2.0, 0, 0]]),
        np.zeros((1, 3)),
    )
    pnt = compare.point_triangle_distances(
        np.array([[3.0, 4.0, 0.0]]),
        np.zeros((1, 3)),
        np.zeros((1, 3)),
        np.zeros((1, 3)),
    )
    np.testing.assert_allclose([seg[0], pnt[0]], [1.0, 5.0])


def _brute_force(queries: np.ndarray, mesh: compare.SurfaceMesh) -> np.ndarray:
    tri = compare.triangulate(mesh.face_sizes, mesh.face_indices)
    a, b, c = (mesh.points[tri[:, k]] for k in range(3))
    out = np.empty(len(queries))
    for i, q in enumerate(queries):
        out[i] = compare.point_triangle_distances(np.broadcast_to(q, a.shape), a, b, c).min()
    return out


def test_grid_search_is_exact() -> None:
    """Against brute force, for queries near the surface, far from it and outside its box."""
    result = bidegree.subdivide(torus(8, 6), degree=4, levels=2)
    mesh = compare.SurfaceMesh(result.points, result.face_sizes, result.face_indices)
    rng = np.random.default_rng(3)
    near = result.points[rng.choice(len(result.points), 150)] + rng.normal(0, 0.02, (150, 3))
    far = rng.uniform(-4, 4, (100, 3))
    queries = np.concatenate([near, far, [[0.0, 0.0, 0.0], [40.0, -30.0, 5.0]]])
    got = compare.distances_to_mesh(queries, mesh)
    np.testing.assert_allclose(got, _brute_force(queries, mesh), rtol=1e-12, atol=1e-12)
    # vertex-only distances
    pts = compare.nearest_point_distances(queries, mesh.points)
    want = np.linalg.norm(queries[:, None, :] - mesh.points[None], axis=2).min(axis=1)
    np.testing.assert_allclose(pts, want, rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize("offset", [0.0, 1e4])
def test_grid_search_on_coincident_points(offset: float) -> None:
    """Queries on (or float32-rounding away from) the target's vertices, far from the origin."""
    result = bidegree.subdivide(torus(6, 5), degree=3, levels=2)
    points = result.points + offset
    mesh = compare.SurfaceMesh(points, result.face_sizes, result.face_indices)
    rounded = points.astype(np.float32).astype(np.float64)
    assert compare.distances_to_mesh(points, mesh).max() == 0.0
    assert compare.nearest_point_distances(points, points).max() == 0.0
    gap = np.linalg.norm(rounded - points, axis=1)
    np.testing.assert_allclose(compare.nearest_point_distances(rounded, points), gap, atol=1e-12)
    assert np.all(compare.distances_to_mesh(rounded, mesh) <= gap + 1e-12)


def test_grid_search_matches_blender_bvh() -> None:
    """Independent check with Blender's BVH tree (mathutils) on a bigger mesh."""
    import bpy  # noqa: F401 - makes Blender's mathutils importable
    from mathutils.bvhtree import BVHTree

    result = bidegree.subdivide(cube(), degree=3, levels=4)
    mesh = compare.SurfaceMesh(result.points, result.face_sizes, result.face_indices)
    tri = compare.triangulate(mesh.face_sizes, mesh.face_indices)
    tree = BVHTree.FromPolygons(mesh.points.tolist(), tri.tolist(), epsilon=0.0)
    rng = np.random.default_rng(5)
    queries = rng.uniform(-0.5, 1.5, (400, 3))
    want = np.array([tree.find_nearest(q.tolist())[3] for q in queries])
    np.testing.assert_allclose(compare.distances_to_mesh(queries, mesh), want, atol=1e-6)


# ------------------------------------------------------------------------------------------
# OpenSubdiv through bpy


def test_opensubdiv_cube_level1_is_catmull_clark() -> None:
    osd = compare.opensubdiv_surface(cube(), 1)
    assert (osd.num_vertices, osd.num_faces) == (26, 24)
    # Catmull-Clark vertex rule at a valence-3 corner of the unit cube: (Q + 2R + (n-3)S)/n
    corner = osd.points[np.argmin(osd.points.sum(axis=1))]
    np.testing.assert_allclose(corner, [2 / 9] * 3, atol=1e-6)
    # face points: centres of the cube's faces
    assert np.min(np.linalg.norm(osd.points - [0.5, 0.5, 0.0], axis=1)) < 1e-6


def test_opensubdiv_sharp_creases_and_boundary_modes() -> None:
    """All 12 edges infinitely sharp and all 8 corners sharp: the surface stays the cube."""
    edges = np.array(
        [
            [0, 1],
            [1, 2],
            [2, 3],
            [3, 0],
            [4, 5],
            [5, 6],
            [6, 7],
            [7, 4],
            [0, 4],
            [1, 5],
            [2, 6],
            [3, 7],
        ]
    )
    sharp = cube(creases=(edges, np.full(12, np.inf)), corners=(np.arange(8), np.full(8, 10.0)))
    osd = compare.opensubdiv_surface(sharp, 2)
    on_face = np.min(np.minimum(np.abs(osd.points), np.abs(osd.points - 1.0)), axis=1)
    assert on_face.max() < 1e-6

    # a semi-sharp crease (sharpness 2) pulls the surface towards edge 0-1, but not onto it
    def gap_to_edge01(mesh: compare.SurfaceMesh) -> float:
        mid = np.abs(mesh.points[:, 0] - 0.5) < 1e-6
        return float(np.min(np.linalg.norm(mesh.points[mid][:, 1:], axis=1)))

    soft = compare.opensubdiv_surface(cube(creases=(edges[:1], [2.0])), 2)
    plain = compare.opensubdiv_surface(cube(), 2)
    assert 1e-3 < gap_to_edge01(soft) < 0.5 * gap_to_edge01(plain)
    assert gap_to_edge01(osd) < 1e-6

    # boundary modes on an open 2 x 2 grid: edge-and-corner pins the valence-2 corners
    grid_pts = np.array([[x, y, 0.0] for y in range(3) for x in range(3)])
    grid = [[0, 1, 4, 3], [1, 2, 5, 4], [3, 4, 7, 6], [4, 5, 8, 7]]
    pinned = compare.opensubdiv_surface(
        bidegree.Mesh(grid_pts, grid, boundary="edge-and-corner"), 2
    )
    smooth = compare.opensubdiv_surface(bidegree.Mesh(grid_pts, grid, boundary="edge-only"), 2)
    assert np.min(np.linalg.norm(pinned.points - [0, 0, 0], axis=1)) < 1e-6
    assert np.min(np.linalg.norm(smooth.points - [0, 0, 0], axis=1)) > 0.05


# ------------------------------------------------------------------------------------------
# bidegree vs OpenSubdiv


def test_regular_torus_degree3_equals_catmull_clark() -> None:
    """On a closed all-valence-4 quad mesh, degree-3 averaging is uniform bicubic B-spline
    refinement, exactly like Catmull-Clark: same refined points at every level."""
    mesh = torus()
    for levels in (1, 2):
        c = compare.compare(mesh, degree=3, levels=levels)
        assert len(c.result.points) == c.opensubdiv.num_vertices
        assert c.hausdorff_relative < 1e-6
        assert c.stats["vertex_sets"]["max_relative"] < 1e-6
        # point sets match one to one (float32 noise only)
        order_a = np.lexsort(np.round(c.result.points, 5).T)
        order_b = np.lexsort(np.round(c.opensubdiv.points, 5).T)
        np.testing.assert_allclose(
            c.result.points[order_a], c.opensubdiv.points[order_b], atol=1e-5
        )


@pytest.mark.parametrize("sharpness", [np.inf, 3.0, 0.5])
def test_regular_torus_with_crease_loop_matches(sharpness: float) -> None:
    """A crease loop around the tube keeps the mesh regular for both schemes; semi-sharp values
    check the Blender crease mapping (c = sqrt(s / 10)) against bidegree's sharpness."""
    n, m = 12, 8
    ring = np.stack([np.arange(n) * m, ((np.arange(n) + 1) % n) * m], axis=1)
    c = compare.compare(torus(n, m, creases=(ring, np.full(n, sharpness))), degree=3, levels=2)
    assert c.hausdorff_relative < 1e-6
    assert c.stats["vertex_sets"]["max_relative"] < 1e-6
    plain = compare.opensubdiv_surface(torus(n, m), 2)
    assert np.abs(c.opensubdiv.points - plain.points).max() > 1e-3  # the crease does something


@pytest.mark.parametrize("boundary", ["edge-only", "edge-and-corner"])
def test_open_regular_grid_matches(boundary: str) -> None:
    n = 4
    pts = np.array([[x, y, 0.2 * np.sin(x + 2 * y)] for y in range(n + 1) for x in range(n + 1)])
    quads = [
        [y * (n + 1) + x, y * (n + 1) + x + 1, (y + 1) * (n + 1) + x + 1, (y + 1) * (n + 1) + x]
        for y in range(n)
        for x in range(n)
    ]
    c = compare.compare(bidegree.Mesh(pts, quads, boundary=boundary), degree=3, levels=2)
    assert c.hausdorff_relative < 1e-6
    corner = np.min(np.linalg.norm(c.result.points - pts[0], axis=1))
    assert (corner < 1e-9) == (boundary == "edge-and-corner")


def test_torus_degree4_differs() -> None:
    c = compare.compare(torus(), degree=4, levels=2)
    assert 1e-4 < c.hausdorff_relative < 5e-2


def test_cube_degree3_close_but_not_equal() -> None:
    """At valence-3 vertices averaging differs from Catmull-Clark's vertex rule."""
    c = compare.compare(cube(), degree=3, levels=2)
    s = c.stats
    assert 1e-3 < c.hausdorff_relative < 0.1
    assert 0 < s["symmetric"]["rms_relative"] < s["symmetric"]["max_relative"]
    assert s["symmetric"]["mean_relative"] <= s["symmetric"]["rms_relative"]
    # worst at the corners (valence 3), tiny at the face centres (valence 4, regular nearby)
    corner = np.argmin(c.result.points.sum(axis=1))
    assert c.forward[corner] == pytest.approx(c.forward.max(), rel=0.5)
    centre = np.argmin(np.linalg.norm(c.result.points - [0.5, 0.5, 0.0], axis=1))
    assert c.forward[centre] < 0.2 * c.forward.max()
    # the limit comparison also runs and gives a different, still small, number
    lim = compare.compare(cube(), degree=3, levels=2, limit=True)
    assert 1e-3 < lim.hausdorff_relative < 0.1
    assert lim.hausdorff != pytest.approx(c.hausdorff)
    assert "Hausdorff" in c.summary()


def test_report_usd_and_plot(tmp_path: Path) -> None:
    c = compare.compare(cube(uvs=np.random.default_rng(1).random((24, 2))), degree=3, levels=2)
    report = tmp_path / "report.usdc"
    compare.write_usd(c, str(report))
    assert usd.validate(report) == []
    stage = Usd.Stage.Open(str(report))
    # Per face corner: the file's points are in their own order (bidegree.usd's point_order).
    for name, surface, distances in (
        ("Result", c.result, c.forward),
        ("OpenSubdiv", c.opensubdiv, c.backward),
    ):
        written = UsdGeom.Mesh(stage.GetPrimAtPath(f"/Bidegree/{name}"))
        corners = np.asarray(written.GetFaceVertexIndicesAttr().Get())
        points = np.asarray(written.GetPointsAttr().Get())
        expected = surface.points[surface.face_indices]
        np.testing.assert_allclose(points[corners], expected, atol=1e-6)
        dist = np.asarray(written.GetPrim().GetAttribute("primvars:distance").Get())
        np.testing.assert_allclose(dist[corners], distances[surface.face_indices], atol=1e-6)
    png = tmp_path / "report.png"
    compare.write_plot(c, str(png))
    import matplotlib.image

    image = matplotlib.image.imread(str(png))
    assert image.shape[0] > 500 and image.shape[1] > 500
    assert image[..., :3].std() > 0.05  # not a blank canvas


def test_cli_hook(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    obj = tmp_path / "cube.obj"
    lines = [f"v {x} {y} {z}" for x, y, z in CUBE_POINTS]
    lines += ["f " + " ".join(str(i + 1) for i in f) for f in CUBE_FACES]
    obj.write_text("\n".join(lines) + "\n")
    parser = argparse.ArgumentParser(prog="bidegree compare")
    compare.add_arguments(parser)
    report, png = tmp_path / "r.usda", tmp_path / "r.png"
    args = parser.parse_args(
        [
            str(obj),
            "--degree",
            "3",
            "--levels",
            "2",
            "-o",
            str(report),
            "--plot",
            str(png),
        ]
    )
    assert compare.run(args) == 0
    out = capsys.readouterr().out
    assert "bidegree -> OpenSubdiv" in out and "OpenSubdiv -> bidegree" in out
    assert report.exists() and png.exists()
    assert usd.validate(report) == []

    bad = parser.parse_args([str(tmp_path / "missing.obj"), "--levels", "1"])
    assert compare.run(bad) == 1
    assert "error" in capsys.readouterr().err
    # unusable report paths are refused before any work is done
    for option, target in (("-o", "nowhere/r.usda"), ("-o", "r.obj"), ("--plot", "nowhere/r.png")):
        args = parser.parse_args([str(obj), option, str(tmp_path / target)])
        assert compare.run(args) == 1
        captured = capsys.readouterr()
        assert captured.out == "" and "error" in captured.err
    assert not (tmp_path / "nowhere").exists() and not (tmp_path / "r.obj").exists()
