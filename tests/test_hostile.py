"""Hostile input (issue 18): each case is a reproducer of a problem a probe found, with the typed
outcome it must have now. Files, signals, address-space and file-size limits are real: the CLI
runs as a child process where the case needs one (a kill, a resource limit)."""

from __future__ import annotations

import importlib.util
import os
import resource
import signal
import subprocess
import sys
import time
import warnings
from pathlib import Path

import bidegree
import numpy as np
import pytest
from cages import CUBE_FACES, CUBE_POINTS, cube
from test_cli import CUBE_OBJ, command

TRIANGLE = "v 0 0 0\nv 1 0 0\nv 1 1 0\nf 1 2 3\n"


def cli(
    *args: str | Path, limits: dict[int, int] | None = None, env: dict[str, str] | None = None
) -> subprocess.CompletedProcess[str]:
    """The installed CLI in a child process, with resource limits (``RLIMIT_*: bytes``) set in
    the child before it starts."""

    def limit() -> None:
        for which, value in (limits or {}).items():
            resource.setrlimit(which, (value, value))
        # Past RLIMIT_FSIZE a write fails with EFBIG (what a full disk looks like to the
        # writer) instead of the process being killed by SIGXFSZ.
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)

    return subprocess.run(
        [*command(), *map(str, args)],
        check=False,
        capture_output=True,
        text=True,
        timeout=300,
        preexec_fn=limit,
        env={**os.environ, **(env or {})},
    )


def one_error_line(proc: subprocess.CompletedProcess[str], *needles: str) -> str:
    """The CLI failed with exit 2 and one ``bidegree: error:`` line (warnings aside)."""
    assert proc.returncode == 2, (proc.returncode, proc.stdout, proc.stderr)
    lines = [line for line in proc.stderr.splitlines() if not line.startswith("bidegree: warning")]
    assert len(lines) == 1 and lines[0].startswith("bidegree: error: "), proc.stderr
    for needle in needles:
        assert needle in lines[0], proc.stderr
    return lines[0]


def files_in(directory: Path) -> list[str]:
    return sorted(p.name for p in directory.iterdir())


# ---------------------------------------------------------------------------------------------
# Item 3: input read under a size cap, streamed; /dev/zero refused quickly


def test_dev_zero_is_refused_at_once(tmp_path: Path) -> None:
    started = time.monotonic()
    proc = cli("subdivide", "/dev/zero", "-o", tmp_path / "x.obj")
    one_error_line(proc, "/dev/zero:1:", "NUL byte")
    assert time.monotonic() - started < 30  # it was an OOM kill after 23 GB before
    assert files_in(tmp_path) == []


def test_input_size_cap(tmp_path: Path) -> None:
    path = tmp_path / "cube.obj"
    path.write_text(CUBE_OBJ)
    size = path.stat().st_size
    with pytest.raises(
        bidegree.BidegreeIOError, match=f"{size} bytes, larger than the input limit"
    ):
        bidegree.Mesh.from_obj(path, max_bytes=size - 1)
    assert bidegree.Mesh.from_obj(path, max_bytes=size).num_faces == 6
    proc = cli("subdivide", path, "-o", tmp_path / "o.obj", "--max-input-bytes", "100")
    one_error_line(proc, "larger than the input limit of 100 bytes")
    # What the mesh takes while reading is under the memory budget too.
    with pytest.raises(bidegree.MemoryBudgetError, match=r"cube\.obj:\d+: the mesh read so far"):
        bidegree.Mesh.from_obj(path, memory_budget=64)


# ---------------------------------------------------------------------------------------------
# Item 5: outputs written to a temporary name and renamed; nothing left on errors and signals


def _kill_mid_write(tmp_path: Path, out: Path, signum: int) -> int:
    """Starts a write of a large result, sends ``signum`` once the write has begun (after the
    CLI reported the subdivision and, for USD, once the temporary file exists), returns the
    exit code."""
    cage = tmp_path / "cube.obj"
    cage.write_text(CUBE_OBJ)
    # A job that a script starts in the background (``cmd &`` without job control) starts
    # with SIGINT ignored, and Python keeps an ignored SIGINT: the CLI would never see this
    # Ctrl-C. The child gets the default disposition, as from a terminal.
    ignored = signal.getsignal(signal.SIGINT) == signal.SIG_IGN
    if ignored:
        signal.signal(signal.SIGINT, signal.SIG_DFL)
    try:
        # Degree 1, 8 levels: 393,216 faces with uvs, an OBJ of about 75 MB (about 0.1 s of
        # writing, checked for signals every megabyte).
        proc = subprocess.Popen(
            [*command(), "subdivide", str(cage), "-o", str(out), "--degree", "1", "--levels", "8"],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
            env={**os.environ, "PYTHONUNBUFFERED": "1"},
        )
    finally:
        if ignored:
            signal.signal(signal.SIGINT, signal.SIG_IGN)
    assert proc.stdout is not None and proc.stderr is not None
    for line in proc.stdout:
        if line.startswith("output:"):
            break
    if out.suffix != ".obj":
        # The USD writer's temporary file is named; an OBJ's has no name until it is complete.
        deadline = time.monotonic() + 60
        while not any(out.parent.iterdir()) and time.monotonic() < deadline:
            time.sleep(0.001)
        assert any(out.parent.iterdir()), "no temporary file appeared"
    proc.send_signal(signum)
    code = proc.wait(timeout=120)
    stderr = proc.stderr.read()
    assert "wrote" not in proc.stdout.read(), "the write finished before the signal"
    if signum != signal.SIGKILL:
        last = stderr.strip().splitlines()[-1]
        assert last.startswith(("bidegree: terminated", "bidegree: interrupted")), stderr
    assert "Traceback" not in stderr, stderr
    return code


def test_sigterm_mid_write_leaves_nothing(tmp_path: Path) -> None:
    out = tmp_path / "out" / "result.obj"
    out.parent.mkdir()
    assert _kill_mid_write(tmp_path, out, signal.SIGTERM) == 128 + signal.SIGTERM
    assert files_in(out.parent) == []  # no file at the target, no temporary file


def test_sigkill_mid_write_leaves_nothing(tmp_path: Path) -> None:
    # Nothing runs on SIGKILL: the OBJ being written is an unnamed file until it is complete.
    out = tmp_path / "out" / "result.obj"
    out.parent.mkdir()
    assert _kill_mid_write(tmp_path, out, signal.SIGKILL) == -signal.SIGKILL
    assert files_in(out.parent) == []


def test_sigint_mid_write_keeps_the_previous_file(tmp_path: Path) -> None:
    out = tmp_path / "out" / "result.obj"
    out.parent.mkdir()
    out.write_text("what the user had\n")
    assert _kill_mid_write(tmp_path, out, signal.SIGINT) == 130
    assert files_in(out.parent) == ["result.obj"]
    assert out.read_text() == "what the user had\n"


@pytest.mark.skipif(importlib.util.find_spec("pxr") is None, reason="needs usd-core")
def test_sigterm_mid_usd_write_leaves_no_temporary_file(tmp_path: Path) -> None:
    out = tmp_path / "out" / "result.usdc"
    out.parent.mkdir()
    assert _kill_mid_write(tmp_path, out, signal.SIGTERM) == 128 + signal.SIGTERM
    assert files_in(out.parent) == []


def test_full_disk_leaves_no_truncated_file(tmp_path: Path) -> None:
    cage = tmp_path / "cube.obj"
    cage.write_text(CUBE_OBJ)
    out = tmp_path / "out" / "result.obj"
    out.parent.mkdir()
    out.write_text("previous\n")
    # A 1 MB file-size limit stands for a full disk: the ~6 MB write fails part-way.
    proc = cli(
        "subdivide", cage, "-o", out, "--levels", "6", limits={resource.RLIMIT_FSIZE: 1 << 20}
    )
    one_error_line(proc, "result.obj", "too large")
    assert files_in(out.parent) == ["result.obj"]
    assert out.read_text() == "previous\n"


def test_refused_writes_leave_nothing(tmp_path: Path) -> None:
    result = bidegree.subdivide(cube(), degree=3, levels=1)
    result.points = result.points.copy()
    result.points[5, 1] = np.nan
    with pytest.raises(bidegree.NonFiniteError, match="vertex 5"):
        result.write_obj(tmp_path / "nan.obj")
    with pytest.raises(bidegree.BidegreeIOError, match="is a directory"):
        bidegree.subdivide(cube(), levels=1).write_obj(tmp_path)
    assert files_in(tmp_path) == []


# ---------------------------------------------------------------------------------------------
# Item 6: BOM, line ends, trailing garbage, one warning per kind of skipped statement or tag


@pytest.mark.parametrize(
    "text",
    [
        "\ufeff" + TRIANGLE,  # shifted every index by one before
        TRIANGLE.replace("\n", "\r"),  # was one line
        TRIANGLE.replace("\n", "\r\n"),
        "\ufeff" + TRIANGLE.replace("\n", "\r\n"),
    ],
    ids=["bom", "cr", "crlf", "bom-crlf"],
)
def test_bom_and_line_ends(tmp_path: Path, text: str) -> None:
    path = tmp_path / "tri.obj"
    path.write_bytes(text.encode())
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        mesh = bidegree.Mesh.from_obj(path)
    np.testing.assert_array_equal(mesh.points, [[0, 0, 0], [1, 0, 0], [1, 1, 0]])
    np.testing.assert_array_equal(mesh.face_indices, [0, 1, 2])


def test_trailing_garbage_is_an_error_with_its_line(tmp_path: Path) -> None:
    path = tmp_path / "garbage.obj"
    path.write_text("v 0 0 0\nv 1 0 0\nv 1 2 3 garbage\nf 1 2 3\n")
    proc = cli("subdivide", path, "-o", tmp_path / "o.obj")
    one_error_line(proc, "garbage.obj:3:", "'garbage'")
    assert not (tmp_path / "o.obj").exists()


def test_unknown_statements_and_tags_warn_once_per_kind(tmp_path: Path) -> None:
    path = tmp_path / "tags.obj"
    path.write_text(
        TRIANGLE + "frobnicate 1\nfrobnicate 2\nt spell 0/0/0\nt spell 0/0/0\nt magic 0/0/0\n"
    )
    with pytest.warns(bidegree.ObjWarning) as caught:
        bidegree.Mesh.from_obj(path)
    assert [str(w.message) for w in caught] == [
        f"{path}:5: unknown statement 'frobnicate' was ignored (2 times)",
        f"{path}:7: tag 'spell' is not supported and was ignored (2 times)",
        f"{path}:9: tag 'magic' is not supported and was ignored",
    ]
    proc = cli("subdivide", path, "-o", tmp_path / "o.obj", "--levels", "1", "-q")
    assert proc.returncode == 0, proc.stderr
    assert proc.stderr.splitlines() == [f"bidegree: warning: {w.message}" for w in caught], (
        proc.stderr
    )


# ---------------------------------------------------------------------------------------------
# Item 9: errors in the file's own terms, the right array, what is allowed; non-finite output


QUAD_POINTS = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0 0 1\n"


@pytest.mark.parametrize(
    ("faces", "error", "message"),
    [
        (
            "f 1 2 3\n\nf 1 3 3 1\n",
            bidegree.RepeatedVertexError,
            ":8: the face uses vertex 3 more than once",
        ),
        (
            "f 1 2 3 4\nt crease 2/1/0 0 2 1\n",
            bidegree.CreaseNotAnEdgeError,
            ":7: crease (0, 2) is not an edge of the mesh",
        ),
    ],
    ids=["repeated", "crease"],
)
def test_mesh_errors_name_the_obj_line(
    tmp_path: Path, faces: str, error: type[Exception], message: str
) -> None:
    path = tmp_path / "bad.obj"
    path.write_text(QUAD_POINTS + faces)
    with pytest.raises(error) as caught:
        bidegree.subdivide(bidegree.Mesh.from_obj(path), levels=1)
    assert str(caught.value).startswith(f"{path}{message}"), caught.value
    assert caught.value.line == int(message.split(":")[1])
    one_error_line(cli("subdivide", path, "-o", tmp_path / "o.obj"), f"bad.obj{message}")
    # The same mesh built from arrays keeps the 0-based terms of its arrays.
    if error is bidegree.RepeatedVertexError:
        with pytest.raises(error, match="face 1 uses vertex 2 more than once"):
            bidegree.Mesh(np.zeros((5, 3)), [[0, 1, 2], [0, 2, 2, 0]])


@pytest.mark.parametrize(
    "faces",
    [
        "f 1 2 3\n\nf 1 3 4 3\n",
        "f 1 2 3\n# flipped\nf 4 3 1\n",
        "f 1 2 3\nf 2 1 4\nf 1 2 5\n",
        "f 1 2 3 4\nf 1 2 5\nt hole 1/0/0 1\nt interpolateboundary 1/0/0 0\n",
    ],
    ids=["repeated", "orientation", "non-manifold", "holes"],
)
def test_dirty_obj_files_subdivide(tmp_path: Path, faces: str) -> None:
    """What OpenSubdiv subdivides, bidegree does: through the API and the CLI (issue 13)."""
    path = tmp_path / "dirty.obj"
    path.write_text(QUAD_POINTS + faces)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", bidegree.IsolatedVerticesWarning)
        result = bidegree.subdivide(bidegree.Mesh.from_obj(path), levels=1)
    assert np.isfinite(np.asarray(result.points)).all()
    proc = cli("subdivide", path, "-o", tmp_path / "o.obj", "--levels", "1", "-q")
    assert proc.returncode == 0, proc.stderr


def test_nan_uvs_are_not_a_bad_vertex() -> None:
    uvs = np.zeros((24, 2))
    uvs[5, 1] = np.nan
    with pytest.raises(bidegree.NonFiniteError, match="uvs: face corner 5") as caught:
        cube(uvs=uvs)
    assert caught.value.corner == 5
    assert "vertex" not in str(caught.value)


def test_bad_sizes_and_levels_say_what_is_allowed(tmp_path: Path) -> None:
    with pytest.raises(bidegree.FaceTooSmallError, match="face 0 has size -4 in face_sizes"):
        bidegree.Mesh(CUBE_POINTS, face_sizes=[-4], face_indices=[0, 1, 2, 3])
    with pytest.raises(bidegree.LevelOutOfRangeError, match=r"max_level 0 is out of range 1\.\."):
        bidegree.subdivide_adaptive(cube(), max_level=0)
    path = tmp_path / "cube.obj"
    path.write_text(CUBE_OBJ)
    proc = cli("subdivide", path, "-o", tmp_path / "o.obj", "--adaptive", "--max-level", "0")
    one_error_line(proc, "max_level 0 is out of range 1..=16")


@pytest.mark.parametrize(
    ("scale", "dtype"),
    [
        (1e300, np.float64),
        (1e-300, np.float64),
        (1e-30, np.float32),
    ],
)
def test_a_scaled_cube_is_not_degenerate(scale: float, dtype: type) -> None:
    mesh = bidegree.Mesh((CUBE_POINTS * scale).astype(dtype), CUBE_FACES)
    result = bidegree.subdivide(mesh, levels=2)
    assert np.isfinite(result.points).all()
    assert result.points.dtype == dtype


def test_float32_overflow_is_an_error_not_inf(tmp_path: Path) -> None:
    huge = (CUBE_POINTS * 2 - 1).astype(np.float32) * np.float32(3e38)
    mesh = bidegree.Mesh(huge, CUBE_FACES)
    for call in (
        lambda: bidegree.subdivide(mesh, degree=3, levels=1),
        lambda: bidegree.Plan(mesh, degree=3, levels=1).evaluate(huge),
        lambda: bidegree.subdivide(mesh, degree=3, levels=1, limit=True),
        lambda: bidegree.subdivide_adaptive(mesh, degree=3, max_level=1, tolerance=0),
    ):
        with pytest.raises(bidegree.NonFiniteError, match="overflow float32"):
            call()
    # In float64 the same cage is fine; a NaN in the input is the input's fault.
    assert np.isfinite(
        bidegree.subdivide(
            bidegree.Mesh(huge.astype(np.float64), CUBE_FACES), degree=3, levels=1
        ).points
    ).all()
    values = CUBE_POINTS.copy()
    values[0, 0] = np.nan
    with pytest.raises(bidegree.NonFiniteError, match=r"^vertex 0 has a non-finite coordinate"):
        bidegree.Plan(cube(), levels=1).evaluate(values)


# ---------------------------------------------------------------------------------------------
# Item 10: t creasemethod chaikin honoured; CLI --creasing


def test_creasemethod_tag_is_honoured(tmp_path: Path) -> None:
    # Semi-sharp creases of different sharpness meeting at a vertex: Chaikin differs there.
    tags = "t crease 2/1/0 0 1 1.0\nt crease 2/1/0 1 2 3.0\nt crease 2/1/0 0 3 2.0\n"
    plain = tmp_path / "plain.obj"
    plain.write_text(CUBE_OBJ.split("t crease")[0] + tags)
    chaikin = tmp_path / "chaikin.obj"
    chaikin.write_text(plain.read_text() + "t creasemethod 0/0/1 chaikin\n")
    options = {"degree": 3, "levels": 3, "rules": "classic"}
    uniform_mesh, chaikin_mesh = bidegree.Mesh.from_obj(plain), bidegree.Mesh.from_obj(chaikin)
    assert (uniform_mesh.creasing, chaikin_mesh.creasing) == ("uniform", "chaikin")
    by_tag = bidegree.subdivide(chaikin_mesh, **options).points
    by_option = bidegree.subdivide(uniform_mesh, creasing="chaikin", **options).points
    uniform = bidegree.subdivide(uniform_mesh, **options).points
    np.testing.assert_array_equal(by_tag, by_option)
    assert not np.array_equal(by_tag, uniform)
    # The CLI follows the tag, and --creasing overrides it.
    for source, flag, expected in (
        (chaikin, [], by_tag),
        (plain, ["--creasing", "chaikin"], by_tag),
        (chaikin, ["--creasing", "uniform"], uniform),
    ):
        out = tmp_path / "out.obj"
        proc = cli(
            "subdivide",
            source,
            "-o",
            out,
            "--degree",
            "3",
            "--levels",
            "3",
            "--rules",
            "classic",
            "-q",
            *flag,
        )
        assert proc.returncode == 0, proc.stderr
        np.testing.assert_array_equal(bidegree.Mesh.from_obj(out).points, expected)


# ---------------------------------------------------------------------------------------------
# The panic boundary: a panic reaches Python as InternalError and the CLI user as one line


def test_cli_prints_one_typed_line_for_a_panic(tmp_path: Path) -> None:
    path = tmp_path / "cube.obj"
    path.write_text(CUBE_OBJ)
    # The CLI with the core's subdivision replaced by the deliberate panic of the binding.
    script = (
        "import sys, bidegree, bidegree.cli\n"
        "bidegree.subdivide = lambda *a, **k: bidegree._native._panic_for_tests()\n"
        f"sys.exit(bidegree.cli.main(['subdivide', {str(path)!r}, '-o', "
        f"{str(tmp_path / 'o.obj')!r}, '-q']))\n"
    )
    proc = subprocess.run(
        [sys.executable, "-c", script], capture_output=True, text=True, check=False, timeout=120
    )
    line = one_error_line(proc, "internal error", "a bug in bidegree")
    assert "panic" not in proc.stderr and "errors.rs" not in proc.stderr, proc.stderr
    assert proc.stderr == line + "\n"
    debug = subprocess.run(
        [sys.executable, "-c", script],
        capture_output=True,
        text=True,
        check=False,
        timeout=120,
        env={**os.environ, "BIDEGREE_DEBUG": "1"},
    )
    assert debug.returncode == 2
    assert "bidegree: debug: panicked at" in debug.stderr and "deliberate panic" in debug.stderr


# ---------------------------------------------------------------------------------------------
# Memory: a request far above an address-space limit is refused, not an abort


def test_request_above_the_address_space_limit_is_a_memory_error(tmp_path: Path) -> None:
    path = tmp_path / "cube.obj"
    path.write_text(CUBE_OBJ)
    # 12 levels of a cube: about 100 million faces, many GB; the process may map 2 GiB.
    proc = cli(
        "subdivide",
        path,
        "-o",
        tmp_path / "o.obj",
        "--levels",
        "12",
        "--memory-budget",
        "64G",
        limits={resource.RLIMIT_AS: 2 << 30},
    )
    one_error_line(proc, "memory")
    assert files_in(tmp_path) == ["cube.obj"]


def python_child(
    script: str, limits: dict[int, int] | None = None
) -> subprocess.CompletedProcess[str]:
    """``script`` in a child Python (this one's interpreter and package) under resource limits
    (``RLIMIT_*: bytes``, set in the child before it starts)."""

    def limit() -> None:
        for which, value in (limits or {}).items():
            resource.setrlimit(which, (value, value))

    return subprocess.run(
        [sys.executable, "-c", script],
        check=False,
        capture_output=True,
        text=True,
        timeout=300,
        preexec_fn=limit,
    )


# The child prints the exception's class, its message and attributes on one line each.
REPORT = """
import bidegree, resource, sys
from cages import cube
def report(work):
    try:
        work()
    except Exception as exc:
        print(type(exc).__name__)
        print(exc)
        print(getattr(exc, "required", None), getattr(exc, "budget", None))
    else:
        print("no error")
    print(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss)  # KiB
"""


def child_report(work: str, limits: dict[int, int] | None = None) -> tuple[str, str, str, int]:
    tests = Path(__file__).parent
    proc = python_child(f"import sys; sys.path.insert(0, {str(tests)!r})\n{REPORT}\n{work}", limits)
    assert proc.returncode == 0, (proc.returncode, proc.stdout, proc.stderr)
    name, message, figures, peak = proc.stdout.splitlines()[-4:]
    return name, message, figures, int(peak)


def test_api_request_above_the_address_space_limit_is_a_memory_budget_error() -> None:
    # The estimate (tens of GB) is within the budget, and within the machine's memory on a
    # large machine: the core's allocations fail under the 2 GiB limit and are refused.
    name, message, figures, _ = child_report(
        "report(lambda: bidegree.subdivide(cube(), degree=3, levels=12, memory_budget=64 << 30))",
        limits={resource.RLIMIT_AS: 2 << 30},
    )
    assert name == "MemoryBudgetError", (name, message)
    assert "out of memory" in message or "memory budget" in message
    required, budget = (int(x) for x in figures.split())
    assert required > 0 and budget > 0


def test_large_requests_keep_address_space_free_for_the_small_ones() -> None:
    # Under an address-space limit the core refuses a large allocation (1 MiB or more) that
    # would leave less than ADDRESS_SPACE_HEADROOM free: the small allocations nothing can make
    # fallible (rayon's jobs, a vector's growth in a walk) would otherwise be the ones to fail,
    # and abort. Here the limit leaves 40 MiB, under the headroom: a subdivision whose largest
    # buffers are a few MiB (it needs about 25 MiB in all, so it would fit) is refused, typed;
    # one of small buffers still runs.
    work = """
from bidegree._native import ADDRESS_SPACE_HEADROOM
assert ADDRESS_SPACE_HEADROOM == 64 << 20, ADDRESS_SPACE_HEADROOM
bidegree.subdivide(cube(), degree=3, levels=3)  # the thread pool and its arenas first
size = int(open("/proc/self/status").read().split("VmSize:")[1].split()[0]) * 1024
resource.setrlimit(resource.RLIMIT_AS, (size + (40 << 20), size + (40 << 20)))
assert len(bidegree.subdivide(cube(), degree=3, levels=3).points) == 386
report(lambda: bidegree.subdivide(cube(), degree=3, levels=7))
"""
    name, message, _, _ = child_report(work)
    assert name == "MemoryBudgetError", (name, message)
    assert message.startswith("out of memory: "), message


@pytest.mark.skipif(bidegree._native.MACHINE_MEMORY is None, reason="machine memory unknown here")
def test_budget_above_the_machine_memory_is_refused_before_any_work() -> None:
    machine = bidegree._native.MACHINE_MEMORY
    assert machine is not None and 0 < bidegree.DEFAULT_MEMORY_BUDGET <= machine
    # 14 levels of a cube: hundreds of GB estimated, under a budget of 1 PiB. The 16 GiB
    # address-space limit only keeps a regression from taking the shared machine down.
    name, message, figures, peak = child_report(
        "report(lambda: bidegree.subdivide(cube(), levels=14, memory_budget=1 << 50))",
        limits={resource.RLIMIT_AS: 16 << 30},
    )
    assert name == "MemoryBudgetError", (name, message)
    assert "out of memory" in message and "this process can have about" in message
    required, budget = (int(x) for x in figures.split())
    assert budget == machine < required
    assert peak < 1 << 20  # KiB: refused from the estimate, nothing of its size was allocated


def test_numpy_allocation_failure_is_a_memory_budget_error() -> None:
    # An int32 faces array fits; its int64 copy (the mesh's index type) does not.
    name, message, _, _ = child_report(
        """
import numpy as np
faces = np.zeros((25_000_000, 4), dtype=np.int32)  # 400 MB; its int64 copy takes 800 MB
size = int(open("/proc/self/status").read().split("VmSize:")[1].split()[0]) * 1024
resource.setrlimit(resource.RLIMIT_AS, (size + (400 << 20), size + (400 << 20)))
report(lambda: bidegree.Mesh(np.zeros((4, 3)), faces))
"""
    )
    assert name == "MemoryBudgetError", (name, message)
    assert message.startswith("out of memory: Unable to allocate"), message


def test_adaptive_refusals_say_when_they_came() -> None:
    # Issue 18 item 2: tolerance 0 knows the result's size, so it is refused before any work; a
    # tiny tolerance under a small budget stops before making the level whose estimate passes
    # it, and says which (``level``).
    points = CUBE_POINTS.astype(np.float64).copy()
    points[6] += 0.8
    bumped = bidegree.Mesh(points, CUBE_FACES)
    with pytest.raises(bidegree.MemoryBudgetError) as before:
        bidegree.subdivide_adaptive(bumped, degree=4, tolerance=0, max_level=16)
    assert str(before.value).startswith("adaptive subdivision refused before any work: "), str(
        before.value
    )
    assert before.value.required > before.value.budget
    assert getattr(before.value, "level", None) is None
    with pytest.raises(bidegree.MemoryBudgetError) as stopped:
        bidegree.subdivide_adaptive(
            bumped, degree=4, tolerance=1e-14, max_level=16, memory_budget=32 << 20
        )
    level = stopped.value.level
    assert level > 1, str(stopped.value)
    assert str(stopped.value).startswith(
        f"adaptive subdivision stopped before making level {level} (levels 1..={level - 1} "
    ), str(stopped.value)
    assert stopped.value.budget == 32 << 20


def test_analysis_of_a_huge_valence_is_a_memory_budget_error() -> None:
    # The dense subdivision matrix of degree 9 at valence 1000 has about 30,000^2 entries (14 GB
    # with its columns): refused before it is made, not an abort (the child's address-space
    # limit makes sure nothing of that size is asked for).
    name, message, figures, peak = child_report(
        "import bidegree.analyze\nreport(lambda: bidegree.analyze.analyze(9, 1000, steps=0))",
        limits={resource.RLIMIT_AS: 3 << 30},
    )
    assert name == "MemoryBudgetError", (name, message)
    assert "over the memory budget" in message, message
    required, budget = (int(x) for x in figures.split())
    assert required > 8 << 30 and budget == bidegree.DEFAULT_MEMORY_BUDGET
    assert peak < 1 << 20  # KiB: under 1 GiB


def test_adaptive_request_above_the_address_space_limit_is_a_memory_budget_error() -> None:
    # The reproducer: tolerance 0 refines everywhere to level 16 (refused, or stopped
    # cleanly, within the default budget); the process may map 2 GiB.
    name, message, _, _ = child_report(
        "report(lambda: bidegree.subdivide_adaptive(cube(), degree=3, tolerance=0, max_level=16))",
        limits={resource.RLIMIT_AS: 2 << 30},
    )
    assert name == "MemoryBudgetError", (name, message)
