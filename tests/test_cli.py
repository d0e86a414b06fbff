"""The ``bidegree`` command line, run as a separate process from the installed package."""

from __future__ import annotations

import importlib.util
import re
import shutil
import subprocess
import sys
from pathlib import Path

import bidegree
import numpy as np
import pytest

# A cube with texture coordinates, faces written with negative (relative) indices in mixed
# forms, one crease, one corner and a boundary tag (the cube is closed, so the tag only has to
# be read and reported).
CUBE_OBJ = """\
# cube with uvs and OpenSubdiv tags
mtllib cube.mtl
o Cube
v 0 0 0
v 1 0 0
v 1 1 0
v 0 1 0
v 0 0 1
v 1 0 1
v 1 1 1
v 0 1 1
vt 0 0
vt 1 0
vt 1 1
vt 0 1
vn 0 0 1
g sides
usemtl white
s off
f -8/-4 -5/-1 -6/-2 -7/-3
f -4/-4/-1 -3/-3/-1 -2/-2/-1 -1/-1/-1
f 1/1 2/2 6/3 5/4
f 2/1 3/2 7/3 6/4
f 3/1 4/2 8/3 7/4
f 4/1 1/2 5/3 8/4
t crease 2/1/0 0 1 3.5
t corner 1/1/0 6 10
t interpolateboundary 1/0/0 1
"""


def command() -> list[str]:
    """The installed console script, or the module when the script is not on PATH."""
    script = shutil.which("bidegree")
    if script is None:
        candidate = Path(sys.executable).parent / "bidegree"
        script = str(candidate) if candidate.exists() else None
    return [script] if script else [sys.executable, "-m", "bidegree.cli"]


def run(*args: str | Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [*command(), *map(str, args)],
        check=False,
        capture_output=True,
        text=True,
        timeout=120,
    )


def run_here(*args: str | Path) -> subprocess.CompletedProcess[str]:
    """Runs ``bidegree.cli.main`` in this process (same code, no interpreter start-up), with
    stdout and stderr captured."""
    from contextlib import redirect_stderr, redirect_stdout
    from io import StringIO

    from bidegree.cli import main

    out, err = StringIO(), StringIO()
    argv = [str(a) for a in args]
    with redirect_stdout(out), redirect_stderr(err):
        try:
            code = main(argv)
        except SystemExit as exc:  # argparse usage errors and --version
            code = exc.code if isinstance(exc.code, int) else 2
    return subprocess.CompletedProcess(argv, code, out.getvalue(), err.getvalue())


@pytest.fixture
def cube_obj(tmp_path: Path) -> Path:
    path = tmp_path / "cube.obj"
    path.write_text(CUBE_OBJ)
    return path


def test_obj_tags_and_forms_are_read(cube_obj: Path) -> None:
    mesh = bidegree.Mesh.from_obj(cube_obj)
    assert (mesh.num_vertices, mesh.num_faces) == (8, 6)
    np.testing.assert_array_equal(mesh.face_indices[:8], [0, 3, 2, 1, 4, 5, 6, 7])
    assert mesh.uvs is not None and mesh.uvs.shape == (24, 2)
    np.testing.assert_array_equal(mesh.uvs[:4], [[0, 0], [0, 1], [1, 1], [1, 0]])
    assert mesh.creases is not None
    np.testing.assert_array_equal(mesh.creases[0], [[0, 1]])
    np.testing.assert_array_equal(mesh.creases[1], [3.5])
    assert mesh.corners is not None
    np.testing.assert_array_equal(mesh.corners[0], [6])
    assert mesh.boundary == "edge-and-corner"
    assert bidegree.Mesh.from_obj(cube_obj, boundary="edge-only").boundary == "edge-only"


def test_subdivide_round_trip(cube_obj: Path, tmp_path: Path) -> None:
    out = tmp_path / "out.obj"
    proc = run("subdivide", cube_obj, "-o", out, "--degree", "3", "--levels", "2")
    assert proc.returncode == 0, proc.stderr
    assert proc.stderr == ""
    assert "8 vertices, 6 faces" in proc.stdout
    assert "degree 3, 2 levels, primal output, edge-and-corner boundary" in proc.stdout
    assert "96 faces" in proc.stdout  # 24 corners * 4 ** (2 - 1)
    assert re.search(r"subdivided in [0-9.]+ m?s", proc.stdout)  # timings are printed

    written = bidegree.Mesh.from_obj(out)
    assert written.num_faces == 96
    assert np.all(written.face_sizes == 4)
    assert written.uvs is not None and written.uvs.shape == (4 * 96, 2)
    # The file holds exactly what the API computes for the same cage.
    expected = bidegree.subdivide(bidegree.Mesh.from_obj(cube_obj), degree=3, levels=2)
    np.testing.assert_array_equal(written.points, expected.points)
    np.testing.assert_array_equal(written.face_indices, expected.face_indices)
    np.testing.assert_array_equal(written.uvs, expected.uvs)


def test_subdivide_options(cube_obj: Path, tmp_path: Path) -> None:
    out = tmp_path / "dual.obj"
    proc = run_here(
        "subdivide",
        cube_obj,
        "-o",
        out,
        "--degree",
        "2",
        "--levels",
        "3",
        "--output",
        "dual",
        "--boundary",
        "edge-only",
        "--memory-budget",
        "1G",
    )
    assert proc.returncode == 0, proc.stderr
    assert "dual output, edge-only boundary" in proc.stdout
    expected = bidegree.subdivide(
        bidegree.Mesh.from_obj(cube_obj, boundary="edge-only"), 2, 3, "dual"
    )
    assert bidegree.Mesh.from_obj(out).num_faces == expected.num_faces
    quiet = run_here("subdivide", cube_obj, "-o", out, "-q")
    assert quiet.returncode == 0 and quiet.stdout == ""


def test_default_boundary_without_tag_is_edge_only(tmp_path: Path) -> None:
    path = tmp_path / "quad.obj"
    path.write_text("v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\n")
    proc = run_here("subdivide", path, "-o", tmp_path / "q.obj", "--levels", "1")
    assert proc.returncode == 0, proc.stderr
    assert "edge-only boundary" in proc.stdout


def assert_one_line_error(proc: subprocess.CompletedProcess[str], *needles: str) -> None:
    assert proc.returncode == 2, (proc.stdout, proc.stderr)
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1, proc.stderr
    assert lines[0].startswith("bidegree: error: "), proc.stderr
    for needle in needles:
        assert needle in lines[0], proc.stderr


def test_bad_obj_reports_the_line(tmp_path: Path) -> None:
    path = tmp_path / "broken.obj"
    path.write_text("v 0 0 0\nv 1 0 0\n\nf 1 2 x\n")
    proc = run("subdivide", path, "-o", tmp_path / "never.obj")
    assert_one_line_error(proc, "broken.obj:4:", "'x'")
    assert not (tmp_path / "never.obj").exists()


@pytest.mark.parametrize(
    ("text", "needles"),
    [
        ("v 0 0 0\nv 1 0 0\nv 1 1 0\nf 1 2 5\n", ("bad.obj:4:", "out of range")),
        (
            "v 0 0 0\nv 1 0 0\nv 1 1 0\nf 1 2 3\nt crease 2/1/0 0 1 -2\n",
            ("bad.obj:5:",),
        ),
        ("v 0 0 0\nt interpolateboundary 1/0/0 9\n", ("bad.obj:2:",)),
    ],
)
def test_bad_obj_variants(tmp_path: Path, text: str, needles: tuple[str, ...]) -> None:
    path = tmp_path / "bad.obj"
    path.write_text(text)
    assert_one_line_error(run_here("subdivide", path, "-o", tmp_path / "o.obj"), *needles)


def test_invalid_requests_exit_2(cube_obj: Path, tmp_path: Path) -> None:
    out = tmp_path / "o.obj"
    assert_one_line_error(run_here("subdivide", cube_obj, "-o", out, "--degree", "0"), "degree 0")
    assert_one_line_error(run_here("subdivide", cube_obj, "-o", out, "--levels", "17"), "levels 17")
    assert_one_line_error(
        run_here("subdivide", cube_obj, "-o", out, "--levels", "9", "--memory-budget", "1M"),
        "memory budget",
    )
    assert_one_line_error(run_here("subdivide", tmp_path / "missing.obj", "-o", out), "missing.obj")
    assert_one_line_error(run_here("subdivide", cube_obj, "-o", tmp_path / "o.ply"), "unsupported")
    nonmanifold = tmp_path / "nm.obj"
    nonmanifold.write_text(
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 -1 0\nv 0 0 1\nf 1 2 3\nf 2 1 4\nf 1 2 5\n"
    )
    # A non-manifold cage subdivides (issue 13), in both outputs.
    for output in ("primal", "dual"):
        proc = run_here("subdivide", nonmanifold, "-o", out, "--levels", "1", "--output", output)
        assert proc.returncode == 0, proc.stderr
        assert out.exists()
        out.unlink()


def test_isolated_vertex_warning_on_stderr(tmp_path: Path) -> None:
    path = tmp_path / "iso.obj"
    path.write_text("v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 9 9 9\nf 1 2 3 4\n")
    proc = run_here("subdivide", path, "-o", tmp_path / "o.obj", "--levels", "1")
    assert proc.returncode == 0, proc.stderr
    assert proc.stderr.startswith("bidegree: warning: 1 isolated")


def test_usage_errors(cube_obj: Path) -> None:
    assert run_here().returncode == 2
    assert run_here("subdivide", cube_obj).returncode == 2  # -o is required
    assert run_here("subdivide", cube_obj, "-o", "x.obj", "--output", "both").returncode == 2
    assert run_here("subdivide", cube_obj, "-o", "x.obj", "--memory-budget", "lots").returncode == 2
    version = run("--version")
    assert version.returncode == 0 and bidegree.__version__ in version.stdout
    module = subprocess.run(
        [sys.executable, "-m", "bidegree", "--version"],
        check=False,
        capture_output=True,
        text=True,
    )
    assert module.returncode == 0 and bidegree.__version__ in module.stdout
    helptext = run_here("--help").stdout
    assert "subdivide" in helptext and "bench" in helptext


@pytest.mark.skipif(
    importlib.util.find_spec("pxr") is None or importlib.util.find_spec("bidegree.usd") is None,
    reason="needs usd-core and bidegree.usd",
)
def test_usd_output(cube_obj: Path, tmp_path: Path) -> None:
    out = tmp_path / "cube.usda"
    proc = run_here("subdivide", cube_obj, "-o", out, "--degree", "3", "--levels", "1")
    assert proc.returncode == 0, proc.stderr
    text = out.read_text()
    assert "#usda" in text and "Result" in text


def test_bench_runs_small(tmp_path: Path) -> None:
    proc = run_here(
        "bench",
        "--degrees",
        "1,3-4",
        "--faces",
        "200",
        "--target-faces",
        "20000",
        "--repeat",
        "1",
    )
    assert proc.returncode == 0, proc.stderr
    lines = proc.stdout.splitlines()
    assert "valence 3" in lines[0] and "valence 5" in lines[0] and "valence 6" in lines[0]
    rows = [line.split() for line in lines if line.split() and line.split()[0].isdigit()]
    assert [int(row[0]) for row in rows] == [1, 3, 4]
    for row in rows:
        assert row[-1].endswith("x")
        assert float(row[3]) > 0 and float(row[4]) > 0 and float(row[5]) > 0


def test_bench_cage_is_closed_with_extraordinary_vertices() -> None:
    from bidegree.bench import make_cage

    mesh = make_cage(600)
    plan = bidegree.Plan(mesh, degree=3, levels=1)  # validates manifoldness and orientation
    e = len(plan.edges)
    assert plan.num_output_vertices - e + plan.num_output_faces == 2
    valence = np.bincount(mesh.face_indices)
    assert {3, 4, 5, 6} <= set(valence.tolist())
    assert mesh.points.dtype == np.float32
