"""Adaptive subdivision from Python: exact uniform points, watertight triangles, the CLI."""

from __future__ import annotations

import resource
from collections import Counter
from pathlib import Path

import bidegree
import numpy as np
import pytest
from cages import CUBE_FACES, CUBE_POINTS
from test_hostile import cli


def bumped_cube(dtype: type = np.float64) -> bidegree.Mesh:
    points = CUBE_POINTS.astype(dtype).copy()
    points[6] += 0.8
    return bidegree.Mesh(points, CUBE_FACES)


def pyramid_prism() -> bidegree.Mesh:
    """Closed: a pentagon, quads and triangles, valences 3, 4 and 5."""
    angles = 2 * np.pi * np.arange(5) / 5
    ring = np.stack([np.cos(angles) * (1 + 0.1 * np.arange(5)), np.sin(angles)], axis=-1)
    points = np.concatenate(
        [np.c_[ring, np.zeros(5)], np.c_[ring, np.full(5, 1.5)], [[0.2, 0.1, 3.5]]]
    )
    faces = [list(range(4, -1, -1))]
    for i in range(5):
        j = (i + 1) % 5
        faces += [[i, j, 5 + j, 5 + i], [5 + i, 5 + j, 10]]
    return bidegree.Mesh(points, faces)


def assert_watertight(result: bidegree.AdaptiveResult) -> None:
    tris = result.triangles
    assert tris.dtype == np.int32 and tris.shape[1] == 3
    directed = Counter()
    for t in tris.tolist():
        assert len(set(t)) == 3
        for k in range(3):
            directed[(t[k], t[(k + 1) % 3])] += 1
    for (a, b), count in directed.items():
        assert count == 1
        assert directed[(b, a)] == 1, f"edge ({a}, {b}) is open: a crack or T-junction"
    assert np.unique(tris).size == result.num_vertices


@pytest.mark.parametrize("degree", [2, 3, 4, 9])
def test_closed_cages_are_watertight_and_mixed(degree: int) -> None:
    for mesh in (bumped_cube(), pyramid_prism()):
        levels_seen = set()
        for tolerance in (0.01, 0.003, 0.001):
            result = bidegree.subdivide_adaptive(
                mesh, degree=degree, max_level=4, tolerance=tolerance
            )
            assert_watertight(result)
            levels_seen.add(int((result.leaves_per_level > 0).sum()))
            assert result.face_origin.shape == (result.num_triangles,)
            assert result.face_origin.max() < mesh.num_faces
        assert max(levels_seen) >= 2


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
@pytest.mark.parametrize("degree", [3, 4])
def test_vertices_equal_uniform_vertices_bitwise(degree: int, dtype: type) -> None:
    mesh = pyramid_prism()
    mesh = bidegree.Mesh(
        mesh.points.astype(dtype), face_sizes=mesh.face_sizes, face_indices=mesh.face_indices
    )
    result = bidegree.subdivide_adaptive(mesh, degree=degree, max_level=4, tolerance=0.003)
    assert result.points.dtype == dtype
    levels = np.unique(result.vertex_level)
    assert len(levels) >= 2
    for level in levels:
        uniform = bidegree.subdivide(mesh, degree=degree, levels=int(level)).points
        at = result.vertex_level == level
        np.testing.assert_array_equal(
            result.points[at].view(np.uint8), uniform[result.vertex_id[at]].view(np.uint8)
        )


def test_tolerance_zero_is_uniform() -> None:
    mesh = bumped_cube()
    result = bidegree.subdivide_adaptive(mesh, degree=4, max_level=3, tolerance=0)
    uniform = bidegree.subdivide(mesh, degree=4, levels=3)
    assert result.num_leaves == uniform.num_faces
    assert result.num_triangles == 2 * uniform.num_faces
    assert result.num_vertices == uniform.num_vertices
    np.testing.assert_array_equal(result.points, uniform.points[result.vertex_id])


def test_flat_cage_with_a_bump_needs_far_fewer_faces() -> None:
    n = 12
    a, b = np.meshgrid(np.arange(n + 1), np.arange(n + 1), indexing="ij")
    points = np.stack([a, b, np.zeros_like(a)], axis=-1).reshape(-1, 3).astype(np.float64)
    points[(n // 2) * (n + 1) + n // 2, 2] = 2.0
    ids = a[:-1, :-1] * (n + 1) + b[:-1, :-1]
    faces = np.stack([ids, ids + n + 1, ids + n + 2, ids + 1], axis=-1).reshape(-1, 4)
    mesh = bidegree.Mesh(points, faces)
    result = bidegree.subdivide_adaptive(mesh, degree=4, max_level=4, tolerance=1e-4)
    uniform_faces = bidegree.estimate(mesh, degree=4, levels=4)["faces"]
    assert result.leaves_per_level[4] > 0
    assert result.num_leaves / uniform_faces < 0.1


def test_measured_error_and_repr() -> None:
    result = bidegree.subdivide_adaptive(
        bumped_cube(), degree=3, max_level=3, tolerance=0.01, measure_leaves=True
    )
    assert result.max_error is not None and result.max_error > 0
    assert "AdaptiveResult(" in repr(result)
    plain = bidegree.subdivide_adaptive(bumped_cube(), degree=3, max_level=3, tolerance=0.01)
    assert plain.max_error is None
    with pytest.raises(ValueError):
        plain.triangles[0, 0] = 1


@pytest.mark.parametrize(
    ("kwargs", "error"),
    [
        ({"degree": 0}, bidegree.DegreeOutOfRangeError),
        ({"degree": -3}, bidegree.DegreeOutOfRangeError),
        ({"max_level": 0}, bidegree.LevelOutOfRangeError),
        ({"max_level": 99}, bidegree.LevelOutOfRangeError),
        ({"tolerance": -1.0}, bidegree.InvalidInputError),
        ({"tolerance": float("nan")}, bidegree.InvalidInputError),
        ({"tolerance": "flat"}, bidegree.InvalidInputError),
        ({"max_level": 8, "tolerance": 0, "memory_budget": 10_000}, bidegree.MemoryBudgetError),
    ],
)
def test_invalid_requests_raise_typed_errors(kwargs: dict, error: type) -> None:
    with pytest.raises(error):
        bidegree.subdivide_adaptive(bumped_cube(), **kwargs)


def test_cli_adaptive_writes_triangles(tmp_path: Path) -> None:
    cage = tmp_path / "cube.obj"
    bumped_cube().write_obj(cage)
    out = tmp_path / "out.obj"
    done = cli(
        "subdivide", cage, "-o", out, "--adaptive", "--tolerance", "0.003", "--max-level", "4",
        "--degree", "3",
    )  # fmt: skip
    assert done.returncode == 0, done.stderr
    assert "leaves" in done.stdout and "triangles" in done.stdout
    faces = [line for line in out.read_text().splitlines() if line.startswith("f ")]
    expected = bidegree.subdivide_adaptive(
        bidegree.Mesh.from_obj(cage), degree=3, max_level=4, tolerance=0.003
    )
    assert len(faces) == expected.num_triangles
    assert all(len(f.split()) == 4 for f in faces)
    bad = cli("subdivide", cage, "-o", tmp_path / "out.usda", "--adaptive")
    assert bad.returncode == 2 and "OBJ only" in bad.stderr


@pytest.mark.parametrize(
    ("tolerance", "budget"),
    [("0", None), ("1e-14", "256M")],
    ids=["uniform-refused-up-front", "tiny-tolerance-stops-at-a-level"],
)
def test_cli_adaptive_stays_under_the_budget(tmp_path: Path, tolerance: str, budget: str) -> None:
    """Issue 18 item 2: under an address-space limit of 1.5 GiB, ``--adaptive --max-level 16``
    is a memory error (exit 2), not an abort or a runaway: tolerance 0 under the default budget
    is refused before any work, a tiny tolerance under 256 MB at the first level whose estimate
    passes the budget."""
    cage = tmp_path / "cube.obj"
    bumped_cube().write_obj(cage)

    args = ["--adaptive", "--tolerance", tolerance, "--max-level", "16"]
    done = cli(
        "subdivide",
        cage,
        "-o",
        tmp_path / "o.obj",
        *args,
        *(["--memory-budget", budget] if budget else []),
        limits={resource.RLIMIT_AS: 3 << 29},
    )
    assert done.returncode == 2, (done.returncode, done.stderr)
    assert "memory budget" in done.stderr, done.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["cube.obj"]


def bumped_grid(n: int = 6, **kwargs: object) -> bidegree.Mesh:
    """An open n x n grid in z = 0 with its middle vertex lifted (uneven refinement)."""
    a, b = np.meshgrid(np.arange(n + 1), np.arange(n + 1), indexing="ij")
    points = np.stack([a, b, np.zeros_like(a)], axis=-1).reshape(-1, 3).astype(np.float64)
    points[(n // 2) * (n + 1) + n // 2, 2] = 2.0
    ids = a[:-1, :-1] * (n + 1) + b[:-1, :-1]
    faces = np.stack([ids, ids + n + 1, ids + n + 2, ids + 1], axis=-1).reshape(-1, 4)
    return bidegree.Mesh(points, faces.tolist(), **kwargs)


def finned_grid(n: int = 6, **kwargs: object) -> bidegree.Mesh:
    """The bumped grid with a fin of 2 quads on two interior edges (edges of 3 faces, the fin's
    second face against the first) and a triangle hanging from a corner (a bowtie vertex)."""
    grid = bumped_grid(n)
    faces = np.asarray(grid.face_indices).reshape(-1, 4).tolist()
    points = grid.points.tolist()
    base = len(points)
    line = [2 * (n + 1) + 1, 2 * (n + 1) + 2, 2 * (n + 1) + 3]
    for k, v in enumerate(line):
        x, y, _ = points[v]
        points.append([x + 0.2 * k, y, 1.0 + 0.4 * (k % 2)])
    points += [[-1.0, -0.5, 0.3], [-0.5, -1.0, -0.3]]
    faces += [[line[0], line[1], base + 1, base], [base + 2, base + 1, line[1], line[2]]]
    faces += [[0, base + 4, base + 3]]
    return bidegree.Mesh(np.array(points), faces, **kwargs)


def seamed_uvs(mesh: bidegree.Mesh, n: int = 6) -> np.ndarray:
    """Per-corner uvs of a grid cage with a seam down the middle (right half shifted) and one
    across the right half (its top shifted too): a vertex with 3 values; the fin and the
    hanging triangle (if any) get uvs of their own."""
    corner_verts = np.asarray(mesh.face_indices)
    face = np.repeat(np.arange(mesh.num_faces), mesh.face_sizes)
    p = mesh.points[corner_verts]
    row, col = face // n, face % n
    grid = face < n * n
    right = (grid & (col >= n // 2)).astype(np.float64)
    top = (grid & (col >= n // 2) & (row >= n // 2)).astype(np.float64)
    extra = (~grid) * (0.3 * p[:, 2] + 0.05 * face)
    u = 0.1 * p[:, 0] + 0.7 * right + 0.01 * p[:, 1] ** 2 + extra
    v = 0.1 * p[:, 1] + 0.4 * top - extra
    return np.stack([u, v], axis=1)


def uniform_by_vertex_and_face(
    values: np.ndarray, face_indices: np.ndarray, face_origin: np.ndarray, sizes: np.ndarray
) -> dict[tuple[int, int], bytes]:
    """The uniform face-varying value at each (output vertex, cage face): checked to be one
    value (one side of a seam)."""
    origin = np.repeat(face_origin, sizes)
    out: dict[tuple[int, int], bytes] = {}
    for v, o, row in zip(face_indices.tolist(), origin.tolist(), values, strict=True):
        bits = row.tobytes()
        assert out.setdefault((v, o), bits) == bits, f"uniform corners at {(v, o)} differ"
    return out


UV_MODES = ["none", "corners-only", "corners-plus1", "corners-plus2", "boundaries", "all"]


@pytest.mark.parametrize("degree", range(1, 10))
def test_non_manifold_and_holed_cages_are_uniform_at_every_level(degree: int) -> None:
    tolerance = 3e-3 if degree < 6 else 5e-4
    finned = finned_grid()
    weights = finned.points[:, :2] ** 2 - finned.points[:, 1:]
    result = bidegree.subdivide_adaptive(
        finned, degree=degree, max_level=3, tolerance=tolerance, vertex_values=weights
    )
    levels = np.unique(result.vertex_level)
    assert len(levels) >= 2 or degree == 1
    for level in levels:
        plan = bidegree.Plan(finned, degree=degree, levels=int(level))
        at = result.vertex_level == level
        ids = result.vertex_id[at]
        np.testing.assert_array_equal(
            result.points[at].view(np.uint8), plan.result().points[ids].view(np.uint8)
        )
        np.testing.assert_array_equal(
            result.vertex_values[at].view(np.uint8), plan.evaluate(weights)[ids].view(np.uint8)
        )
    # Holes (given, or boundary "none"): those faces are left out, the other vertices are the
    # uniform ones (a hole shapes its neighbours: the cage without holes has the same points).
    holed = bidegree.Mesh(
        finned.points,
        face_sizes=finned.face_sizes,
        face_indices=finned.face_indices,
        holes=[7, 20, 36],
    )
    none = bumped_grid(boundary="none")
    for mesh, plain, holes in ((holed, finned, {7, 20, 36}), (none, bumped_grid(), None)):
        result = bidegree.subdivide_adaptive(mesh, degree=degree, max_level=3, tolerance=tolerance)
        drawn = set(result.face_origin.tolist())
        uniform_drawn = set(bidegree.subdivide(mesh, degree=degree, levels=1).face_origin.tolist())
        assert drawn <= uniform_drawn
        if holes is not None:
            assert not drawn & holes
        for level in np.unique(result.vertex_level):
            at = result.vertex_level == level
            uniform = bidegree.subdivide(plain, degree=degree, levels=int(level)).points
            np.testing.assert_array_equal(result.points[at], uniform[result.vertex_id[at]])


@pytest.mark.parametrize("degree", range(1, 10))
def test_uvs_equal_uniform_uvs_at_their_level(degree: int) -> None:
    tolerance = 3e-3 if degree < 6 else 5e-4
    base = bumped_grid()
    uvs = seamed_uvs(base)
    mesh = bidegree.Mesh(
        base.points, face_sizes=base.face_sizes, face_indices=base.face_indices, uvs=uvs
    )
    for mode in UV_MODES:
        result = bidegree.subdivide_adaptive(
            mesh,
            degree=degree,
            max_level=3,
            tolerance=tolerance,
            uv_mode=mode,
            face_varying={"twice": 2 * uvs},
        )
        assert result.uv_mode == mode and result.uvs is not None
        assert result.uvs.shape == (3 * result.num_triangles, 2)
        assert set(result.face_varying) == {"twice"}
        corner_vertex = result.triangles.reshape(-1)
        corner_face = np.repeat(result.face_origin, 3)
        for level in np.unique(result.vertex_level):
            uniform = bidegree.subdivide(mesh, degree=degree, levels=int(level), uv_mode=mode)
            twice = bidegree.Plan(mesh, degree=degree, levels=int(level)).evaluate_face_varying(
                2 * uvs, mode
            )
            for values, got in ((uniform.uvs, result.uvs), (twice, result.face_varying["twice"])):
                want = uniform_by_vertex_and_face(
                    values, uniform.face_indices, uniform.face_origin, uniform.face_sizes
                )
                for c in np.flatnonzero(result.vertex_level[corner_vertex] == level):
                    key = (int(result.vertex_id[corner_vertex[c]]), int(corner_face[c]))
                    assert got[c].tobytes() == want[key], (mode, level, key)


def test_uvs_of_a_non_manifold_cage_and_the_obj_output(tmp_path: Path) -> None:
    finned = finned_grid()
    mesh = bidegree.Mesh(
        finned.points,
        face_sizes=finned.face_sizes,
        face_indices=finned.face_indices,
        uvs=seamed_uvs(finned),
    )
    result = bidegree.subdivide_adaptive(mesh, degree=3, max_level=3, tolerance=3e-3)
    assert result.uv_mode == "boundaries" and np.isfinite(result.uvs).all()
    path = tmp_path / "adaptive.obj"
    result.write_obj(path)
    lines = path.read_text().splitlines()
    # One vt per distinct value: read back, the indices weld as the values do.
    distinct = len(np.unique(result.uvs, axis=0))
    assert sum(line.startswith("vt ") for line in lines) == distinct
    np.testing.assert_allclose(bidegree.Mesh.from_obj(path).uvs, result.uvs, rtol=0, atol=1e-12)
    faces = [line for line in lines if line.startswith("f ")]
    assert len(faces) == result.num_triangles and "/" in faces[0]
    # Triangle edges along cage edges know them (checked against the uniform plans in Rust).
    assert result.edge_origin.shape == result.edge_level.shape == (3 * result.num_triangles,)
    np.testing.assert_array_equal(result.cage_edges, bidegree.Plan(mesh, levels=1).cage_edges)
    on = result.edge_origin >= 0
    assert on.any() and (~on).any()
    assert (result.edge_sharpness[~on] == 0).all() and (result.edge_sharpness[on] == 10).any()
    plain = bidegree.subdivide_adaptive(finned, degree=3, max_level=3, tolerance=3e-3)
    assert plain.uvs is None and plain.vertex_values is None and plain.face_varying == {}
    np.testing.assert_array_equal(plain.points, result.points)
    with pytest.raises(bidegree.InvalidInputError):
        bidegree.subdivide_adaptive(mesh, uv_mode="smooth")
    with pytest.raises(bidegree.InvalidInputError):
        bidegree.subdivide_adaptive(mesh, vertex_values=np.zeros((3, 2)))
    with pytest.raises(bidegree.InvalidInputError):
        bidegree.subdivide_adaptive(mesh, face_varying={"uv": np.zeros((5, 2))})
    with pytest.raises(bidegree.NonFiniteError):
        bidegree.subdivide_adaptive(
            mesh, face_varying={"uv": np.full((mesh.num_corners, 2), np.nan)}
        )


def test_cage_vertices_and_their_corner_sharpness() -> None:
    """``cage_vertex`` names each cage vertex's own output vertex (past an isolated vertex the
    core drops), ``vertex_sharpness`` is its corner sharpness lowered by its level."""
    prism = pyramid_prism()
    points = np.concatenate([[[9.0, 9.0, 9.0]], prism.points])
    faces = prism.face_indices + 1
    given = {3: 10.0, 6: 2.5, 9: 1.5}
    mesh = bidegree.Mesh(
        points,
        face_sizes=prism.face_sizes,
        face_indices=faces,
        corners=(np.array(list(given)), np.array(list(given.values()))),
    )
    with pytest.warns(bidegree.IsolatedVerticesWarning):
        result = bidegree.subdivide_adaptive(mesh, degree=3, max_level=4, tolerance=0.003)
    assert len(np.unique(result.vertex_level)) >= 2
    assert result.cage_vertex.dtype == np.int32 and result.vertex_sharpness.dtype == np.float32
    at = np.flatnonzero(result.cage_vertex >= 0)
    np.testing.assert_array_equal(np.sort(result.cage_vertex[at]), np.arange(1, 12))
    np.testing.assert_array_equal(result.cage_vertex[at], result.vertex_id[at] + 1)
    assert (result.vertex_id[result.cage_vertex < 0] >= 11).all()
    for i in at:
        s = given.get(int(result.cage_vertex[i]), 0.0)
        kept = 10.0 if s >= 10 else max(s - int(result.vertex_level[i]), 0.0)
        assert result.vertex_sharpness[i] == np.float32(kept)
    assert (result.vertex_sharpness[result.cage_vertex < 0] == 0).all()
    corner = at[result.cage_vertex[at] == 3][0]
    np.testing.assert_array_equal(result.points[corner], points[3])


def test_one_dimensional_values_come_back_one_dimensional() -> None:
    """As ``Plan.evaluate`` / ``evaluate_face_varying``: (vertices,) in, (N,) out; a (corners,)
    set gives (3 T,); the same numbers as the (.., 1) form."""
    base = bumped_grid()
    weights = base.points[:, 0] * base.points[:, 1]
    uvs = seamed_uvs(base)
    mesh = bidegree.Mesh(
        base.points, face_sizes=base.face_sizes, face_indices=base.face_indices, uvs=uvs
    )
    kwargs = {"degree": 3, "max_level": 3, "tolerance": 3e-3}
    flat = bidegree.subdivide_adaptive(
        mesh, vertex_values=weights, face_varying={"u": uvs[:, 0], "uv": uvs}, **kwargs
    )
    column = bidegree.subdivide_adaptive(
        mesh, vertex_values=weights[:, None], face_varying={"u": uvs[:, :1]}, **kwargs
    )
    assert flat.vertex_values.shape == (flat.num_vertices,)
    assert flat.face_varying["u"].shape == (3 * flat.num_triangles,)
    assert flat.face_varying["uv"].shape == (3 * flat.num_triangles, 2)
    assert column.vertex_values.shape == (column.num_vertices, 1)
    np.testing.assert_array_equal(flat.vertex_values, column.vertex_values[:, 0])
    np.testing.assert_array_equal(flat.face_varying["u"], column.face_varying["u"][:, 0])


@pytest.mark.parametrize("mode", ["boundaries", "none", "all"])
def test_indexed_uvs_keep_their_seams(mode: str) -> None:
    """The mesh's ``uv_indices`` (and ``(values, mode, indices)`` sets) are the topology on
    adaptive output as on uniform output: a cut with equal coordinates on both sides stays a
    seam; every triangle corner is the uniform (indexed) value at its vertex's level."""
    base = bumped_grid()
    n = 6
    chart = np.column_stack([0.1 * base.points[:, 0], 0.1 * base.points[:, 1] ** 1.5])
    corner_verts = np.asarray(base.face_indices)
    face = np.repeat(np.arange(base.num_faces), base.face_sizes)
    # Faces are column-major here (face = a * n + b, a the x index): cut along x = 3.
    cut = corner_verts.copy()
    on_cut = (face // n >= 3) & (base.points[corner_verts, 0] == 3)
    cut[on_cut] += len(base.points)
    values = np.concatenate([chart, chart])
    mesh = bidegree.Mesh(
        base.points,
        face_sizes=base.face_sizes,
        face_indices=base.face_indices,
        uvs=values,
        uv_indices=cut,
    )
    kwargs = {"degree": 3, "max_level": 3, "tolerance": 3e-3, "uv_mode": mode}
    result = bidegree.subdivide_adaptive(
        base, face_varying={"cut": (values, mode, cut), "welded": values[cut]}, **kwargs
    )
    from_mesh = bidegree.subdivide_adaptive(mesh, **kwargs)
    np.testing.assert_array_equal(from_mesh.uvs, result.face_varying["cut"])
    if mode != "all":
        assert np.abs(result.face_varying["cut"] - result.face_varying["welded"]).max() > 1e-4
    corner_vertex = result.triangles.reshape(-1)
    corner_face = np.repeat(result.face_origin, 3)
    for level in np.unique(result.vertex_level):
        uniform = bidegree.subdivide(mesh, degree=3, levels=int(level), uv_mode=mode)
        want = uniform_by_vertex_and_face(
            uniform.uvs, uniform.face_indices, uniform.face_origin, uniform.face_sizes
        )
        for c in np.flatnonzero(result.vertex_level[corner_vertex] == level):
            key = (int(result.vertex_id[corner_vertex[c]]), int(corner_face[c]))
            assert result.face_varying["cut"][c].tobytes() == want[key], (level, key)
