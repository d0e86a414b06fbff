"""Face-varying values (UVs) of every degree in OpenSubdiv's six modes (issue 14): the API,
the options, the CLI, OBJ and USD. The comparison of classic degree 3 with Blender's
Subdivision Surface in every mode is ``tests/test_dirty_reference.py`` (it needs ``bpy``)."""

from __future__ import annotations

import itertools
from pathlib import Path
from types import SimpleNamespace

import bidegree
import numpy as np
import pytest
from bidegree import usd
from bidegree.options import Options
from cages import torus
from cages_dirty import cube_unwrap, cylinder_seam, uv_junctions

MODES = ("none", "corners-only", "corners-plus1", "corners-plus2", "boundaries", "all")
SMOOTH = MODES[:-1]
N, M = 6, 5  # the torus: N x M vertices, vertex (i, j) = i * M + j


def _torus_uvs(seed: int = 3) -> tuple[bidegree.Mesh, np.ndarray, np.ndarray]:
    """The regular torus with a UV layout without seams: random values per vertex, given per
    corner. Returns the mesh (uvs set), the per-vertex values and the per-corner values."""
    plain = torus(N, M)
    per_vertex = np.random.default_rng(seed).random((N * M, 2))
    per_corner = per_vertex[plain.face_indices]
    mesh = bidegree.Mesh(plain.points, face_sizes=plain.face_sizes,
                         face_indices=plain.face_indices, uvs=per_corner)  # fmt: skip
    return mesh, per_vertex, per_corner


def _lane_riesenfeld(grid: np.ndarray, degree: int, levels: int) -> np.ndarray:
    """Periodic tensor-product Lane-Riesenfeld of a (rows, cols, C) grid: per level replicate,
    then ``degree`` passes of (1 + z) / 2 along each axis; even degrees get the drawing step
    (one more pass)."""
    for _ in range(levels):
        for axis in (0, 1):
            grid = np.repeat(grid, 2, axis=axis)
            for _ in range(degree):
                grid = 0.5 * (grid + np.roll(grid, -1, axis=axis))
    if degree % 2 == 0:
        for axis in (0, 1):
            grid = 0.5 * (grid + np.roll(grid, -1, axis=axis))
    return grid.reshape(-1, grid.shape[-1])


def _same_sets(ours: np.ndarray, reference: np.ndarray, tolerance: float) -> None:
    """Every point of each set has one of the other within ``tolerance`` (max norm)."""
    d = np.abs(ours[:, None, :] - reference[None, :, :]).max(axis=2)
    assert d.min(axis=1).max() <= tolerance
    assert d.min(axis=0).max() <= tolerance


@pytest.mark.parametrize("degree", range(1, 10))
def test_seamless_torus_uvs_are_the_tensor_b_spline(degree: int) -> None:
    """No seams: every mode gives the tensor-product B-spline of the cage UVs (every corner of
    an output vertex the same value), i.e. the UVs through the plan like positions."""
    mesh, per_vertex, per_corner = _torus_uvs()
    levels = 2
    plan = bidegree.Plan(mesh, degree=degree, levels=levels)
    as_points = plan.evaluate(per_vertex)[plan.face_indices]
    reference = _lane_riesenfeld(per_vertex.reshape(N, M, 2), degree, levels)
    for mode in SMOOTH:
        uvs = plan.evaluate_face_varying(per_corner, mode)
        np.testing.assert_array_equal(uvs, as_points)
        _same_sets(uvs, reference, 1e-12)
    # Limit values: the limit masks of the positions.
    limit = plan.evaluate_face_varying(per_corner, "boundaries", limit=True)
    np.testing.assert_array_equal(limit, plan.limit_positions(per_vertex)[plan.face_indices])


@pytest.mark.parametrize("degree", range(1, 10))
def test_all_is_bilinear(degree: int) -> None:
    """``all`` is linear whatever the degree: the bilinear (degree 1) refinement per face."""
    mesh, per_vertex, per_corner = _torus_uvs(5)
    linear = bidegree.Plan(mesh, degree=1, levels=2, rules="classic")
    want = linear.evaluate(per_vertex)[linear.face_indices]
    got = bidegree.Plan(mesh, degree=degree, levels=2).evaluate_face_varying(per_corner, "all")
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-15)


def _values_per_vertex(result: bidegree.Result, uvs: np.ndarray) -> np.ndarray:
    """Number of distinct values among the corners of each output vertex."""
    order = np.lexsort((uvs[:, 1], uvs[:, 0], result.face_indices))
    v, u = result.face_indices[order], uvs[order]
    new = np.ones(len(v), dtype=bool)
    new[1:] = (v[1:] != v[:-1]) | np.any(u[1:] != u[:-1], axis=1)
    return np.bincount(v[new], minlength=result.num_vertices)


@pytest.mark.parametrize("degree", range(1, 10))
def test_seams_stay_seams_and_positions_ignore_the_mode(degree: int) -> None:
    """On a cylinder with one seam, every mode keeps the seam where the linear UVs have it:
    each output vertex on it has exactly two values (one per side, shared bitwise by that
    side's corners), every other vertex one. The positions do not depend on the mode."""
    cage = cylinder_seam()
    mesh = bidegree.Mesh(cage.points, face_sizes=cage.face_sizes,
                         face_indices=cage.face_indices, uvs=cage.uvs)  # fmt: skip
    results = {m: bidegree.subdivide(mesh, degree=degree, levels=2, uv_mode=m) for m in MODES}
    seams = _values_per_vertex(results["all"], results["all"].uvs)
    assert set(np.unique(seams)) == {1, 2}
    for mode, result in results.items():
        assert result.uv_mode == mode
        np.testing.assert_array_equal(result.points, results["all"].points)
        np.testing.assert_array_equal(_values_per_vertex(result, result.uvs), seams)
        if mode != "all" and degree > 1:  # degree 1 is bilinear in every mode
            assert np.abs(result.uvs - results["all"].uvs).max() > 1e-4, mode


def test_modes_differ_and_several_uv_sets_go_at_once() -> None:
    """The modes give different UVs on a cage with junctions; a mapping of UV sets gives each
    set as if alone (each with its own seams)."""
    cage = uv_junctions()
    mesh = bidegree.Mesh(cage.points, face_sizes=cage.face_sizes, face_indices=cage.face_indices)
    plan = bidegree.Plan(mesh, degree=4, levels=2)
    seamless = cage.points[cage.face_indices, :2].copy()
    sets = {"UVMap": np.asarray(cage.uvs), "Flat": seamless}
    for mode in MODES:
        both = plan.evaluate_face_varying(sets, mode)
        assert set(both) == set(sets)
        for name, values in sets.items():
            np.testing.assert_array_equal(both[name], plan.evaluate_face_varying(values, mode))
    by_mode = {m: plan.evaluate_face_varying(sets["UVMap"], m) for m in MODES}
    separated = {
        (a, b) for a, b in itertools.pairwise(MODES) if np.abs(by_mode[a] - by_mode[b]).max() > 1e-6
    }
    # corners-plus1 and -plus2 differ where a convex corner's other side is concave: the cube.
    cube = cube_unwrap()
    cube_mesh = bidegree.Mesh(cube.points, face_sizes=cube.face_sizes,
                              face_indices=cube.face_indices)  # fmt: skip
    cube_plan = bidegree.Plan(cube_mesh, degree=4, levels=2)
    plus = [cube_plan.evaluate_face_varying(cube.uvs, m) for m in MODES[2:4]]
    if np.abs(plus[0] - plus[1]).max() > 1e-6:
        separated.add(MODES[2:4])
    assert separated == set(itertools.pairwise(MODES))
    # One channel and many channels, float32 kept.
    one = plan.evaluate_face_varying(sets["UVMap"][:, 0].astype(np.float32), "none")
    assert one.dtype == np.float32 and one.shape == (len(plan.face_indices),)
    five = np.concatenate([sets["UVMap"], sets["UVMap"], sets["UVMap"][:, :1]], axis=1)
    out = plan.evaluate_face_varying(five, "corners-plus1")
    np.testing.assert_array_equal(out[:, :2], by_mode["corners-plus1"])


def test_bad_requests_are_typed_errors() -> None:
    mesh, _, per_corner = _torus_uvs()
    plan = bidegree.Plan(mesh, degree=3, levels=1)
    with pytest.raises(bidegree.InvalidInputError, match="uv_mode"):
        plan.evaluate_face_varying(per_corner, "smooth")  # type: ignore[arg-type]
    with pytest.raises(bidegree.InvalidInputError, match="uv_mode"):
        bidegree.subdivide(mesh, uv_mode="linear")  # type: ignore[arg-type]
    with pytest.raises(bidegree.InvalidInputError, match="uv_mode"):
        Options(uv_mode="linear")
    with pytest.raises(bidegree.InvalidInputError):
        plan.evaluate_face_varying(per_corner[:-1], "none")
    bad = per_corner.copy()
    bad[3, 1] = np.nan
    with pytest.raises(bidegree.NonFiniteError):
        plan.evaluate_face_varying(bad, "none")
    dual = bidegree.Plan(mesh, degree=3, levels=1, output="dual")
    with pytest.raises(bidegree.InvalidInputError, match="primal"):
        dual.evaluate_face_varying(per_corner, "none", limit=True)
    # The dual output takes each of its corners' values from the drawing mesh's corners.
    assert len(dual.evaluate_face_varying(per_corner, "none")) == len(dual.face_indices)


def test_options_cli_and_obj_vt(tmp_path: Path) -> None:
    """``Options.uv_mode`` reaches the request; the CLI's ``--uv-mode`` subdivides an OBJ's
    ``vt`` and writes them smooth."""
    from test_cli import run_here

    cage = uv_junctions()
    mesh = bidegree.Mesh(cage.points, face_sizes=cage.face_sizes,
                         face_indices=cage.face_indices, uvs=cage.uvs)  # fmt: skip
    source = tmp_path / "cage.obj"
    mesh.write_obj(source)
    for mode in ("corners-plus2", "boundaries"):
        options = Options(degree=3, levels=2, uv_mode=mode)
        want = bidegree.subdivide(mesh, degree=3, levels=2, uv_mode=mode)  # type: ignore[arg-type]
        np.testing.assert_array_equal(options.subdivide(mesh).uvs, want.uvs)
        np.testing.assert_array_equal(options.evaluate_face_varying(want.plan, mesh.uvs), want.uvs)
        out = tmp_path / f"{mode}.obj"
        done = run_here("subdivide", source, "-o", out, "--degree", "3", "--uv-mode", mode, "-q")
        assert done.returncode == 0, done.stderr
        back = bidegree.Mesh.from_obj(out)
        np.testing.assert_allclose(back.uvs, want.uvs, rtol=0, atol=1e-6)
    args = (
        __import__("bidegree.cli")
        .cli.build_parser()
        .parse_args(["subdivide", "in.obj", "-o", "o.obj", "--uv-mode", "none"])
    )
    assert Options.from_namespace(args).uv_mode == "none"
    assert Options().uv_mode == "boundaries"


@pytest.mark.parametrize("mode", MODES)
def test_usd_writes_the_mode_and_every_uv_set(tmp_path: Path, mode: str) -> None:
    pxr = pytest.importorskip("pxr")
    cage = uv_junctions()
    mesh = bidegree.Mesh(cage.points, face_sizes=cage.face_sizes,
                         face_indices=cage.face_indices, uvs=cage.uvs)  # fmt: skip
    result = bidegree.subdivide(mesh, degree=3, levels=1, uv_mode=mode)  # type: ignore[arg-type]
    flat = cage.points[cage.face_indices, :2]
    extra = {"flat": (flat, result.plan.evaluate_face_varying(flat, mode))}  # type: ignore[arg-type]
    path = tmp_path / "uv.usda"
    usd.export(path, mesh, result, uv_sets=extra)
    stage = pxr.Usd.Stage.Open(str(path))
    cmesh = pxr.UsdGeom.Mesh(stage.GetPrimAtPath("/Bidegree/Cage"))
    assert cmesh.GetFaceVaryingLinearInterpolationAttr().Get() == usd.UV_MODE_TO_USD[mode]
    for prim, st, more in (
        ("Cage", mesh.uvs, extra["flat"][0]),
        ("Result", result.uvs, extra["flat"][1]),
    ):
        primvars = pxr.UsdGeom.PrimvarsAPI(stage.GetPrimAtPath(f"/Bidegree/{prim}"))
        for name, want in (("st", st), ("flat", more)):
            primvar = primvars.GetPrimvar(name)
            assert primvar.GetInterpolation() == pxr.UsdGeom.Tokens.faceVarying
            # The cage's by its topology; the result's st in its indexed form.
            assert primvar.IsIndexed() == (prim == "Cage" or name == "st")
            got = np.asarray(primvar.ComputeFlattened())
            np.testing.assert_allclose(got, want, rtol=0, atol=1e-6)
    st = pxr.UsdGeom.PrimvarsAPI(stage.GetPrimAtPath("/Bidegree/Result")).GetPrimvar("st")
    np.testing.assert_array_equal(np.asarray(st.GetIndices()), result.uv_indices)
    assert len(st.Get()) == len(result.uv_values)
    assert usd.validate(path) == []
    with pytest.raises(bidegree.InvalidInputError, match="UV set"):
        usd.export(tmp_path / "bad.usda", mesh, result, uv_sets={"st": extra["flat"]})
    # A result-like object whose indexed uvs do not fit its faces is refused, nothing written.
    fields = ("points", "face_sizes", "face_indices", "degree", "levels", "output", "uv_mode")
    bad = SimpleNamespace(**{name: getattr(result, name) for name in fields})
    bad.uv_values, bad.uv_indices = result.uv_values, result.uv_indices.copy()
    bad.uv_indices[3] = len(result.uv_values)
    with pytest.raises(bidegree.InvalidInputError, match="out of range"):
        usd.export(tmp_path / "bad-index.usda", mesh, bad)
    assert not (tmp_path / "bad-index.usda").exists()


@pytest.mark.parametrize(("degree", "rules"), [(2, "averaging"), (3, "classic"), (4, "averaging")])
def test_holes_leave_the_uvs_of_the_other_faces_as_they_are(degree: int, rules: str) -> None:
    """A hole is refined with the rest and left out of the output (OpenSubdiv's ``holeIndices``):
    the UVs of every kept face equal those of the cage without the hole, bitwise, in every mode."""
    cage = cube_unwrap()
    args = {"face_sizes": cage.face_sizes, "face_indices": cage.face_indices, "uvs": cage.uvs}
    whole = bidegree.Mesh(cage.points, **args)
    holed = bidegree.Mesh(cage.points, holes=[1], **args)
    for mode in MODES:
        full = bidegree.subdivide(whole, degree=degree, levels=2, rules=rules, uv_mode=mode)
        cut = bidegree.subdivide(holed, degree=degree, levels=2, rules=rules, uv_mode=mode)
        kept = full.face_origin != 1
        assert 0 < len(cut.face_sizes) == kept.sum() < len(full.face_sizes)
        np.testing.assert_array_equal(cut.uvs, full.uvs[np.repeat(kept, full.face_sizes)])


def _with_uvs(mesh: bidegree.Mesh, **uvs: object) -> bidegree.Mesh:
    """``mesh`` with ``uvs=`` / ``uv_indices=``."""
    return bidegree.Mesh(
        mesh.points, face_sizes=mesh.face_sizes, face_indices=mesh.face_indices, **uvs
    )


def _seamed_by_index() -> tuple[bidegree.Mesh, np.ndarray, np.ndarray, np.ndarray]:
    """A bumped 4 x 4 grid whose uvs are one smooth chart, and vt-style indices that cut it
    along the column x = 2: the corners right of it take a second index at those vertices,
    with the same coordinates. Returns the plain mesh, the values, the cut indices and the
    welded ones (one index per vertex)."""
    n = 4
    xs, ys = np.meshgrid(np.arange(n + 1.0), np.arange(n + 1.0))
    points = np.column_stack([xs.ravel(), ys.ravel(), np.zeros(xs.size)])
    points[12, 2] = 1.0
    faces = [
        [y * (n + 1) + x, y * (n + 1) + x + 1, (y + 1) * (n + 1) + x + 1, (y + 1) * (n + 1) + x]
        for y in range(n)
        for x in range(n)
    ]
    mesh = bidegree.Mesh(points, faces)
    x, y = points[:, 0], points[:, 1]
    chart = np.column_stack([x / n + 0.05 * np.sin(y), y / n + 0.03 * x**2 / n**2])
    nv = len(points)
    values = np.concatenate([chart, chart])  # rows nv.. repeat the coordinates
    welded = mesh.face_indices.copy()
    cut = welded.copy()
    right = np.repeat([(f % n) >= 2 for f in range(len(faces))], 4)
    on_cut = right & (points[welded, 0] == 2)
    cut[on_cut] = nv + welded[on_cut]
    return mesh, values, cut, welded


def test_indices_are_the_topology() -> None:
    """Values + per-corner indices (OpenSubdiv's way): two indices with equal coordinates at
    one vertex stay apart (a seam), one index is one value; the same topology as distinct
    values welded by value, bitwise."""
    mesh, values, cut, welded = _seamed_by_index()
    plan = bidegree.Plan(mesh, degree=3, levels=2)
    for mode in MODES:
        seam = plan.evaluate_face_varying(values, mode, indices=cut)
        joined = plan.evaluate_face_varying(values, mode, indices=welded)
        by_value = plan.evaluate_face_varying(values[cut], mode)
        np.testing.assert_array_equal(joined, by_value)  # equal coordinates weld by value
        if mode == "all":
            np.testing.assert_array_equal(seam, joined)
        else:
            assert np.abs(seam - joined).max() > 1e-4, mode
        # The cut as distinct values, welded by value: the same face-varying mesh.
        moved = values.copy()
        moved[len(mesh.points) :] += 1.0
        np.testing.assert_array_equal(
            plan.evaluate_face_varying(moved, mode, indices=cut),
            plan.evaluate_face_varying(moved[cut], mode),
        )
    # Several sets at once, one of them indexed; 1-D values come back 1-D.
    both = plan.evaluate_face_varying({"cut": (values, cut), "flat": values[cut]}, "none")
    np.testing.assert_array_equal(
        both["cut"], plan.evaluate_face_varying(values, "none", indices=cut)
    )
    u = plan.evaluate_face_varying(values[:, 0], "none", indices=cut)
    np.testing.assert_array_equal(u, both["cut"][:, 0])
    # The mesh's uv_indices are its uvs' topology, in subdivide and in Plan.result.
    indexed = _with_uvs(mesh, uvs=values, uv_indices=cut)
    np.testing.assert_array_equal(indexed.uvs, values[cut])
    np.testing.assert_array_equal(indexed.uv_indices, cut)
    result = bidegree.subdivide(indexed, degree=3, levels=2, uv_mode="boundaries")
    np.testing.assert_array_equal(result.uvs, plan.evaluate_face_varying(values, indices=cut))


def test_bad_indices_are_typed_errors() -> None:
    mesh, values, cut, _ = _seamed_by_index()
    plan = bidegree.Plan(mesh, degree=3, levels=1)
    with pytest.raises(bidegree.IndexOutOfRangeError, match="out of range"):
        plan.evaluate_face_varying(values[:10], indices=cut)
    with pytest.raises(bidegree.IndexOutOfRangeError):
        plan.evaluate_face_varying(values, indices=-cut - 1)
    with pytest.raises(bidegree.InvalidInputError, match="one index per face corner"):
        plan.evaluate_face_varying(values, indices=cut[1:])
    with pytest.raises(bidegree.InvalidInputError, match="integers"):
        plan.evaluate_face_varying(values, indices=cut.astype(float))
    with pytest.raises(bidegree.InvalidInputError, match="mapping"):
        plan.evaluate_face_varying({"a": values[cut]}, indices=cut)
    with pytest.raises(bidegree.InvalidInputError, match="give the uvs"):
        _with_uvs(mesh, uv_indices=cut)
    with pytest.raises(bidegree.IndexOutOfRangeError):
        _with_uvs(mesh, uvs=values[:10], uv_indices=cut)


def test_obj_vt_indices_are_the_topology(tmp_path: Path) -> None:
    """An OBJ with two ``vt`` of identical coordinates at one vertex keeps the seam (as
    OpenSubdiv); one ``vt`` there welds. Writing a mesh keeps its topology through a read."""
    mesh, values, cut, welded = _seamed_by_index()
    plan = bidegree.Plan(mesh, degree=3, levels=2)
    for indices in (cut, welded):
        cage = _with_uvs(mesh, uvs=values, uv_indices=indices)
        path = tmp_path / "cage.obj"
        cage.write_obj(path)
        vt = [line for line in path.read_text().splitlines() if line.startswith("vt ")]
        assert len(vt) == len(values) and vt[:25] == vt[25:]  # the coordinates repeat
        back = bidegree.Mesh.from_obj(path)
        np.testing.assert_array_equal(back.uv_indices, indices)
        got = bidegree.subdivide(back, degree=3, levels=2).uvs
        np.testing.assert_array_equal(got, plan.evaluate_face_varying(values, indices=indices))
    # Per-corner uvs (welded by value) are written one vt per distinct value: the same seams.
    plain = _with_uvs(mesh, uvs=values[cut])
    plain.write_obj(tmp_path / "plain.obj")
    back = bidegree.Mesh.from_obj(tmp_path / "plain.obj")
    np.testing.assert_array_equal(
        bidegree.subdivide(back, degree=3, levels=2).uvs,
        bidegree.subdivide(plain, degree=3, levels=2).uvs,
    )
    # A result written and read back subdivides with the result's seams.
    result = bidegree.subdivide(plain, degree=3, levels=1)
    result.write_obj(tmp_path / "result.obj")
    again = bidegree.Mesh.from_obj(tmp_path / "result.obj")
    by_value = bidegree.Mesh(result.points, face_sizes=result.face_sizes,
                             face_indices=result.face_indices, uvs=result.uvs)  # fmt: skip
    np.testing.assert_allclose(
        bidegree.subdivide(again, degree=3, levels=1).uvs,
        bidegree.subdivide(by_value, degree=3, levels=1).uvs,
        rtol=0,
        atol=1e-12,
    )


def test_usd_cage_uvs_are_indexed_by_their_topology(tmp_path: Path) -> None:
    pxr = pytest.importorskip("pxr")
    mesh, values, cut, _ = _seamed_by_index()
    for uvs, indices in ((values, cut), (values[cut], None)):
        cage = _with_uvs(mesh, uvs=uvs, uv_indices=indices)
        result = bidegree.subdivide(cage, degree=3, levels=1)
        path = tmp_path / "cage.usda"
        usd.export(path, cage, result)
        stage = pxr.Usd.Stage.Open(str(path))
        st = pxr.UsdGeom.PrimvarsAPI(stage.GetPrimAtPath("/Bidegree/Cage")).GetPrimvar("st")
        written = np.asarray(st.GetIndices())
        np.testing.assert_allclose(np.asarray(st.ComputeFlattened()), values[cut], atol=1e-7)
        # The written indices are the topology subdivided (the cut's seam, or the weld).
        again = _with_uvs(mesh, uvs=np.asarray(st.Get()), uv_indices=written)
        np.testing.assert_allclose(
            bidegree.subdivide(again, degree=3, levels=1).uvs, result.uvs, rtol=0, atol=1e-6
        )
        assert usd.validate(path) == []


def test_blender_uv_indices_are_the_reference_weld() -> None:
    """``bidegree.blender_uv_indices`` (vectorized) groups corners as the reference loop of
    ``tests/opensubdiv_reference.py`` does, on the issue's UV cages and on them with UVs moved
    by amounts around Blender's limit and faces' UVs mirrored (winding flipped)."""
    import opensubdiv_reference as ref
    from cages_dirty import issue_14_cages

    rng = np.random.default_rng(14)
    for cage in issue_14_cages(with_blender=False).values():
        uvs = np.asarray(cage.uvs, dtype=np.float32)
        moved = uvs + rng.choice([0.0, 5e-5, -9e-5, 2e-4], size=uvs.shape).astype(np.float32)
        face = np.repeat(np.arange(len(cage.face_sizes)), cage.face_sizes)
        mirrored = uvs.copy()
        flip = np.isin(face, rng.choice(len(cage.face_sizes), 3, replace=False))
        mirrored[flip, 0] = 1 - mirrored[flip, 0]
        for given in (uvs, moved, mirrored):
            ours = bidegree.blender_uv_indices(cage.face_sizes, cage.face_indices, given)
            theirs = ref.blender_uv_values(cage, given)
            # The same partition of the corners (numbered differently).
            pairs = set(zip(ours.tolist(), theirs.tolist(), strict=True))
            assert len(pairs) == len(set(ours.tolist())) == len(set(theirs.tolist())), cage.name
    with pytest.raises(bidegree.InvalidInputError):
        bidegree.blender_uv_indices([4], [0, 1, 2, 3], np.zeros((3, 2)))


@pytest.mark.parametrize("output", ["primal", "dual"])
def test_the_indexed_form_expands_to_the_per_corner_values(output: str) -> None:
    """``evaluate_face_varying_shared`` gives ``(values, indices)`` whose expansion is the
    per-corner result, bitwise, in every mode (a cube unwrap with seams, a hole, float32 and
    float64, 1-D values, indexed input, several sets); its indices are the plan's own (the same
    read-only array every call) and every value is used."""
    cage = cube_unwrap()
    mesh = bidegree.Mesh(cage.points, face_sizes=cage.face_sizes,
                         face_indices=cage.face_indices, holes=[2])  # fmt: skip
    plan = bidegree.Plan(mesh, degree=4, levels=2, output=output)
    for mode, dtype in itertools.product(MODES, (np.float32, np.float64)):
        uvs = cage.uvs.astype(dtype)
        values, indices = plan.evaluate_face_varying_shared(uvs, mode)
        assert values.dtype == dtype and indices.dtype == np.int32
        np.testing.assert_array_equal(values[indices], plan.evaluate_face_varying(uvs, mode))
        assert np.array_equal(np.unique(indices), np.arange(len(values)))
        assert not indices.flags.writeable
        again_values, again = plan.evaluate_face_varying_shared(uvs * 2, mode)
        assert again is indices
        np.testing.assert_array_equal(
            again_values[again], plan.evaluate_face_varying(uvs * 2, mode)
        )
        flat, flat_indices = plan.evaluate_face_varying_shared(uvs[:, 0], mode)
        assert flat.ndim == 1
        np.testing.assert_array_equal(
            flat[flat_indices], plan.evaluate_face_varying(uvs[:, 0], mode)
        )
    table, index = np.unique(cage.uvs, axis=0, return_inverse=True)
    both = plan.evaluate_face_varying_shared(
        {"indexed": (table, index.reshape(-1)), "per-corner": cage.uvs}, "none"
    )
    for values, indices in both.values():
        np.testing.assert_array_equal(values[indices], plan.evaluate_face_varying(cage.uvs, "none"))


def test_results_keep_uvs_in_the_indexed_form(tmp_path: Path) -> None:
    """A result's uvs are ``uv_values[uv_indices]``; its OBJ writes one ``vt`` per value and
    reads back with the same seams; assigning ``uvs`` drops the indexed form."""
    cage = cylinder_seam()
    mesh = bidegree.Mesh(cage.points, face_sizes=cage.face_sizes,
                         face_indices=cage.face_indices, uvs=cage.uvs)  # fmt: skip
    result = bidegree.subdivide(mesh, degree=3, levels=2, uv_mode="boundaries")
    assert result.uv_values is not None and result.uv_indices is not None
    np.testing.assert_array_equal(
        result.uvs, result.plan.evaluate_face_varying(cage.uvs, "boundaries")
    )
    path = tmp_path / "seam.obj"
    result.write_obj(path)
    assert path.read_text().count("\nvt ") == len(result.uv_values)
    back = bidegree.Mesh.from_obj(path)
    np.testing.assert_array_equal(back.uv_indices, result.uv_indices)
    np.testing.assert_allclose(back.uvs, result.uvs, rtol=0, atol=1e-6)
    result.uvs = result.uvs + 1.0
    assert result.uv_values is None and result.uv_indices is None
    assert result.uvs is not None
