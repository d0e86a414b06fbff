"""Classic rules (``rules="classic"``, degree 3) against OpenSubdiv's catmark, run by the real
``bpy`` (Blender's Subdivision Surface modifier).

Blender settings (``bidegree.compare.opensubdiv_surface``): ``use_limit_surface=False`` refines
uniformly (the points are the level-L vertices), ``True`` gives limit positions;
``boundary_smooth`` 'ALL' = edge-only, 'PRESERVE_CORNERS' = edge-and-corner; creases are the
``crease_edge`` / ``crease_vert`` float attributes c with sharpness ``10 c^2`` (computed by
Blender in float32: the cages here carry exactly that float32 sharpness). Blender uses
OpenSubdiv's uniform creasing method.

Points are put in correspondence by position (nearest point both ways, same count); every
distance must be below 1e-5 of the bounding-box diagonal. Blender keeps loose vertices (no
faces) where bidegree drops them; ``opensubdiv_surface`` drops them too, and the cages here
have none. Blender computes in float32, so the cages are float32-representable.
"""

from __future__ import annotations

import bidegree
import numpy as np
import pytest

bpy = pytest.importorskip("bpy")
from bidegree import compare  # noqa: E402

TOLERANCE = 1e-5
INF = 10.0


def _blender_sharpness(s: np.ndarray) -> np.ndarray:
    """The sharpness Blender derives from the crease value it is given for ``s``."""
    c = compare._blender_crease(np.asarray(s, dtype=np.float64))
    return (c * c * np.float32(10.0)).astype(np.float32)


def _mesh(
    points: np.ndarray,
    faces: list[list[int]],
    creases: list[tuple[int, int, float]] = (),  # type: ignore[assignment]
    corners: list[tuple[int, float]] = (),  # type: ignore[assignment]
    boundary: str = "edge-only",
) -> bidegree.Mesh:
    pts = np.asarray(points, dtype=np.float32).astype(np.float64)
    kw: dict[str, object] = {"boundary": boundary}
    if creases:
        pairs = np.array([(a, b) for a, b, _ in creases], dtype=np.int64)
        kw["creases"] = (pairs, _blender_sharpness(np.array([s for *_, s in creases])))
    if corners:
        verts = np.array([v for v, _ in corners], dtype=np.int64)
        kw["corners"] = (verts, _blender_sharpness(np.array([s for _, s in corners])))
    return bidegree.Mesh(pts, faces, **kw)  # type: ignore[arg-type]


# ------------------------------------------------------------------------------------------
# cages

CUBE = np.array(
    [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0, 0, 1], [1, 0, 1], [1, 1, 1], [0, 1, 1]],
    dtype=np.float64,
) + 0.05 * np.sin(np.arange(24).reshape(8, 3))
CUBE_FACES = [[0, 3, 2, 1], [4, 5, 6, 7], [0, 1, 5, 4], [1, 2, 6, 5], [2, 3, 7, 6], [3, 0, 4, 7]]
CUBE_EDGES = sorted({tuple(sorted((f[i], f[(i + 1) % 4]))) for f in CUBE_FACES for i in range(4)})


def _torus(n: int = 10, m: int = 6) -> tuple[np.ndarray, list[list[int]]]:
    i, j = np.meshgrid(np.arange(n), np.arange(m), indexing="ij")
    u, v = 2 * np.pi * i / n, 2 * np.pi * j / m
    r = 2.0 + 0.7 * np.cos(v) + 0.1 * np.sin(3 * u)
    pts = np.stack([r * np.cos(u), 0.7 * np.sin(v), r * np.sin(u)], axis=-1).reshape(-1, 3)
    a, b = i * m + j, ((i + 1) % n) * m + j
    c, d = ((i + 1) % n) * m + (j + 1) % m, i * m + (j + 1) % m
    return pts, np.stack([a, d, c, b], axis=-1).reshape(-1, 4).tolist()


def _grid_with_holes(n: int = 7) -> tuple[np.ndarray, list[list[int]]]:
    i, j = np.meshgrid(np.arange(n + 1), np.arange(n + 1), indexing="ij")
    pts = np.stack([i, j, 0.3 * np.sin(i + 0.5 * j)], axis=-1).reshape(-1, 3).astype(float)
    holes = {(2, 2), (2, 3), (4, 5)}
    faces = [
        [a * (n + 1) + b, (a + 1) * (n + 1) + b, (a + 1) * (n + 1) + b + 1, a * (n + 1) + b + 1]
        for a in range(n)
        for b in range(n)
        if (a, b) not in holes
    ]
    return pts, faces


def _fan(k: int) -> tuple[np.ndarray, list[list[int]]]:
    """An open disk of k quads around a centre of valence k (2k ring vertices)."""
    t = np.pi * np.arange(2 * k) / k
    radius = np.where(np.arange(2 * k) % 2 == 0, 1.0, 1.3)
    ring = np.stack([radius * np.cos(t), radius * np.sin(t), 0.2 * np.cos(3 * t)], axis=-1)
    pts = np.vstack([[0.0, 0.0, 0.4], ring])
    faces = [[0, 1 + 2 * i, 1 + 2 * i + 1, 1 + (2 * i + 2) % (2 * k)] for i in range(k)]
    return pts, faces


def _tri_pent() -> tuple[np.ndarray, list[list[int]]]:
    """A closed pentagonal prism whose top is a fan of triangles: triangles, quads, a pentagon."""
    t = 2 * np.pi * np.arange(5) / 5
    bottom = np.stack([np.cos(t), np.sin(t), np.zeros(5)], axis=-1)
    top = np.stack([np.cos(t), np.sin(t), np.ones(5) + 0.1 * np.sin(2 * t)], axis=-1)
    pts = np.vstack([bottom, top, [[0.1, 0.0, 1.5]]])
    faces = [[4, 3, 2, 1, 0]]
    faces += [[i, (i + 1) % 5, 5 + (i + 1) % 5, 5 + i] for i in range(5)]
    faces += [[5 + i, 5 + (i + 1) % 5, 10] for i in range(5)]
    return pts, faces


def _suzanne() -> tuple[np.ndarray, list[list[int]]]:
    import bmesh

    bm = bmesh.new()
    try:
        bmesh.ops.create_monkey(bm)
        pts = np.array([v.co[:] for v in bm.verts], dtype=np.float64)
        faces = [[v.index for v in f.verts] for f in bm.faces]
    finally:
        bm.free()
    return pts, faces


TORUS = _torus()
T_ID = 6  # vertices per ring of the torus (m)


def _torus_loop(s: float, ring: int = 0) -> list[tuple[int, int, float]]:
    """The crease loop j = ring along u around the torus."""
    return [(i * T_ID + ring, ((i + 1) % 10) * T_ID + ring, s) for i in range(10)]


def _torus_meridian(s: float, i: int = 3) -> list[tuple[int, int, float]]:
    return [(i * T_ID + j, i * T_ID + (j + 1) % T_ID, s) for j in range(T_ID)]


def _cases() -> dict[str, bidegree.Mesh]:
    cases = {
        "cube": _mesh(CUBE, CUBE_FACES),
        "torus": _mesh(*TORUS),
        "suzanne": _mesh(*_suzanne()),
        "grid-holes-edge-only": _mesh(*_grid_with_holes()),
        "grid-holes-edge-and-corner": _mesh(*_grid_with_holes(), boundary="edge-and-corner"),
        "triangles-pentagon": _mesh(*_tri_pent()),
        "pole-64": _mesh(*_fan(64)),
        "cube-all-creased-inf": _mesh(CUBE, CUBE_FACES, [(a, b, INF) for a, b in CUBE_EDGES]),
        "cube-all-creased-2.3": _mesh(CUBE, CUBE_FACES, [(a, b, 2.3) for a, b in CUBE_EDGES]),
        "crossing-creases": _mesh(*TORUS, _torus_loop(2.3) + _torus_meridian(0.5)),
        "crossing-creases-inf": _mesh(*TORUS, _torus_loop(INF) + _torus_meridian(INF)),
        "dart": _mesh(*TORUS, _torus_loop(INF)[:3]),
        "semi-sharp-dart": _mesh(*TORUS, _torus_loop(1.0)[:4]),
        "corners": _mesh(CUBE, CUBE_FACES, corners=[(0, INF), (6, 2.3), (3, 0.5)]),
        "corner-on-crease": _mesh(*TORUS, _torus_loop(1.0), [(0, 0.5), (T_ID * 5, INF)]),
        "grid-boundary-corners": _mesh(
            *_grid_with_holes(), corners=[(3, 0.5), (8 * 7 + 2, 2.3), (8 * 3 + 3, 1.0)]
        ),
        "grid-crease-to-boundary-edge-and-corner": _mesh(
            *_grid_with_holes(),
            [(8 * a + 5, 8 * (a + 1) + 5, 1.7) for a in range(3)],
            [(0, 0.5)],
            boundary="edge-and-corner",
        ),
        "triangles-pentagon-creases": _mesh(
            *_tri_pent(), [(5, 6, 0.7), (6, 7, 3.0), (0, 1, INF), (7, 10, 1.5)], [(10, 1.2)]
        ),
    }
    for k in range(3, 13):
        cases[f"valence-{k}"] = _mesh(*_fan(k))
    for s in (0.5, 1.0, 2.3, INF):
        cases[f"torus-crease-{s}"] = _mesh(*TORUS, _torus_loop(s))
        cases[f"grid-crease-{s}"] = _mesh(
            *_grid_with_holes(), [(8 * a + 5, 8 * (a + 1) + 5, s) for a in range(7)]
        )
    return cases


CASES = _cases()
RESULTS: dict[tuple[str, int], float] = {}


def _relative_gap(ours: np.ndarray, theirs: np.ndarray, diagonal: float) -> float:
    assert ours.shape == theirs.shape, (ours.shape, theirs.shape)
    one = compare.nearest_point_distances(ours, theirs).max()
    two = compare.nearest_point_distances(theirs, ours).max()
    return float(max(one, two) / diagonal)


@pytest.mark.parametrize("name", sorted(CASES))
def test_uniform_refinement_matches_opensubdiv(name: str) -> None:
    mesh = CASES[name]
    diagonal = float(np.linalg.norm(np.ptp(mesh.points, axis=0)))
    gaps = []
    for levels in (1, 2, 3):
        ours = bidegree.subdivide(mesh, degree=3, levels=levels, rules="classic").points
        theirs = compare.opensubdiv_surface(mesh, levels).points
        gap = _relative_gap(ours, theirs, diagonal)
        RESULTS[(name, levels)] = gap
        gaps.append(gap)
    print(f"{name}: max relative distance per level 1..3: " + ", ".join(f"{g:.1e}" for g in gaps))
    assert max(gaps) < TOLERANCE, gaps


LIMIT_CASES = [
    "cube",
    "torus",
    "suzanne",
    "grid-holes-edge-only",
    "grid-holes-edge-and-corner",
    "triangles-pentagon",
    "valence-3",
    "valence-5",
    "valence-12",
    "cube-all-creased-inf",
    "crossing-creases-inf",
    "dart",
    "torus-crease-10.0",
    # Semi-sharp features are exact once they have decayed (sharpness <= levels), as here at
    # level 3: the limit masks then see smooth rules. Blender's limit is the true limit.
    "torus-crease-2.3",
    "crossing-creases",
    "corners",
    "corner-on-crease",
    "semi-sharp-dart",
    "torus-crease-0.5",
    "torus-crease-1.0",
    "grid-crease-2.3",
    "cube-all-creased-2.3",
    "pole-64",
]


@pytest.mark.parametrize("name", LIMIT_CASES)
def test_limit_positions_match_opensubdiv(name: str) -> None:
    mesh = CASES[name]
    diagonal = float(np.linalg.norm(np.ptp(mesh.points, axis=0)))
    levels = 3
    plan = bidegree.Plan(mesh, degree=3, levels=levels, rules="classic")
    ours = plan.limit_positions()[: mesh.num_vertices]
    # Blender numbers the cage vertices first in its refined mesh.
    theirs = compare.opensubdiv_surface(mesh, levels, limit=True).points[: mesh.num_vertices]
    gap = float(np.linalg.norm(ours - theirs, axis=1).max() / diagonal)
    print(f"{name}: limit positions at cage vertices, max relative distance {gap:.1e}")
    assert gap < TOLERANCE, gap


def test_chaikin_differs_only_where_semi_sharp_creases_meet() -> None:
    # Blender uses uniform creasing; Chaikin changes the result only where semi-sharp creases of
    # different sharpness meet (the crossing), and equals uniform on a single crease loop.
    single = CASES["torus-crease-2.3"]
    a = bidegree.subdivide(single, degree=3, levels=3, rules="classic").points
    b = bidegree.subdivide(single, degree=3, levels=3, rules="classic", creasing="chaikin").points
    np.testing.assert_array_equal(a, b)
    crossing = CASES["crossing-creases"]
    a = bidegree.subdivide(crossing, degree=3, levels=3, rules="classic").points
    b = bidegree.subdivide(crossing, degree=3, levels=3, rules="classic", creasing="chaikin")
    assert np.abs(a - b.points).max() > 1e-4


def test_classic_rules_api() -> None:
    mesh = CASES["cube"]
    plan = bidegree.Plan(mesh, degree=3, levels=1, rules="classic")
    assert plan.rules == "classic"
    assert bidegree.Plan(mesh, degree=3, levels=1).rules == "averaging"
    with pytest.raises(bidegree.InvalidInputError):
        bidegree.Plan(mesh, degree=4, levels=1, rules="classic")
    with pytest.raises(bidegree.InvalidInputError):
        bidegree.Plan(mesh, degree=3, levels=1, rules="loop")
    # The classic limit masks only apply to the classic rules; Doo-Sabin has none.
    with pytest.raises(bidegree.InvalidInputError):
        bidegree.Plan(mesh, degree=2, levels=1, rules="classic").limit_positions()
    # Doo-Sabin: degree 2 classic differs from the averaging degree 2 at valence 3.
    a = bidegree.subdivide(mesh, degree=2, levels=2).points
    b = bidegree.subdivide(mesh, degree=2, levels=2, rules="classic").points
    assert a.shape == b.shape and np.abs(a - b).max() > 1e-3
