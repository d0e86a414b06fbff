"""Adaptive subdivision from Python: exact uniform points, watertight triangles, the CLI."""

from __future__ import annotations

import resource
import subprocess
import sys
from collections import Counter
from pathlib import Path

import bidegree
import numpy as np
import pytest
from cages import CUBE_FACES, CUBE_POINTS


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
    done = subprocess.run(
        [
            sys.executable,
            "-m",
            "bidegree.cli",
            "subdivide",
            str(cage),
            "-o",
            str(out),
            "--adaptive",
            "--tolerance",
            "0.003",
            "--max-level",
            "4",
            "--degree",
            "3",
        ],
        capture_output=True,
        text=True,
        check=False,
        timeout=120,
    )
    assert done.returncode == 0, done.stderr
    assert "leaves" in done.stdout and "triangles" in done.stdout
    faces = [line for line in out.read_text().splitlines() if line.startswith("f ")]
    expected = bidegree.subdivide_adaptive(
        bidegree.Mesh.from_obj(cage), degree=3, max_level=4, tolerance=0.003
    )
    assert len(faces) == expected.num_triangles
    assert all(len(f.split()) == 4 for f in faces)
    bad = subprocess.run(
        [
            sys.executable,
            "-m",
            "bidegree.cli",
            "subdivide",
            str(cage),
            "-o",
            str(tmp_path / "out.usda"),
            "--adaptive",
        ],
        capture_output=True,
        text=True,
        check=False,
        timeout=120,
    )
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

    def limit() -> None:
        resource.setrlimit(resource.RLIMIT_AS, (3 << 29, 3 << 29))

    args = ["--adaptive", "--tolerance", tolerance, "--max-level", "16"]
    done = subprocess.run(
        [
            sys.executable,
            "-m",
            "bidegree.cli",
            "subdivide",
            str(cage),
            "-o",
            str(tmp_path / "o.obj"),
        ]
        + args
        + (["--memory-budget", budget] if budget else []),
        capture_output=True,
        text=True,
        check=False,
        timeout=120,
        preexec_fn=limit,
    )
    assert done.returncode == 2, (done.returncode, done.stderr)
    assert "memory budget" in done.stderr, done.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["cube.obj"]
