"""USD export (bidegree.usd) with the real usd-core: round trips, validation, bad input."""

from __future__ import annotations

import os
import time
from pathlib import Path
from types import SimpleNamespace

import bidegree
import cages
import numpy as np
import pytest
from bidegree import usd
from pxr import Sdf, Usd, UsdGeom


def pentagonal_cage(boundary: str = "edge-and-corner") -> bidegree.Mesh:
    """An open pentagonal prism: pentagon bottom (n-gon), top split into a triangle and a quad,
    four of the five side quads (one missing: a boundary loop), creases, corners and UVs."""
    angles = 2 * np.pi * np.arange(5) / 5
    ring = np.stack([np.cos(angles), np.zeros(5), np.sin(angles)], axis=1)
    top = ring + np.array([0.0, 1.5, 0.0])
    points = np.concatenate([ring, top])  # 0..4 bottom, 5..9 top
    faces = [
        [0, 1, 2, 3, 4][::-1],  # bottom pentagon, facing down
        [5, 6, 7],  # top triangle
        [5, 7, 8, 9],  # top quad
        [0, 1, 6, 5],
        [1, 2, 7, 6],
        [2, 3, 8, 7],
        [3, 4, 9, 8],
        # side (4, 0, 5, 9) missing: boundary 4-0-5-9
    ]
    nc = sum(len(f) for f in faces)
    rng = np.random.default_rng(7)
    return bidegree.Mesh(
        points,
        faces,
        creases=(np.array([[5, 6], [6, 7], [1, 2]]), np.array([np.inf, 2.5, 0.75])),
        corners=(np.array([3, 8]), np.array([10.0, 1.25])),
        uvs=rng.random((nc, 2)),
        boundary=boundary,
    )


@pytest.fixture(scope="module")
def cage() -> bidegree.Mesh:
    return pentagonal_cage()


@pytest.fixture(scope="module")
def result(cage: bidegree.Mesh) -> bidegree.Result:
    return bidegree.subdivide(cage, degree=3, levels=2)


def _attr(prim: Usd.Prim, name: str) -> object:
    attr = prim.GetAttribute(name)
    assert attr.IsValid(), f"{prim.GetPath()} has no attribute {name}"
    return attr.Get()


def _np(value: object) -> np.ndarray:
    return np.asarray(value)


def _file_numbers(file_indices: np.ndarray, result_indices: np.ndarray, points: int) -> np.ndarray:
    """The file's number of each result point (every one used by a face), checking that the
    file's faces are the result's faces, in the same order, up to a renumbering of the points."""
    assert file_indices.shape == result_indices.shape
    numbers = np.full(points, -1, dtype=np.int64)
    numbers[result_indices] = file_indices
    np.testing.assert_array_equal(numbers[result_indices], file_indices)
    np.testing.assert_array_equal(np.sort(numbers), np.arange(points))
    return numbers


def _first_use_order(face_indices: np.ndarray) -> bool:
    """Whether each point number first appears in ``face_indices`` as one more than the largest
    before it (the points numbered by their first use)."""
    before = np.concatenate([[-1], np.maximum.accumulate(face_indices)[:-1]])
    return bool(np.all(face_indices <= before + 1))


@pytest.mark.parametrize("point_order", usd.POINT_ORDERS)
@pytest.mark.parametrize("ext", [".usda", ".usdc", ".usd"])
def test_round_trip_every_attribute(
    tmp_path: Path, cage: bidegree.Mesh, result: bidegree.Result, ext: str, point_order: str
) -> None:
    path = tmp_path / f"surface{ext}"
    distances = np.linspace(0.0, 1.0, len(result.points))
    usd.export(
        path,
        cage,
        result,
        up_axis="Z",
        meters_per_unit=0.01,
        distances=distances,
        point_order=point_order,
    )

    head = path.read_bytes()[:8]
    assert head == (b"#usda 1." if ext == ".usda" else b"PXR-USDC")
    stage = Usd.Stage.Open(str(path))
    assert UsdGeom.GetStageUpAxis(stage) == UsdGeom.Tokens.z
    assert UsdGeom.GetStageMetersPerUnit(stage) == pytest.approx(0.01)
    root = stage.GetDefaultPrim()
    assert root.GetPath() == Sdf.Path("/Bidegree") and root.GetTypeName() == "Xform"

    # ---- cage: Catmull-Clark mesh of the same control points
    cprim = stage.GetPrimAtPath("/Bidegree/Cage")
    cmesh = UsdGeom.Mesh(cprim)
    assert cprim.GetTypeName() == "Mesh"
    assert cmesh.GetSubdivisionSchemeAttr().Get() == UsdGeom.Tokens.catmullClark
    assert cmesh.GetInterpolateBoundaryAttr().Get() == UsdGeom.Tokens.edgeAndCorner
    assert cmesh.GetFaceVaryingLinearInterpolationAttr().Get() == UsdGeom.Tokens.boundaries
    assert cmesh.GetOrientationAttr().Get() == UsdGeom.Tokens.rightHanded
    np.testing.assert_allclose(_np(cmesh.GetPointsAttr().Get()), cage.points, rtol=0, atol=1e-6)
    np.testing.assert_array_equal(_np(cmesh.GetFaceVertexCountsAttr().Get()), cage.face_sizes)
    np.testing.assert_array_equal(_np(cmesh.GetFaceVertexIndicesAttr().Get()), cage.face_indices)
    edges = cage.creases[0]
    np.testing.assert_array_equal(_np(cmesh.GetCreaseIndicesAttr().Get()), edges.reshape(-1))
    np.testing.assert_array_equal(_np(cmesh.GetCreaseLengthsAttr().Get()), [2, 2, 2])
    # inf is written as 10 (OpenSubdiv's "infinitely sharp"), finite values unchanged
    np.testing.assert_allclose(_np(cmesh.GetCreaseSharpnessesAttr().Get()), [10.0, 2.5, 0.75])
    np.testing.assert_array_equal(_np(cmesh.GetCornerIndicesAttr().Get()), [3, 8])
    np.testing.assert_allclose(_np(cmesh.GetCornerSharpnessesAttr().Get()), [10.0, 1.25])
    cst = UsdGeom.PrimvarsAPI(cprim).GetPrimvar("st")
    assert cst.GetTypeName() == Sdf.ValueTypeNames.TexCoord2fArray
    assert cst.GetInterpolation() == UsdGeom.Tokens.faceVarying
    # Indexed by the face-varying topology subdivided (here the weld by value).
    assert cst.IsIndexed()
    np.testing.assert_allclose(_np(cst.ComputeFlattened()), cage.uvs, atol=1e-6)
    cext = _np(cmesh.GetExtentAttr().Get())
    np.testing.assert_allclose(cext, [cage.points.min(0), cage.points.max(0)], atol=1e-6)

    # ---- result: plain polygons with normals, UVs, distances, extent and bidegree metadata
    rprim = stage.GetPrimAtPath("/Bidegree/Result")
    rmesh = UsdGeom.Mesh(rprim)
    assert rmesh.GetSubdivisionSchemeAttr().Get() == UsdGeom.Tokens.none
    # The same faces in the same order; the points renumbered by their first use in them
    # (point_order="first-use") or in the result's order. ``at`` reads per-vertex values of the
    # file in the result's order.
    file_indices = _np(rmesh.GetFaceVertexIndicesAttr().Get())
    at = _file_numbers(file_indices, result.face_indices, len(result.points))
    if point_order == "result":
        np.testing.assert_array_equal(file_indices, result.face_indices)
    else:
        assert _first_use_order(file_indices) and not _first_use_order(result.face_indices)
    pts = _np(rmesh.GetPointsAttr().Get())[at]
    np.testing.assert_allclose(pts, result.points, atol=1e-6)
    np.testing.assert_array_equal(_np(rmesh.GetFaceVertexCountsAttr().Get()), result.face_sizes)
    normals = _np(rmesh.GetNormalsAttr().Get())[at]
    assert rmesh.GetNormalsInterpolation() == UsdGeom.Tokens.vertex
    assert normals.shape == pts.shape
    np.testing.assert_allclose(np.linalg.norm(normals, axis=1), 1.0, atol=1e-5)
    np.testing.assert_allclose(
        normals,
        usd.vertex_normals(result.points, result.face_sizes, result.face_indices),
    )
    st = UsdGeom.PrimvarsAPI(rprim).GetPrimvar("st")
    assert st.GetInterpolation() == UsdGeom.Tokens.faceVarying
    assert st.GetTypeName() == Sdf.ValueTypeNames.TexCoord2fArray
    assert st.IsIndexed()  # the result's indexed form
    np.testing.assert_array_equal(_np(st.GetIndices()), result.uv_indices)
    np.testing.assert_allclose(_np(st.ComputeFlattened()), result.uvs, atol=1e-6)
    dist = UsdGeom.PrimvarsAPI(rprim).GetPrimvar("distance")
    assert dist.GetInterpolation() == UsdGeom.Tokens.vertex
    np.testing.assert_allclose(_np(dist.Get())[at], distances, atol=1e-7)
    color = UsdGeom.PrimvarsAPI(rprim).GetPrimvar("displayColor")
    assert color.GetInterpolation() == UsdGeom.Tokens.vertex
    colors = _np(color.Get())[at]
    np.testing.assert_allclose(colors, usd.distance_colors(distances))
    np.testing.assert_allclose(colors[0], [0.05, 0.03, 0.25], atol=1e-6)  # distance 0
    np.testing.assert_allclose(colors[-1], [1.0, 1.0, 0.6], atol=1e-6)  # the largest
    assert np.all(np.diff(colors.sum(axis=1)) >= -1e-6)  # brighter with distance
    ext_r = _np(rmesh.GetExtentAttr().Get())
    np.testing.assert_allclose(ext_r, [pts.min(0), pts.max(0)])
    assert _attr(rprim, "bidegree:degree") == 3
    assert _attr(rprim, "bidegree:levels") == 2
    assert _attr(rprim, "bidegree:output") == "primal"
    assert _attr(rprim, "bidegree:boundary") == "edge-and-corner"
    assert _attr(rprim, "bidegree:version") == bidegree.__version__
    assert rprim.GetAttribute("bidegree:degree").IsCustom()

    assert usd.validate(path) == []


def test_edge_only_without_uvs_creases_or_distances(tmp_path: Path) -> None:
    """A closed quad cube, edge-only, nothing optional: no optional attribute is authored."""
    cube = cages.cube(np.float32)
    res = bidegree.subdivide(cube, degree=4, levels=1)
    path = tmp_path / "cube.usda"
    usd.export(path, cube, res)
    stage = Usd.Stage.Open(str(path))
    assert UsdGeom.GetStageUpAxis(stage) == UsdGeom.Tokens.y
    assert UsdGeom.GetStageMetersPerUnit(stage) == 1.0
    cprim = stage.GetPrimAtPath("/Bidegree/Cage")
    assert UsdGeom.Mesh(cprim).GetInterpolateBoundaryAttr().Get() == UsdGeom.Tokens.edgeOnly
    for name in ("creaseIndices", "cornerIndices", "primvars:st"):
        assert not cprim.GetAttribute(name).HasAuthoredValue()
    rprim = stage.GetPrimAtPath("/Bidegree/Result")
    assert not rprim.GetAttribute("primvars:st").HasAuthoredValue()
    assert not rprim.GetAttribute("primvars:distance").HasAuthoredValue()
    assert not rprim.GetAttribute("primvars:displayColor").HasAuthoredValue()
    assert rprim.GetAttribute("bidegree:degree").Get() == 4
    assert rprim.GetAttribute("bidegree:boundary").Get() == "edge-only"
    assert usd.validate(path) == []
    # normals point outwards on the (convex) result
    pts = np.asarray(UsdGeom.Mesh(rprim).GetPointsAttr().Get())
    normals = np.asarray(UsdGeom.Mesh(rprim).GetNormalsAttr().Get())
    outward = np.einsum("ij,ij->i", normals, pts - pts.mean(0))
    assert np.all(outward > 0)


def test_first_use_order_describes_the_same_surface(tmp_path: Path) -> None:
    """The default point order (first use in the faces) writes the result's surface: the same
    faces as point tuples, the same per-vertex values at each point, the face-varying values
    (limit normals, UVs) per corner unchanged; points no face uses are kept, last, in their
    order; the extra meshes are re-ordered the same way; the file validates."""
    rng = np.random.default_rng(3)
    mesh = cages.cube(uvs=rng.random((24, 2)))
    result = bidegree.subdivide(mesh, degree=4, levels=3, limit=True, normals=True)
    n = len(result.points)
    # Two points no face uses: one inserted at 5, one at the end.
    points = np.insert(result.points, 5, [9.0, 9.0, 9.0], axis=0)
    points = np.vstack([points, [[-9.0, -9.0, -9.0]]])
    indices = result.face_indices + (result.face_indices >= 5)
    like = _result_like(result, points=points, face_indices=indices, normals=result.normals)
    distances = rng.random(n + 2)
    path = tmp_path / "ordered.usdc"
    usd.export(path, mesh, like, distances=distances, extra_meshes={"Again": (like, 2 * distances)})
    assert usd.validate(path) == []

    stage = Usd.Stage.Open(str(path))
    for name, dist in (("Result", distances), ("Again", 2 * distances)):
        prim = stage.GetPrimAtPath(f"/Bidegree/{name}")
        written = UsdGeom.Mesh(prim)
        file_indices = _np(written.GetFaceVertexIndicesAttr().Get())
        assert _first_use_order(file_indices) and not np.array_equal(file_indices, indices)
        np.testing.assert_array_equal(_np(written.GetFaceVertexCountsAttr().Get()), like.face_sizes)
        pts = _np(written.GetPointsAttr().Get())
        np.testing.assert_allclose(pts[file_indices], points[indices], rtol=0, atol=1e-6)
        primvars = UsdGeom.PrimvarsAPI(prim)
        file_dist = _np(primvars.GetPrimvar("distance").Get())
        np.testing.assert_allclose(file_dist[file_indices], dist[indices], rtol=1e-6)
        colors = _np(primvars.GetPrimvar("displayColor").Get())
        np.testing.assert_allclose(colors[file_indices], usd.distance_colors(dist)[indices])
        np.testing.assert_array_equal(pts[-2:], [[9.0, 9.0, 9.0], [-9.0, -9.0, -9.0]])
        np.testing.assert_allclose(file_dist[-2:], dist[[5, n + 1]], rtol=1e-6)
        normals = _np(written.GetNormalsAttr().Get())
        if name == "Result":  # limit normals, one per point (the cube is smooth): as computed
            assert written.GetNormalsInterpolation() == UsdGeom.Tokens.vertex
            np.testing.assert_array_equal(normals[-2:], 0.0)  # used by no face
            np.testing.assert_allclose(normals[file_indices], result.normals, rtol=0, atol=1e-6)
            st = _np(primvars.GetPrimvar("st").Get())
            np.testing.assert_allclose(st, result.uvs, rtol=0, atol=1e-6)
        else:  # area-weighted vertex normals at each point
            assert written.GetNormalsInterpolation() == UsdGeom.Tokens.vertex
            expected = usd.vertex_normals(points, like.face_sizes, indices)
            np.testing.assert_array_equal(normals[file_indices], expected[indices])


def test_vertex_normals_are_area_weighted() -> None:
    # two triangles sharing vertex 0: a big one in the XY plane, a small one in the XZ plane
    points = np.array([[0, 0, 0], [4, 0, 0], [0, 4, 0], [0, 0, -1], [1, 0, 0]], dtype=float)
    sizes = np.array([3, 3])
    indices = np.array([0, 1, 2, 0, 4, 3])  # normals (0,0,1)*8 and (0,1,0)*0.5
    n = usd.vertex_normals(points, sizes, indices)
    expected = np.array([0, 0.5, 8.0]) / np.linalg.norm([0, 0.5, 8.0])
    np.testing.assert_allclose(n[0], expected, atol=1e-6)
    np.testing.assert_allclose(n[1], [0, 0, 1], atol=1e-6)
    np.testing.assert_allclose(n[3], [0, 1, 0], atol=1e-6)


def test_validate_reports_errors(tmp_path: Path) -> None:
    """The validation used by the tests can fail: a stage without metadata is rejected."""
    stage = Usd.Stage.CreateInMemory()
    UsdGeom.Xform.Define(stage, "/Root")
    path = tmp_path / "bare.usda"
    stage.GetRootLayer().Export(str(path))
    errors = usd.validate(path)
    assert any("upAxis" in e for e in errors)
    assert any("defaultPrim" in e for e in errors)


def test_overwrite_refreshes_open_layer(
    tmp_path: Path, cage: bidegree.Mesh, result: bidegree.Result
) -> None:
    path = tmp_path / "again.usdc"
    usd.export(path, cage, result, distances=np.zeros(len(result.points)))
    first = Usd.Stage.Open(str(path))  # keeps the layer open in the registry
    usd.export(path, cage, result, distances=np.ones(len(result.points)))
    again = Usd.Stage.Open(str(path))
    d = np.asarray(again.GetPrimAtPath("/Bidegree/Result").GetAttribute("primvars:distance").Get())
    assert np.all(d == 1.0)
    del first


def _leftovers(directory: Path) -> list[str]:
    return sorted(p.name for p in directory.iterdir())


def test_missing_directory(tmp_path: Path, cage: bidegree.Mesh, result: bidegree.Result) -> None:
    target = tmp_path / "no" / "such" / "dir" / "out.usda"
    with pytest.raises(bidegree.BidegreeIOError, match="does not exist"):
        usd.export(target, cage, result)
    assert not (tmp_path / "no").exists()


def test_unwritable_path(tmp_path: Path, cage: bidegree.Mesh, result: bidegree.Result) -> None:
    blocker = tmp_path / "file.txt"
    blocker.write_text("not a directory")
    with pytest.raises(bidegree.BidegreeIOError):
        usd.export(blocker / "out.usda", cage, result)
    (tmp_path / "dir.usda").mkdir()
    with pytest.raises(bidegree.BidegreeIOError, match="is a directory"):
        usd.export(tmp_path / "dir.usda", cage, result)
    assert _leftovers(tmp_path) == ["dir.usda", "file.txt"]


def test_unsupported_extension(
    tmp_path: Path, cage: bidegree.Mesh, result: bidegree.Result
) -> None:
    with pytest.raises(bidegree.InvalidInputError, match="extension"):
        usd.export(tmp_path / "out.obj", cage, result)
    assert _leftovers(tmp_path) == []


def _result_like(result: bidegree.Result, **changes: object) -> SimpleNamespace:
    fields = {
        name: getattr(result, name)
        for name in (
            "points",
            "face_sizes",
            "face_indices",
            "uvs",
            "degree",
            "levels",
            "output",
        )
    }
    fields["boundary"] = result.boundary
    fields.update(changes)
    return SimpleNamespace(**fields)


@pytest.mark.parametrize(
    ("change", "message"),
    [
        ({"distances": "short"}, "distances must have shape"),
        ({"uvs": "short"}, "face corners"),
        ({"points": "2d"}, r"shape \(N, 3\)"),
        ({"face_indices": "out of range"}, "out of range"),
        ({"face_sizes": "bad sum"}, "sum to"),
        ({"points": "nan"}, "NaN"),
        ({"up_axis": "X"}, "up_axis"),
        ({"meters_per_unit": 0.0}, "meters_per_unit"),
        ({"point_order": "random"}, "point_order"),
        ({"boundary": "edge-only"}, "boundary mode"),
    ],
)
def test_bad_input_keeps_existing_file(
    tmp_path: Path,
    cage: bidegree.Mesh,
    result: bidegree.Result,
    change: dict[str, object],
    message: str,
) -> None:
    target = tmp_path / "keep.usdc"
    target.write_bytes(b"previous content")
    kwargs: dict[str, object] = {}
    res: object = result
    ((key, value),) = change.items()
    if key == "distances":
        kwargs["distances"] = np.zeros(len(result.points) - 1)
    elif key == "uvs":
        res = _result_like(result, uvs=result.uvs[:-1])
    elif key == "points" and value == "2d":
        res = _result_like(result, points=result.points[:, :2])
    elif key == "points":
        bad = result.points.copy()
        bad[5, 1] = np.nan
        res = _result_like(result, points=bad)
    elif key == "face_indices":
        idx = result.face_indices.copy()
        idx[0] = len(result.points)
        res = _result_like(result, face_indices=idx)
    elif key == "face_sizes":
        sizes = result.face_sizes.copy()
        sizes[0] += 1
        res = _result_like(result, face_sizes=sizes)
    elif key == "boundary":
        res = _result_like(result, boundary=value)
    else:
        kwargs[key] = value
    with pytest.raises(bidegree.InvalidInputError, match=message):
        usd.export(target, cage, res, **kwargs)
    assert target.read_bytes() == b"previous content"
    assert _leftovers(tmp_path) == ["keep.usdc"]


def test_new_file_mode_follows_umask(
    tmp_path: Path, cage: bidegree.Mesh, result: bidegree.Result
) -> None:
    umask = os.umask(0o022)
    try:
        path = tmp_path / "mode.usda"
        usd.export(path, cage, result)
    finally:
        os.umask(umask)
    assert path.stat().st_mode & 0o777 == 0o644


def test_large_result_is_fast(tmp_path: Path) -> None:
    """A 262,144-face result (torus cage 32 x 32, 4 levels) is written in well under 10 s."""
    n = 32
    i, j = np.meshgrid(np.arange(n), np.arange(n), indexing="ij")
    u, v = 2 * np.pi * i / n, 2 * np.pi * j / n
    points = np.stack(
        [
            (2 + 0.7 * np.cos(v)) * np.cos(u),
            0.7 * np.sin(v),
            (2 + 0.7 * np.cos(v)) * np.sin(u),
        ],
        axis=-1,
    ).reshape(-1, 3)
    a, b = i * n + j, ((i + 1) % n) * n + j
    c, d = ((i + 1) % n) * n + (j + 1) % n, i * n + (j + 1) % n
    faces = np.stack([a, d, c, b], axis=-1).reshape(-1, 4)
    uvs = np.random.default_rng(0).random((faces.size, 2))
    torus = bidegree.Mesh(points, faces, uvs=uvs)
    res = bidegree.subdivide(torus, degree=3, levels=4)
    assert len(res.face_sizes) == 262_144
    for ext in (".usdc", ".usda"):
        t0 = time.perf_counter()
        usd.export(tmp_path / f"big{ext}", torus, res, distances=np.zeros(len(res.points)))
        seconds = time.perf_counter() - t0
        assert seconds < 10.0, f"{ext}: {seconds:.1f} s"
    stage = Usd.Stage.Open(str(tmp_path / "big.usdc"))
    counts = stage.GetPrimAtPath("/Bidegree/Result").GetAttribute("faceVertexCounts").Get()
    assert len(counts) == 262_144
