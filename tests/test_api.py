"""The Python API of the installed package: validation errors as their classes, dtypes and memory
layouts, plan re-evaluation, attributes, face-varying uvs, no mutation of the caller's arrays,
and counts that follow from the topology. (The mathematics of the scheme is tested in Rust.)"""

from __future__ import annotations

import sys
import threading
import time
import warnings
from pathlib import Path

import bidegree
import numpy as np
import pytest
from cages import CUBE_FACES, CUBE_POINTS, cube


def mixed_cage() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """An open cage with a triangle, quads and a pentagon (points, face_sizes, face_indices),
    irregular enough that any mixing of rows or channels shows."""
    points = np.array(
        [
            [0.0, 0.0, 0.1],
            [1.0, 0.0, 0.0],
            [2.0, 0.1, 0.3],
            [0.0, 1.0, 0.2],
            [1.1, 1.0, 0.5],
            [2.0, 1.2, 0.1],
            [0.5, 2.0, 0.4],
            [1.6, 2.1, 0.0],
            [2.5, 0.6, 0.2],
        ]
    )
    faces = [[0, 1, 4, 3], [1, 2, 5, 4], [3, 4, 7, 6], [4, 5, 7], [2, 8, 5]]
    sizes = np.array([len(f) for f in faces])
    indices = np.concatenate([np.array(f) for f in faces])
    return points, sizes, indices


# ---------------------------------------------------------------------------------------------
# Exceptions


def test_every_error_class_derives_from_bidegree_error() -> None:
    names = [
        "EmptyMeshError",
        "FaceTooSmallError",
        "RepeatedVertexError",
        "IndexOutOfRangeError",
        "NonFiniteError",
        "DegenerateFaceError",
        "NonManifoldEdgeError",
        "InconsistentOrientationError",
        "CreaseNotAnEdgeError",
        "DegreeOutOfRangeError",
        "LevelOutOfRangeError",
        "MemoryBudgetError",
        "InvalidInputError",
        "BidegreeIOError",
        "InternalError",
    ]
    classes = {getattr(bidegree, name) for name in names}
    assert len(classes) == len(names)
    for cls in classes:
        assert issubclass(cls, bidegree.BidegreeError)
    assert issubclass(bidegree.IsolatedVerticesWarning, UserWarning)
    assert issubclass(bidegree.IndexOutOfRangeError, IndexError)
    assert issubclass(bidegree.BidegreeIOError, OSError)
    assert isinstance(bidegree.__version__, str) and bidegree.__version__


@pytest.mark.parametrize(
    ("points", "faces"),
    [(np.zeros((0, 3)), []), (CUBE_POINTS, [])],
    ids=["no-vertices", "no-faces"],
)
def test_empty_mesh(points: np.ndarray, faces: list) -> None:
    with pytest.raises(bidegree.EmptyMeshError):
        bidegree.Mesh(points, faces)


def test_face_too_small() -> None:
    with pytest.raises(bidegree.FaceTooSmallError) as info:
        bidegree.Mesh(CUBE_POINTS, [[0, 1, 2], [3, 4]])
    assert (info.value.face, info.value.size) == (1, 2)
    assert "face 1" in str(info.value)


def test_repeated_vertex() -> None:
    """A face may repeat a vertex (OpenSubdiv's degenerate edge); fewer than three distinct
    vertices stays an error, naming the face and the vertex."""
    bidegree.Mesh(CUBE_POINTS, [[0, 1, 2, 1]])
    with pytest.raises(bidegree.RepeatedVertexError) as info:
        bidegree.Mesh(CUBE_POINTS, [[0, 1, 1, 0]])
    assert (info.value.face, info.value.vertex) == (0, 1)


@pytest.mark.parametrize("bad", [8, 1000, -1], ids=["just-past", "far", "negative"])
def test_index_out_of_range(bad: int) -> None:
    with pytest.raises(bidegree.IndexOutOfRangeError) as info:
        bidegree.Mesh(CUBE_POINTS, [[0, 1, bad]])
    assert info.value.index == bad
    assert info.value.num_vertices == 8


def test_index_out_of_range_in_flat_arrays_and_tags() -> None:
    with pytest.raises(bidegree.IndexOutOfRangeError):
        bidegree.Mesh(CUBE_POINTS, face_sizes=[3], face_indices=np.array([0, 1, 9], np.uint32))
    with pytest.raises(bidegree.IndexOutOfRangeError):
        cube(creases=([[0, 8]], [1.0]))
    with pytest.raises(bidegree.IndexOutOfRangeError):
        cube(corners=([-2], [1.0]))


def test_non_finite_points() -> None:
    points = CUBE_POINTS.copy()
    points[5, 1] = np.nan
    mesh = bidegree.Mesh(points, CUBE_FACES)
    with pytest.raises(bidegree.NonFiniteError) as info:
        bidegree.subdivide(mesh)
    assert info.value.vertex == 5
    points[5, 1] = np.inf
    with pytest.raises(bidegree.NonFiniteError):
        bidegree.subdivide(bidegree.Mesh(points.astype(np.float32), CUBE_FACES))


def test_degenerate_face_is_subdivided() -> None:
    """Zero area is a property of positions, not of topology: the collapsed quad subdivides
    (to its one point), as in OpenSubdiv."""
    result = bidegree.subdivide(bidegree.Mesh(np.zeros((4, 3)), [[0, 1, 2, 3]]))
    assert np.all(np.asarray(result.points) == 0.0)
    with pytest.raises(bidegree.NonFiniteError):
        bidegree.subdivide(bidegree.Mesh(np.full((4, 3), np.nan), [[0, 1, 2, 3]]))


def test_non_manifold_edge() -> None:
    """Three faces on one edge: each keeps its own side; the edge is an infinitely sharp curve
    they all meet (the edge's children are shared, bitwise)."""
    points = np.random.default_rng(0).normal(size=(5, 3))
    mesh = bidegree.Mesh(points, [[0, 1, 2], [1, 0, 3], [0, 1, 4]])
    result = bidegree.subdivide(mesh, levels=2)
    assert len(result.face_sizes) == 3 * 3 * 4
    pts = np.asarray(result.points)
    # The shared edge stays the straight segment between its (corner) ends.
    t = (pts - points[0]) @ (points[1] - points[0]) / np.sum((points[1] - points[0]) ** 2)
    on_line = np.linalg.norm(pts - (points[0] + np.outer(t, points[1] - points[0])), axis=1)
    assert np.sum(on_line < 1e-12) >= 5


def test_inconsistent_orientation() -> None:
    """Faces running an edge the same way subdivide, each on its own side."""
    points = np.random.default_rng(1).normal(size=(6, 3))
    mesh = bidegree.Mesh(points, [[0, 1, 2, 3], [0, 1, 4, 5]])
    result = bidegree.subdivide(mesh, levels=1)
    assert len(result.face_sizes) == 8


def test_holes_are_left_out() -> None:
    """Hole faces shape their neighbours but are not drawn, nor the vertices only they use."""
    whole = bidegree.subdivide(cube(), levels=2)
    holed = bidegree.subdivide(cube(holes=[0]), levels=2)
    assert len(holed.face_sizes) == len(whole.face_sizes) - 16
    assert len(holed.points) == len(whole.points) - 9
    kept = {tuple(p) for p in np.asarray(holed.points)}
    assert kept <= {tuple(p) for p in np.asarray(whole.points)}
    with pytest.raises(bidegree.InvalidInputError):
        cube(holes=[6])


def test_limits_and_dual_output_with_holes_and_non_manifold_edges() -> None:
    """Limits of a cage with holes are the whole surface's at the vertices and corners drawn;
    the dual output leaves out the dual faces that reach into a hole and has one face per sheet
    at a non-manifold edge (issue 13)."""
    whole = bidegree.Plan(cube(), degree=4, levels=2)
    holed = bidegree.Plan(cube(holes=[0]), degree=4, levels=2)
    positions, normals = holed.limit_surface()
    assert positions.shape == (holed.num_output_vertices, 3)
    assert normals.shape == (len(holed.face_indices), 3)
    drawn = {tuple(p) for p in holed.limit_positions()}
    assert drawn < {tuple(p) for p in whole.limit_positions()}
    dual = bidegree.subdivide(cube(holes=[0]), degree=3, levels=2, output="dual")
    full = bidegree.subdivide(cube(), degree=3, levels=2, output="dual")
    # Every vertex of M_2 whose faces touch the hole face loses its dual face: 5 x 5 of them.
    assert len(dual.face_sizes) == len(full.face_sizes) - 25
    fin = bidegree.Mesh(
        np.random.default_rng(2).normal(size=(5, 3)), [[0, 1, 2], [1, 0, 3], [0, 1, 4]]
    )
    sheets = bidegree.subdivide(fin, degree=2, levels=1, output="dual")
    # 3 sheets of 3 quads each: 3 x 7 vertices, the line's 3 vertices with a face per sheet.
    assert len(sheets.face_sizes) == 3 * 7
    assert np.isfinite(sheets.points).all()


_THREADS_SCRIPT = """
import hashlib, bidegree, numpy as np
from cages import cube
fin = bidegree.Mesh(
    np.random.default_rng(2).normal(size=(5, 3)), [[0, 1, 2], [1, 0, 3], [0, 1, 4]]
)
h = hashlib.sha256()
for degree in (2, 3, 4):
    h.update(bidegree.subdivide(fin, degree=degree, levels=2, output="dual").points.tobytes())
    holed = bidegree.subdivide(cube(holes=[0]), degree=degree, levels=2, limit=True, normals=True)
    h.update(holed.points.tobytes())
    h.update(holed.normals.tobytes())
print(h.hexdigest())
"""


def test_dual_and_limits_do_not_depend_on_rayon_num_threads() -> None:
    """The dual output of a non-manifold cage and the limits of a cage with holes are the same
    bits with ``RAYON_NUM_THREADS`` 1 and 3 (issue 13)."""
    import os
    import subprocess

    def digest(threads: int) -> str:
        env = {**os.environ, "RAYON_NUM_THREADS": str(threads)}
        tests = str(Path(__file__).parent)
        env["PYTHONPATH"] = os.pathsep.join(filter(None, [tests, env.get("PYTHONPATH")]))
        proc = subprocess.run(
            [sys.executable, "-c", _THREADS_SCRIPT], env=env, capture_output=True, text=True
        )
        assert proc.returncode == 0, proc.stderr
        return proc.stdout.strip()

    assert digest(1) == digest(3)


def test_crease_not_an_edge() -> None:
    mesh = cube(creases=([[0, 6]], [2.0]))  # a space diagonal
    with pytest.raises(bidegree.CreaseNotAnEdgeError) as info:
        bidegree.Plan(mesh)
    assert (info.value.a, info.value.b) == (0, 6)


@pytest.mark.parametrize("degree", [0, 32, -1, 2**70])
def test_degree_out_of_range(degree: int) -> None:
    with pytest.raises(bidegree.DegreeOutOfRangeError):
        bidegree.Plan(cube(), degree=degree)
    with pytest.raises(bidegree.DegreeOutOfRangeError):
        bidegree.subdivide(cube(), degree=degree)
    with pytest.raises(bidegree.DegreeOutOfRangeError):
        bidegree.estimate(cube(), degree, 2)


@pytest.mark.parametrize("levels", [17, -1])
def test_levels_out_of_range(levels: int) -> None:
    with pytest.raises(bidegree.LevelOutOfRangeError):
        bidegree.Plan(cube(), levels=levels)
    with pytest.raises(bidegree.LevelOutOfRangeError):
        bidegree.subdivide(cube(), levels=levels)


def test_memory_budget_refusal() -> None:
    with pytest.raises(bidegree.MemoryBudgetError) as info:
        bidegree.Plan(cube(), degree=4, levels=10, memory_budget=1_000_000)
    assert info.value.budget == 1_000_000
    assert info.value.required > 1_000_000
    assert info.value.faces == 24 * 4**9
    with pytest.raises(bidegree.MemoryBudgetError):
        bidegree.subdivide(cube(), degree=4, levels=3, memory_budget=10)
    # The default budget (4 GiB) refuses 16 levels of a cube without allocating anything.
    with pytest.raises(bidegree.MemoryBudgetError):
        bidegree.Plan(cube(), levels=16)


def test_isolated_vertices_warn_and_are_dropped() -> None:
    points = np.vstack([CUBE_POINTS, [[5.0, 5.0, 5.0]]])
    mesh = bidegree.Mesh(points, CUBE_FACES)
    with pytest.warns(bidegree.IsolatedVerticesWarning, match="1 isolated") as caught:
        result = bidegree.subdivide(mesh, degree=3, levels=2)
    assert caught[0].filename == __file__  # the warning points at the caller
    with pytest.warns(bidegree.IsolatedVerticesWarning):
        plan = bidegree.Plan(mesh, degree=3, levels=2)
    assert list(plan.isolated_vertices) == [8]
    reference = bidegree.subdivide(cube(), degree=3, levels=2)
    assert result.points.shape == reference.points.shape
    np.testing.assert_array_equal(result.points, reference.points)
    # Without isolated vertices there is no warning.
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        bidegree.subdivide(cube(), degree=3, levels=2)


@pytest.mark.parametrize(
    "make",
    [
        lambda: bidegree.Mesh(CUBE_POINTS[:, :2], CUBE_FACES),
        lambda: bidegree.Mesh(CUBE_POINTS.reshape(-1), CUBE_FACES),
        lambda: bidegree.Mesh(CUBE_POINTS, CUBE_FACES, face_sizes=[4], face_indices=[0, 1, 2, 3]),
        lambda: bidegree.Mesh(CUBE_POINTS),
        lambda: bidegree.Mesh(CUBE_POINTS, face_sizes=[[4]], face_indices=[0, 1, 2, 3]),
        lambda: bidegree.Mesh(CUBE_POINTS, [[0.0, 1.5, 2.0]]),
        lambda: bidegree.Mesh(np.array([["a", "b", "c"]]), [[0, 1, 2]]),
        lambda: bidegree.Mesh(CUBE_POINTS, face_sizes=[4, 4], face_indices=[0, 1, 2, 3]),
        lambda: cube(boundary="nothing"),
        lambda: cube(uvs=np.zeros((23, 2))),
        lambda: cube(uvs=np.zeros((24, 3))),
        lambda: cube(creases=([0, 1], [1.0])),
        lambda: cube(creases=([[0, 1]], [1.0, 2.0])),
        lambda: cube(creases=([[0, 1]], [-1.0])),
        lambda: cube(creases=[[0, 1]]),
        lambda: bidegree.Plan(cube(), output="both"),
        lambda: bidegree.Plan(cube(), degree=3.5),
        lambda: bidegree.Plan(cube(), memory_budget=-1),
        lambda: bidegree.Plan("cube"),
        lambda: bidegree.Plan(cube()).evaluate(np.zeros((7, 3))),
        lambda: bidegree.Plan(cube()).evaluate(np.zeros((8, 0))),
        lambda: bidegree.Plan(cube()).evaluate(np.zeros((8, 3, 1))),
        lambda: bidegree.Plan(cube()).evaluate_face_varying(np.zeros((8, 2))),
        lambda: bidegree.Plan(cube()).result(np.zeros((8, 2))),
        lambda: bidegree.subdivide(cube(), output=None),
    ],
)
def test_invalid_input(make) -> None:
    with pytest.raises(bidegree.InvalidInputError):
        make()


def test_io_errors(tmp_path: Path) -> None:
    with pytest.raises(bidegree.BidegreeIOError, match=r"missing\.obj"):
        bidegree.Mesh.from_obj(tmp_path / "missing.obj")
    bad = tmp_path / "bad.obj"
    bad.write_text("v 0 0 0\nv 1 0 0\nv 1 1 zero\nf 1 2 3\n")
    with pytest.raises(bidegree.BidegreeIOError, match=r"bad\.obj:3: 'zero' is not a number"):
        bidegree.Mesh.from_obj(bad)
    result = bidegree.subdivide(cube(), degree=2, levels=1)
    with pytest.raises(bidegree.BidegreeIOError):
        result.write_obj(tmp_path / "no" / "such" / "dir.obj")


def test_panic_becomes_internal_error() -> None:
    # The message is the typed error alone; the panic's text and place are its detail.
    with pytest.raises(bidegree.InternalError, match="a bug in bidegree") as caught:
        bidegree._native._panic_for_tests()
    assert "deliberate panic" not in str(caught.value)
    assert "deliberate panic" in caught.value.detail
    assert "errors.rs" in caught.value.detail
    # The extension still works afterwards.
    assert bidegree.subdivide(cube(), degree=3, levels=1).num_faces == 24


def test_panic_on_a_worker_thread_becomes_internal_error() -> None:
    # The core's passes run on rayon's workers: a panic there is handed to the caller, caught
    # at the boundary, and its text (recorded by the worker's hook) is the detail alone.
    for _ in range(3):
        with pytest.raises(bidegree.InternalError, match="a bug in bidegree") as caught:
            bidegree._native._panic_for_tests(in_worker=True)
        assert "deliberate panic" not in str(caught.value)
        assert "deliberate panic for tests on a worker" in caught.value.detail
        assert "errors.rs" in caught.value.detail
    assert bidegree.subdivide(cube(), degree=3, levels=1).num_faces == 24


# ---------------------------------------------------------------------------------------------
# dtypes, layouts, re-evaluation


@pytest.mark.parametrize(
    ("given", "expected"),
    [(np.float32, np.float32), (np.float64, np.float64), (np.int32, np.float64)],
)
def test_dtype_is_kept(given: type, expected: type) -> None:
    mesh = cube(given)
    assert mesh.points.dtype == expected
    result = bidegree.subdivide(mesh, degree=3, levels=2)
    assert result.points.dtype == expected
    plan = result.plan
    assert plan.evaluate(CUBE_POINTS.astype(np.float32)).dtype == np.float32
    assert plan.evaluate(CUBE_POINTS.astype(np.float64)).dtype == np.float64
    assert plan.evaluate(CUBE_POINTS.astype(np.int64)).dtype == np.float64
    assert result.face_sizes.dtype == np.int32
    assert result.face_indices.dtype == np.int32
    assert result.face_origin.dtype == np.int32
    assert result.edges.dtype == np.int32
    assert result.corner_edges.dtype == np.int32


def test_float32_and_float64_agree() -> None:
    points, sizes, indices = mixed_cage()
    r64 = bidegree.subdivide(bidegree.Mesh(points, face_sizes=sizes, face_indices=indices))
    r32 = bidegree.subdivide(
        bidegree.Mesh(points.astype(np.float32), face_sizes=sizes, face_indices=indices)
    )
    np.testing.assert_allclose(r32.points, r64.points, rtol=0, atol=1e-5)


def test_fortran_order_gives_the_same_result() -> None:
    points, sizes, indices = mixed_cage()
    fortran = np.asfortranarray(points)
    assert not fortran.flags.c_contiguous
    c_result = bidegree.subdivide(bidegree.Mesh(points, face_sizes=sizes, face_indices=indices))
    f_result = bidegree.subdivide(bidegree.Mesh(fortran, face_sizes=sizes, face_indices=indices))
    np.testing.assert_array_equal(c_result.points, f_result.points)

    plan = c_result.plan
    attribute = np.random.default_rng(2).normal(size=(len(points), 5))
    np.testing.assert_array_equal(
        plan.evaluate(attribute), plan.evaluate(np.asfortranarray(attribute))
    )
    # Strided views and foreign byte order are read correctly too.
    wide = np.zeros((len(points), 6))
    wide[:, ::2] = points
    np.testing.assert_array_equal(plan.evaluate(wide[:, ::2]), c_result.points)
    np.testing.assert_array_equal(plan.evaluate(points.astype(">f8")), c_result.points)


def test_native_layer_refuses_fortran_arrays_itself() -> None:
    # numpy's as_slice() would accept a Fortran array and read it transposed: the extension
    # checks C order itself (the package always converts before calling it).
    plan = bidegree.Plan(cube())
    native = plan._native_plan
    with pytest.raises(bidegree.InvalidInputError, match="C-contiguous"):
        native.evaluate(np.asfortranarray(CUBE_POINTS))
    with pytest.raises(bidegree.InvalidInputError):
        native.evaluate(CUBE_POINTS.astype(np.float16))
    np.testing.assert_array_equal(native.evaluate(CUBE_POINTS), plan.evaluate(CUBE_POINTS))


def test_plan_evaluate_equals_subdivide_bitwise() -> None:
    points, sizes, indices = mixed_cage()
    mesh = bidegree.Mesh(points, face_sizes=sizes, face_indices=indices)
    for dtype in (np.float32, np.float64):
        plan = bidegree.Plan(mesh, degree=5, levels=2)
        moved = (points + np.random.default_rng(3).normal(0, 0.1, points.shape)).astype(dtype)
        fresh = bidegree.subdivide(
            bidegree.Mesh(moved, face_sizes=sizes, face_indices=indices),
            degree=5,
            levels=2,
        )
        cached = plan.evaluate(moved)
        assert cached.dtype == fresh.points.dtype == dtype
        np.testing.assert_array_equal(cached, fresh.points)
        np.testing.assert_array_equal(plan.result(moved).points, fresh.points)
        np.testing.assert_array_equal(fresh.face_indices, plan.face_indices)


def test_evaluate_five_channel_attribute() -> None:
    points, sizes, indices = mixed_cage()
    mesh = bidegree.Mesh(points, face_sizes=sizes, face_indices=indices)
    plan = bidegree.Plan(mesh, degree=4, levels=2)
    rng = np.random.default_rng(4)
    attribute = np.hstack([points, rng.normal(size=(len(points), 2))])
    out = plan.evaluate(attribute)
    assert out.shape == (plan.num_output_vertices, 5)
    # Channels are independent: the first three are the positions, each channel alone agrees.
    np.testing.assert_allclose(out[:, :3], plan.evaluate(points), rtol=0, atol=1e-12)
    for channel in range(5):
        single = plan.evaluate(attribute[:, channel])
        assert single.shape == (plan.num_output_vertices,)
        np.testing.assert_allclose(out[:, channel], single, rtol=0, atol=1e-12)
    # A constant attribute stays constant (averaging).
    ones = plan.evaluate(np.ones((len(points), 2), dtype=np.float32))
    np.testing.assert_allclose(ones, 1.0, rtol=1e-6)


def test_face_varying_uvs() -> None:
    points, sizes, indices = mixed_cage()
    corners = len(indices)
    uvs = np.random.default_rng(5).uniform(size=(corners, 2)).astype(np.float32)
    mesh = bidegree.Mesh(points, face_sizes=sizes, face_indices=indices, uvs=uvs)
    result = bidegree.subdivide(mesh, degree=3, levels=2)
    assert result.uvs is not None
    assert result.uvs.shape == (len(result.face_indices), 2)
    assert result.uvs.dtype == np.float32
    # Linear interpolation inside each cage face: output uvs stay in the face's uv range.
    origin = np.repeat(result.face_origin, result.face_sizes)
    offsets = np.concatenate([[0], np.cumsum(sizes)])
    for face in range(len(sizes)):
        face_uvs = uvs[offsets[face] : offsets[face + 1]]
        inside = result.uvs[origin == face]
        assert len(inside) > 0
        assert np.all(inside >= face_uvs.min(axis=0) - 1e-6)
        assert np.all(inside <= face_uvs.max(axis=0) + 1e-6)
    # Without cage uvs there are none; evaluate_face_varying works on any corner attribute.
    plain = bidegree.subdivide(bidegree.Mesh(points, face_sizes=sizes, face_indices=indices))
    assert plain.uvs is None
    values = result.plan.evaluate_face_varying(np.ones((corners, 3)))
    assert values.shape == (len(result.face_indices), 3)
    np.testing.assert_allclose(values, 1.0)


def test_callers_arrays_are_never_modified() -> None:
    points, sizes, indices = mixed_cage()
    uvs = np.random.default_rng(6).uniform(size=(len(indices), 2))
    creases = (np.array([[0, 1], [1, 2]]), np.array([2.0, 10.0]))
    corners = (np.array([6]), np.array([3.0]))
    arrays = [points, sizes, indices, uvs, *creases, *corners]
    copies = [a.copy() for a in arrays]
    flags = [a.flags.writeable for a in arrays]

    mesh = bidegree.Mesh(
        points,
        face_sizes=sizes,
        face_indices=indices,
        uvs=uvs,
        creases=creases,
        corners=corners,
    )
    result = bidegree.subdivide(mesh, degree=3, levels=2)
    plan = result.plan
    plan.evaluate(points)
    plan.evaluate(np.asfortranarray(points))
    plan.evaluate_face_varying(uvs)
    result.points += 1.0  # the result is the caller's own memory, not the cage's
    with pytest.raises(bidegree.DegreeOutOfRangeError):
        bidegree.subdivide(mesh, degree=0)
    bad_indices = indices.copy()
    bad_indices[2] = 99
    bad_copy = bad_indices.copy()
    with pytest.raises(bidegree.IndexOutOfRangeError):
        bidegree.Mesh(points, face_sizes=sizes, face_indices=bad_indices)
    np.testing.assert_array_equal(bad_indices, bad_copy)

    for array, copy, flag in zip(arrays, copies, flags, strict=True):
        np.testing.assert_array_equal(array, copy)
        assert array.flags.writeable == flag
    # Mesh keeps its own read-only copies: later changes by the caller do not leak in.
    points[0] = 100.0
    assert mesh.points[0, 0] != 100.0
    assert not mesh.points.flags.writeable
    assert not result.face_indices.flags.writeable
    with pytest.raises(ValueError):
        mesh.points[0, 0] = 1.0


# ---------------------------------------------------------------------------------------------
# Counts that follow from the topology


def test_one_level_gives_one_quad_per_face_corner() -> None:
    points, sizes, indices = mixed_cage()
    mesh = bidegree.Mesh(points, face_sizes=sizes, face_indices=indices)
    for degree in (1, 2, 3, 4, 7):
        result = bidegree.subdivide(mesh, degree=degree, levels=1)
        assert result.num_faces == len(indices)
        assert np.all(result.face_sizes == 4)
        assert len(result.face_indices) == 4 * len(indices)
        # Each cage face gives as many quads as it has corners.
        np.testing.assert_array_equal(np.bincount(result.face_origin), sizes)


@pytest.mark.parametrize("levels", [1, 2, 3, 4])
def test_levels_multiply_faces_by_four(levels: int) -> None:
    points, sizes, indices = mixed_cage()
    mesh = bidegree.Mesh(points, face_sizes=sizes, face_indices=indices)
    corners = len(indices)
    result = bidegree.subdivide(mesh, degree=3, levels=levels)
    assert result.num_faces == corners * 4 ** (levels - 1)
    assert len(result.face_sizes) == result.num_faces
    assert bidegree.estimate(mesh, 3, levels)["faces"] == result.num_faces
    assert result.plan.num_output_vertices == len(result.points)
    assert result.face_indices.max() < len(result.points)


def test_edges_and_corner_edges_are_consistent() -> None:
    result = bidegree.subdivide(cube(), degree=4, levels=2)
    v, f, e = len(result.points), result.num_faces, len(result.edges)
    assert v - e + f == 2  # a closed genus-0 surface
    assert result.edges.shape == (e, 2)
    corner_edges = result.corner_edges
    assert corner_edges.shape == result.face_indices.shape
    # Corner c's edge joins its vertex and the next corner's vertex of the same face.
    starts = np.repeat(np.cumsum(result.face_sizes) - result.face_sizes, result.face_sizes)
    position = np.arange(len(result.face_indices)) - starts
    size = np.repeat(result.face_sizes, result.face_sizes)
    following = result.face_indices[starts + (position + 1) % size]
    ends = np.sort(result.edges[corner_edges], axis=1)
    expected = np.sort(np.stack([result.face_indices, following], axis=1), axis=1)
    np.testing.assert_array_equal(ends, expected)
    # Every edge of a closed mesh is used by exactly two corners.
    np.testing.assert_array_equal(np.bincount(corner_edges, minlength=e), 2)


def test_dual_output_and_result_properties() -> None:
    mesh = cube()
    result = bidegree.subdivide(mesh, degree=3, levels=2, output="dual")
    assert result.output == "dual"
    assert (result.degree, result.levels, result.boundary) == (3, 2, "edge-only")
    assert len(result.face_sizes) == result.num_faces
    assert int(result.face_sizes.sum()) == len(result.face_indices)
    assert "Result(" in repr(result) and "Plan(" in repr(result.plan) and "Mesh(" in repr(mesh)


def test_faces_given_as_arrays_and_creases_corners_boundary() -> None:
    quads = np.array(CUBE_FACES, dtype=np.int32)
    a = bidegree.Mesh(CUBE_POINTS, quads)
    b = bidegree.Mesh(CUBE_POINTS, face_sizes=np.full(6, 4), face_indices=quads.reshape(-1))
    np.testing.assert_array_equal(a.face_indices, b.face_indices)
    np.testing.assert_array_equal(bidegree.subdivide(a).points, bidegree.subdivide(b).points)
    creased = cube(creases=([[0, 1], [1, 2]], 10.0), corners=([6], [np.inf]))
    assert creased.creases is not None and creased.creases[1].dtype == np.float32
    np.testing.assert_array_equal(creased.creases[1], [10.0, 10.0])
    assert bidegree.subdivide(creased, degree=3, levels=2).num_faces == 96
    edge_and_corner = cube(boundary="edge-and-corner")
    assert bidegree.Plan(edge_and_corner).boundary == "edge-and-corner"


def test_obj_round_trip(tmp_path: Path) -> None:
    points, sizes, indices = mixed_cage()
    uvs = np.random.default_rng(7).uniform(size=(len(indices), 2))
    mesh = bidegree.Mesh(points, face_sizes=sizes, face_indices=indices, uvs=uvs)
    result = bidegree.subdivide(mesh, degree=3, levels=2)
    path = tmp_path / "out.obj"
    result.write_obj(path)
    back = bidegree.Mesh.from_obj(path)
    np.testing.assert_array_equal(back.points, result.points)  # shortest exact decimal form
    np.testing.assert_array_equal(back.face_sizes, result.face_sizes)
    np.testing.assert_array_equal(back.face_indices, result.face_indices)
    assert back.uvs is not None
    np.testing.assert_array_equal(back.uvs, result.uvs)
    mesh.write_obj(tmp_path / "cage.obj")
    cage = bidegree.Mesh.from_obj(tmp_path / "cage.obj")
    np.testing.assert_array_equal(cage.points, points)
    np.testing.assert_array_equal(cage.uvs, uvs)


def test_threads_share_a_plan() -> None:
    points, sizes, indices = mixed_cage()
    plan = bidegree.Plan(bidegree.Mesh(points, face_sizes=sizes, face_indices=indices), 6, 3)
    expected = plan.evaluate(points)
    outputs: list[np.ndarray] = []

    def work() -> None:
        for _ in range(5):
            outputs.append(plan.evaluate(points))

    threads = [threading.Thread(target=work) for _ in range(4)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    assert len(outputs) == 20
    for out in outputs:
        np.testing.assert_array_equal(out, expected)


def test_gil_is_released_during_evaluation() -> None:
    from bidegree.bench import make_cage

    mesh = make_cage(600)
    plan = bidegree.Plan(mesh, degree=9, levels=4)
    started, finished = threading.Event(), threading.Event()
    seconds: list[float] = []

    def work() -> None:
        started.set()
        start = time.perf_counter()
        plan.evaluate(mesh.points)
        seconds.append(time.perf_counter() - start)
        finished.set()

    # A long switch interval: the interpreter itself never takes the GIL from the worker, so this
    # thread only runs during the evaluation if the extension releases the GIL (a GIL-holding C
    # call, e.g. a catastrophic regex, gives 0 spins here).
    interval = sys.getswitchinterval()
    sys.setswitchinterval(0.25)
    try:
        thread = threading.Thread(target=work)
        thread.start()
        started.wait()
        spins = 0
        while not finished.is_set():
            spins += 1
        thread.join()
    finally:
        sys.setswitchinterval(interval)
    assert seconds[0] > 0.01
    assert spins > 1000, spins
