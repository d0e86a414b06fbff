"""Limit positions and normals through the Python API, the CLI and USD (issue 6)."""

from __future__ import annotations

from pathlib import Path

import bidegree
import numpy as np
import pytest
from cages import cube, torus
from test_cli import run_here


def bspline(n: int, t: np.ndarray) -> np.ndarray:
    """The centred cardinal B-spline of degree n at t (Cox-de Boor, vectorised)."""
    x = np.asarray(t, dtype=np.float64) + (n + 1) / 2
    values = [((x - i >= 0) & (x - i < 1)).astype(np.float64) for i in range(n + 1)]
    for d in range(1, n + 1):
        for i in range(n + 1 - d):
            y = x - i
            values[i] = (y * values[i] + (d + 1 - y) * values[i + 1]) / d
    return values[0]


@pytest.mark.parametrize("degree", [2, 3, 4, 7])
def test_torus_limit_is_the_tensor_bspline_of_the_cage(degree: int) -> None:
    n, m = 12, 8
    mesh = torus(n, m)
    limit = bidegree.Plan(mesh, degree=degree, levels=1).limit_positions()
    offsets = np.arange(-8, 9)
    w = bspline(degree, offsets.astype(np.float64))
    grid = mesh.points.reshape(n, m, 3)
    for i in range(n):
        for j in range(m):
            rows = (i + offsets) % n
            cols = (j + offsets) % m
            expected = np.einsum("a,b,abk->k", w, w, grid[np.ix_(rows, cols)])
            np.testing.assert_allclose(limit[i * m + j], expected, rtol=0, atol=1e-12)


@pytest.mark.parametrize("degree", [2, 3, 4, 5, 9])
def test_subdivide_limit_and_normals(degree: int) -> None:
    mesh = cube()
    result = bidegree.subdivide(mesh, degree=degree, levels=2, limit=True, normals=True)
    plan = result.plan
    np.testing.assert_array_equal(result.points, plan.limit_positions())
    assert result.normals is not None
    assert result.normals.shape == (len(result.face_indices), 3)
    np.testing.assert_allclose(np.linalg.norm(result.normals, axis=1), 1.0, atol=1e-12)
    # Outward on the cube: the normal points away from its centre.
    at = result.points[result.face_indices] - 0.5
    assert (np.einsum("ij,ij->i", at, result.normals) > 0).all()
    # The limit at a vertex does not depend on the level it is asked at.
    coarse = bidegree.Plan(mesh, degree=degree, levels=1).limit_positions()
    np.testing.assert_allclose(result.points[: len(coarse)], coarse, rtol=0, atol=1e-12)
    # The limit lies off the refined points, which normals=True alone keeps; except at degree
    # 2, whose drawing points (centroids of a vertex's k dual points) are exactly its limits.
    refined = bidegree.subdivide(mesh, degree=degree, levels=2, normals=True)
    gap = np.abs(refined.points - result.points).max()
    assert gap < 1e-12 if degree == 2 else gap > 1e-4
    np.testing.assert_array_equal(refined.normals, result.normals)


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_release_buffers_changes_no_result(dtype: type) -> None:
    """A plan's kept working arrays, freed between calls, change no bit of what it gives."""
    mesh = cube(dtype)
    plan = bidegree.Plan(mesh, degree=4, levels=3)
    moved = (mesh.points * 1.5 + 0.25).astype(dtype)
    first = [plan.evaluate(mesh.points), *plan.limit_surface()]
    plan.release_buffers()
    other = [plan.evaluate(moved), *plan.limit_surface(moved)]
    plan.release_buffers()
    again = [plan.evaluate(mesh.points), *plan.limit_surface()]
    plan.release_buffers()
    plan.release_buffers()
    for a, b in zip(first, again, strict=True):
        assert a.dtype == dtype
        np.testing.assert_array_equal(a, b)
    assert all(np.abs(a - b).max() > 0.1 for a, b in zip(first[:2], other[:2], strict=True))


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_vertex_normals_put_the_corners_together(dtype: type) -> None:
    """normals="vertex": the same positions and one normal per output vertex, its corners'
    bit for bit where they agree (every vertex of the smooth cube at degree 4), else the unit
    vector along their sum (degree 1: each face's bilinear normal at its corners)."""
    tolerance = 1e-6 if dtype == np.float32 else 1e-12
    for degree in (1, 4):
        plan = bidegree.Plan(cube(dtype), degree=degree, levels=2)
        positions, at_corners = plan.limit_surface()
        same, at_vertices = plan.limit_surface(normals="vertex")
        np.testing.assert_array_equal(same, positions)
        assert at_vertices.shape == positions.shape and at_vertices.dtype == dtype
        corners = plan.face_indices
        agree = np.ones(len(positions), dtype=bool)
        np.logical_and.at(agree, corners, (at_corners == at_vertices[corners]).all(axis=1))
        sums = np.zeros((len(positions), 3))
        np.add.at(sums, corners, at_corners.astype(np.float64))
        unit = sums / np.linalg.norm(sums, axis=1)[:, None]
        split = ~agree
        np.testing.assert_allclose(at_vertices[split], unit[split], rtol=0, atol=tolerance)
        assert split.any() if degree == 1 else not split.any()
        assert plan.limit_normals_split == (degree == 1)  # known without the points
    with pytest.raises(bidegree.InvalidInputError, match="normals"):
        plan.limit_surface(normals="face")  # type: ignore[arg-type]


def test_limit_refusals() -> None:
    mesh = cube()
    with pytest.raises(bidegree.InvalidInputError, match="primal"):
        bidegree.subdivide(mesh, degree=4, levels=1, output="dual", limit=True)
    with pytest.raises(bidegree.InvalidInputError, match="classic"):
        bidegree.subdivide(mesh, degree=3, levels=1, rules="classic", normals=True)
    with pytest.raises(bidegree.InvalidInputError):
        bidegree.Plan(mesh, degree=4, levels=1).limit_surface(np.zeros((8, 2)))
    assert bidegree.Plan(mesh, degree=4, levels=1).limit_extra_levels >= 1
    assert bidegree.Plan(torus(), degree=4, levels=1).limit_extra_levels == 0
    with pytest.raises(bidegree.InvalidInputError, match="classic"):
        _ = bidegree.Plan(mesh, degree=3, levels=1, rules="classic").limit_normals_split


def test_subdivide_to_the_limit_still_validates_the_geometry() -> None:
    # With limit=True the plain refinement is skipped, not the checks of the points.
    bad = cube().points.copy()
    bad[3, 2] = np.nan
    mesh = bidegree.Mesh(bad, face_sizes=cube().face_sizes, face_indices=cube().face_indices)
    for normals in (False, True):
        with pytest.raises(bidegree.NonFiniteError) as info:
            bidegree.subdivide(mesh, degree=4, levels=1, limit=True, normals=normals)
        assert info.value.vertex == 3


def test_usd_carries_limit_normals(tmp_path: Path) -> None:
    """Per point where every point's corners agree (the smooth cube), per corner at a sharp
    crease; either way each corner's normal is the limit's."""
    pxr = pytest.importorskip("pxr")
    from bidegree import usd

    smooth = cube()
    sharp = bidegree.Mesh(
        smooth.points,
        face_sizes=smooth.face_sizes,
        face_indices=smooth.face_indices,
        creases=(np.array([smooth.face_indices[:2]]), np.array([10.0], dtype=np.float32)),
    )
    for mesh, interpolation in ((smooth, "vertex"), (sharp, "faceVarying")):
        result = bidegree.subdivide(mesh, degree=4, levels=2, limit=True, normals=True)
        path = tmp_path / f"limit-{interpolation}.usda"
        usd.export(path, mesh, result)
        assert usd.validate(path) == []
        stage = pxr.Usd.Stage.Open(str(path))
        prim = pxr.UsdGeom.Mesh(stage.GetPrimAtPath("/Bidegree/Result"))
        assert prim.GetNormalsInterpolation() == interpolation
        normals = np.array(prim.GetNormalsAttr().Get())
        if interpolation == "vertex":
            normals = normals[np.array(prim.GetFaceVertexIndicesAttr().Get())]
        np.testing.assert_allclose(normals, result.normals, rtol=0, atol=1e-6)


def test_cli_limit_and_normals(tmp_path: Path) -> None:
    cage = tmp_path / "cube.obj"
    lines = [f"v {x} {y} {z}" for x, y, z in cube().points]
    lines += ["f " + " ".join(str(v + 1) for v in f) for f in cube().face_indices.reshape(-1, 4)]
    cage.write_text("\n".join(lines) + "\n")
    out = tmp_path / "cube.usda"
    proc = run_here("subdivide", cage, "-o", out, "--limit", "--normals", "--levels", "1")
    assert proc.returncode == 0, proc.stderr
    assert "limit positions, limit normals" in proc.stdout
    assert out.exists()
    obj = tmp_path / "out.obj"
    proc = run_here("subdivide", cage, "-o", obj, "--normals", "--levels", "1")
    assert proc.returncode == 0, proc.stderr
    text = obj.read_text()
    expected = bidegree.subdivide(cube(), degree=4, levels=1, normals=True)
    assert text.count("\nvn ") == len(expected.face_indices)
    assert "//" in text.split("\nf ", 1)[1]
