"""The output edge -> cage edge map and the sharpness edges keep (issue 14): ``Plan.edge_origin``,
``Plan.cage_edges``, ``Plan.edge_sharpness``, checked against geometry (degree 1 is the cage's
bilinear refinement, so an edge lies on a cage edge exactly when both its ends do)."""

from __future__ import annotations

import bidegree
import numpy as np
import pytest
from cages import CUBE_FACES, CUBE_POINTS


def _on_segment(points: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    ab = b - a
    t = (points - a) @ ab / (ab @ ab)
    near = np.linalg.norm(a + t[:, None] * ab - points, axis=1) < 1e-9
    return near & (t > -1e-9) & (t < 1 + 1e-9)


@pytest.mark.parametrize("levels", [0, 1, 3])
def test_child_edges_of_each_cage_edge(levels: int) -> None:
    points, faces = CUBE_POINTS, CUBE_FACES
    # An isolated vertex first: cage edges are in the user's numbering, not the compacted one.
    points = np.vstack([[[5.0, 5.0, 5.0]], points])
    faces = [[v + 1 for v in f] for f in faces]
    with pytest.warns(bidegree.IsolatedVerticesWarning):
        plan = bidegree.Plan(bidegree.Mesh(points, faces), degree=1, levels=levels)
    cage_edges = np.asarray(plan.cage_edges)
    assert len(cage_edges) == 12
    assert (cage_edges[:, 0] < cage_edges[:, 1]).all() and cage_edges.min() == 1
    keys = cage_edges[:, 0] * 100 + cage_edges[:, 1]
    assert (np.diff(keys) > 0).all()
    out = plan.evaluate(points)
    edges = np.asarray(plan.edges)
    origin = np.asarray(plan.edge_origin)
    assert origin.shape == (len(edges),) and origin.dtype == np.int32
    for e, (a, b) in enumerate(cage_edges):
        on = _on_segment(out, points[a], points[b])
        np.testing.assert_array_equal(origin == e, on[edges[:, 0]] & on[edges[:, 1]])
    assert (np.bincount(origin[origin >= 0], minlength=12) == 2**levels).all()
    assert (origin >= -1).all()


def test_kept_sharpness_follows_the_rules() -> None:
    # Two semi-sharp edges meeting at a vertex (Chaikin averages them there) and a sharp one.
    a, b, c = _path_of_three_edges()
    mesh = bidegree.Mesh(
        CUBE_POINTS, CUBE_FACES, creases=(np.array([a, b, c]), np.array([2.5, 1.5, 10.0]))
    )
    settings = (("averaging", "uniform"), ("classic", "uniform"), ("classic", "chaikin"))
    for rules, creasing in settings:
        plan = bidegree.Plan(mesh, degree=3, levels=2, rules=rules, creasing=creasing)
        cage_edges = np.asarray(plan.cage_edges).tolist()
        origin = np.asarray(plan.edge_origin)
        sharpness = np.asarray(plan.edge_sharpness)
        assert (sharpness[origin < 0] == 0).all()
        np.testing.assert_array_equal(sharpness[origin == cage_edges.index(sorted(c))], 10)
        semi = sharpness[origin == cage_edges.index(sorted(a))]
        if creasing == "uniform":
            np.testing.assert_array_equal(semi, 0.5)
            assert (sharpness[origin == cage_edges.index(sorted(b))] == 0).all()
        else:
            # Chaikin: next to the 1.5 edge the 2.5 edge's halves lower differently.
            assert len(set(semi.tolist())) > 1
        ids = [cage_edges.index(sorted(e)) for e in (a, b, c)]
        others = np.isin(origin, ids, invert=True)
        assert (sharpness[others & (origin >= 0)] == 0).all()


def _path_of_three_edges() -> tuple[list[int], list[int], list[int]]:
    """Edges a, b (sharing a vertex) and c (apart from both) of the cube."""
    edges = sorted({tuple(sorted((f[i], f[(i + 1) % 4]))) for f in CUBE_FACES for i in range(4)})
    a = edges[0]
    b = next(e for e in edges if e != a and a[1] in e)
    c = next(e for e in edges if not set(e) & (set(a) | set(b)))
    return list(a), list(b), list(c)


def test_dual_edges_on_cage_edges_are_boundary_edges() -> None:
    points = np.array([[x, y, 0.0] for y in range(3) for x in range(3)])
    faces = [[0, 1, 4, 3], [1, 2, 5, 4], [3, 4, 7, 6], [4, 5, 8, 7]]
    plan = bidegree.Plan(bidegree.Mesh(points, faces), degree=2, levels=2, output="dual")
    origin = np.asarray(plan.edge_origin)
    faces_of_edge = np.bincount(np.asarray(plan.corner_edges), minlength=len(origin))
    assert (origin >= 0).any()
    assert (faces_of_edge[origin >= 0] == 1).all()
    # A boundary cage edge of this grid has both its halves' boundary points on it.
    boundary = np.asarray(plan.cage_edges)[origin[origin >= 0]]
    on_boundary = (points[boundary][..., :2] % 2 == 0).all(axis=1).any(axis=1)
    assert on_boundary.all()
