"""The batch on one machine: bad arguments, failures that leave nothing, files that do not stop
the run, untrusted scripts, the manifest and ``--resume`` (issues 17 and 18, items 8 and 11)."""

from __future__ import annotations

import subprocess
import sys
import time
from pathlib import Path

import bpy
import pytest
from conftest import (
    BATCH,
    CUBE_OBJ,
    output_files,
    progress_lines,
    read_manifest,
    run_batch,
    save_scene,
)


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--degree", "0"], "degree 0 is out of range"),
        (["--degree", "40"], "degree 40 is out of range"),
        (["--levels", "17"], "levels 17 is out of range"),
        (["--degree", "4", "--rules", "classic"], "classic rules exist for degrees 1 to 3"),
        (["--output", "dual", "--limit"], "use the primal output"),
        (["--workers", "0"], "--workers 0"),
        (["--retries", "-1"], "--retries -1"),
        (["--usd", "--usda"], "--usd and --usda"),
        (["--degree", "x"], "invalid int value: 'x'"),
        (["--workers", "2", "--scheduler", "tcp://127.0.0.1:1"], "not allowed with argument"),
        (["missing.obj"], "missing.obj: no such file"),
        (["notes.txt"], "notes.txt: not a .blend or .obj file"),
        (["cube.obj"], "cube.obj is given twice"),
        (["sub/cube.obj"], "both write cube.*"),
    ],
)
def test_bad_arguments_exit_2_before_any_work(
    tmp_path: Path, args: list[str], message: str
) -> None:
    (tmp_path / "cube.obj").write_text(CUBE_OBJ)
    (tmp_path / "sub").mkdir()
    (tmp_path / "sub" / "cube.obj").write_text(CUBE_OBJ)
    (tmp_path / "notes.txt").write_text("not a mesh\n")
    inputs = [a for a in args if a.endswith((".obj", ".txt"))]
    options = [a for a in args if a not in inputs]
    proc = run_batch("cube.obj", *inputs, "--out", "out", *options, cwd=tmp_path)
    assert proc.returncode == 2, proc.stdout + proc.stderr
    assert proc.stderr.count("\n") == 1 and "Traceback" not in proc.stderr, proc.stderr
    assert message in proc.stderr
    assert proc.stdout == ""
    assert not (tmp_path / "out").exists()  # nothing was done, not even the output folder


@pytest.mark.parametrize("where", ["a file", "under a file", "unwritable"])
def test_bad_output_folder_exits_2(tmp_path: Path, where: str) -> None:
    (tmp_path / "cube.obj").write_text(CUBE_OBJ)
    (tmp_path / "taken").write_text("the user's file\n")
    if where == "unwritable":
        out = Path("/proc/bidegree-out")  # cannot be created whatever the user's rights
    else:
        out = tmp_path / ("taken" if where == "a file" else "taken/out")
    proc = run_batch("cube.obj", "--out", out, cwd=tmp_path)
    assert proc.returncode == 2, proc.stdout + proc.stderr
    assert proc.stderr.count("\n") == 1 and "Traceback" not in proc.stderr, proc.stderr
    assert f"--out {out}" in proc.stderr
    assert (tmp_path / "taken").read_text() == "the user's file\n"


def test_a_failed_file_leaves_nothing(inputs: dict[str, Path], tmp_path: Path) -> None:
    # The USD output's name is taken by a folder: the .blend of the same file, already complete,
    # must not be left behind when its USD cannot be put in place.
    out = tmp_path / "out"
    (out / "cube.usdc").mkdir(parents=True)
    (out / "cube.usdc" / "keep.txt").write_text("mine\n")
    proc = run_batch(inputs["cube"], inputs["grid"], "--out", out, "--usd", cwd=tmp_path)
    assert proc.returncode == 1, proc.stdout + proc.stderr
    lines = progress_lines(proc.stdout)
    assert "cube.obj: FAILED: IsADirectoryError" in lines[0], lines
    assert "grid.obj: ok" in lines[1], lines
    assert output_files(out) == {"cube.usdc", "grid.bidegree.blend", "grid.usdc"}
    assert (out / "cube.usdc" / "keep.txt").read_text() == "mine\n"
    manifest = read_manifest(out)
    assert manifest["cube.obj"]["status"] == "failed" and manifest["cube.obj"]["outputs"] == []
    assert manifest["grid.obj"]["status"] == "done"


def test_the_batch_survives_any_single_file(inputs: dict[str, Path], tmp_path: Path) -> None:
    empty = save_scene(
        tmp_path / "empty.blend",
        lambda: bpy.context.scene.collection.objects.link(
            bpy.data.objects.new("Nothing", bpy.data.meshes.new("Nothing"))
        ),
    )
    bad_obj = tmp_path / "bad.obj"
    bad_obj.write_bytes(b"\xef\xbb\xbfv 0 0 0\nv 1 0\nf 1 2 9\n\x00\x01\x02binary junk\n")
    files = [empty, inputs["garbage"], bad_obj, inputs["nonfinite"], inputs["cube"]]
    out = tmp_path / "out"
    proc = run_batch(*files, "--out", out, "--usda", cwd=tmp_path)
    assert proc.returncode == 1, proc.stdout + proc.stderr
    lines = progress_lines(proc.stdout)
    assert len(lines) == 5, proc.stdout
    for line, path in zip(lines[:4], files[:4], strict=True):
        assert f"{path}: FAILED: " in line
    assert "garbage.blend: FAILED: RuntimeError" in lines[1]
    assert "nonfinite.blend: FAILED: NonFiniteError" in lines[3]
    assert "cube.obj: ok" in lines[4]
    assert output_files(out) == {"cube.bidegree.blend", "cube.usda"}
    summary = proc.stdout.splitlines()[-5:]
    assert summary[0].startswith("bidegree batch: 1 done, 4 failed, 0 skipped")
    assert [s.split(": ", 2)[1] for s in summary[1:]] == [str(p) for p in files[:4]]


def _script_blend(path: Path, marker: Path) -> Path:
    """A .blend whose registered text block writes ``marker`` when the file's scripts run."""

    def build() -> None:
        bpy.ops.mesh.primitive_cube_add()
        text = bpy.data.texts.new("startup.py")
        text.write(f"open({str(marker)!r}, 'w').write('the script ran')\n")
        text.use_module = True  # "Register": runs when the file is loaded with scripts on

    return save_scene(path, build)


def test_input_scripts_run_only_when_trusted(tmp_path: Path) -> None:
    marker = tmp_path / "marker"
    blend = _script_blend(tmp_path / "asset.blend", marker)
    # The batch inside a Blender whose preferences allow Auto Run Python Scripts.
    run = (
        "import sys, bpy; "
        "bpy.context.preferences.filepaths.use_scripts_auto_execute = True; "
        "from bidegree_blender.batch import main; sys.exit(main(sys.argv[1:]))"
    )
    for trusted in (False, True):
        proc = subprocess.run(
            [sys.executable, "-c", run, str(blend), "--out", str(tmp_path / "out")]
            + (["--trust-scripts"] if trusted else []),
            capture_output=True,
            text=True,
            timeout=300,
            check=False,
        )
        assert proc.returncode == 0, proc.stdout + proc.stderr
        assert "asset.blend: ok" in proc.stdout
        assert marker.exists() == trusted, (trusted, proc.stdout + proc.stderr)


def test_manifest_and_resume(inputs: dict[str, Path], tmp_path: Path) -> None:
    out = tmp_path / "out"
    files = [inputs["cube"], inputs["scene"]]
    proc = run_batch(*files, "--out", out, "--usd", "--levels", "1", cwd=tmp_path)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    manifest = read_manifest(out)
    assert set(manifest) == {"cube.obj", "scene.blend"}
    scene = manifest["scene.blend"]
    assert scene["status"] == "done" and scene["attempts"] == 1 and scene["worker"] == "local"
    assert (scene["degree"], scene["levels"], scene["objects"]) == (4, 1, 2)
    assert [o["path"] for o in scene["outputs"]] == [
        "scene.bidegree.blend",
        "scene_Arrayed.usdc",
        "scene_Prism.usdc",
    ]
    for o in scene["outputs"]:
        assert (out / o["path"]).stat().st_size == o["bytes"]
    assert output_files(out) == {
        "cube.bidegree.blend",
        "cube.usdc",
        *(o["path"] for o in scene["outputs"]),
    }

    # Delete one output: --resume redoes that file only.
    (out / "scene_Prism.usdc").unlink()
    proc = run_batch(*files, "--out", out, "--usd", "--levels", "1", "--resume", cwd=tmp_path)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    lines = progress_lines(proc.stdout)  # skipped files first, then the work
    assert "cube.obj: skipped" in lines[0] and "scene.blend: ok" in lines[1], lines
    assert "1 done, 0 failed, 1 skipped" in proc.stdout
    redone = read_manifest(out)["scene.blend"]["outputs"]
    assert [o["bytes"] for o in redone] == [(out / o["path"]).stat().st_size for o in redone]

    # A truncated output, and other settings, are not "done" either.
    (out / "cube.usdc").write_bytes((out / "cube.usdc").read_bytes()[:100])
    proc = run_batch(*files, "--out", out, "--usd", "--levels", "1", "--resume", cwd=tmp_path)
    lines = progress_lines(proc.stdout)
    assert "scene.blend: skipped" in lines[0] and "cube.obj: ok" in lines[1], lines
    proc = run_batch(*files, "--out", out, "--usd", "--levels", "2", "--resume", cwd=tmp_path)
    assert "2 done, 0 failed, 0 skipped" in proc.stdout, proc.stdout
    assert {e["levels"] for e in read_manifest(out).values()} == {2}


def test_sigterm_leaves_no_partial_output(inputs: dict[str, Path], tmp_path: Path) -> None:
    out = tmp_path / "out"
    proc = subprocess.Popen(
        [*BATCH, str(inputs["slow"]), "--out", str(out), "--levels", "3", "--usd"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    partial = out / ".bidegree-partial"
    try:
        while proc.poll() is None and not any(partial.glob("slow@*/*")):
            time.sleep(0.005)  # until the first output of the file is being written
        proc.terminate()
        stdout, stderr = proc.communicate(timeout=120)
    finally:
        proc.kill()
    assert proc.returncode == 128 + 15, stdout + stderr
    assert "interrupted" in stderr
    assert output_files(out) == set()  # no output, no partial folder
    assert "bidegree-manifest.json" not in {p.name for p in out.iterdir()}
