"""The batch on dask.distributed (issue 17): a real LocalCluster of worker processes, a real
scheduler and worker started as a farm starts them, a worker killed mid-file."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from conftest import (
    BATCH,
    assert_same_outputs,
    blend_meshes,
    output_files,
    progress_lines,
    read_manifest,
    run_batch,
    usd_text,
)

SIX = ["cube", "nonfinite", "grid", "scene", "garbage", "monkey"]
FAILURES = {
    "nonfinite.blend": "NonFiniteError: object 'nonfinite': vertex 0 has a non-finite position",
    "garbage.blend": "RuntimeError: Error: Loading",
}


def test_local_cluster_matches_the_local_batch(inputs: dict[str, Path], tmp_path: Path) -> None:
    files = [inputs[k] for k in SIX]
    local, farm = tmp_path / "local", tmp_path / "farm"
    for out, extra in ((local, []), (farm, ["--workers", "2"])):
        proc = run_batch(*files, "--out", out, "--usd", "--levels", "2", *extra, cwd=tmp_path)
        assert proc.returncode == 1, proc.stdout + proc.stderr
        lines = progress_lines(proc.stdout)
        assert len(lines) == 6, proc.stdout
        for name, message in FAILURES.items():
            (line,) = [ln for ln in lines if f"{name}: FAILED" in ln]
            assert message in line
            assert f"failed: {inputs[name.split('.')[0]]}: {message}" in proc.stdout
        assert "bidegree batch: 4 done, 2 failed, 0 skipped" in proc.stdout

    names = output_files(local)
    assert len(names) == 9  # 4 .blend, 5 USD (scene.blend has two objects)
    assert output_files(farm) == names
    assert_same_outputs(local, farm, names)

    manifest = read_manifest(farm)
    assert set(manifest) == {p.name for p in files}
    for name, entry in manifest.items():
        assert entry["status"] == ("failed" if name in FAILURES else "done"), entry
        assert entry["attempts"] == 1
        assert (entry["degree"], entry["levels"]) == (4, 2)
        if name not in FAILURES:
            assert entry["worker"].startswith("tcp://127.0.0.1:")
    local_manifest = read_manifest(local)
    for name, entry in manifest.items():
        ours, theirs = entry["outputs"], local_manifest[name]["outputs"]
        assert [o["path"] for o in ours] == [o["path"] for o in theirs], name
        # USD files are byte for byte the same (a .blend holds pointers and is not).
        usd = [o for o in ours if not o["path"].endswith(".blend")]
        assert usd == [o for o in theirs if not o["path"].endswith(".blend")], name
    assert len({e["worker"] for n, e in manifest.items() if n not in FAILURES}) == 2


def _kill_writers(proc: subprocess.Popen[str], out: Path, stem: str, kills: int) -> list[int]:
    """SIGKILL each worker seen writing ``stem``'s outputs, up to ``kills`` of them, then wait.

    A worker names itself in its partial folder, ``.bidegree-partial/<stem>@<host>-<pid>-<n>``;
    it is killed once the first output is in there (mid-write).
    """
    killed: list[int] = []
    deadline = time.monotonic() + 300
    while len(killed) < kills and proc.poll() is None and time.monotonic() < deadline:
        for folder in (out / ".bidegree-partial").glob(f"{stem}@*"):
            pid = int(folder.name.split("@")[1].split("-")[-2])
            if pid not in killed and any(folder.iterdir()):
                os.kill(pid, signal.SIGKILL)
                killed.append(pid)
        time.sleep(0.002)
    return killed


def _start(files: list[Path], out: Path, *extra: str) -> subprocess.Popen[str]:
    return subprocess.Popen(
        [*BATCH, *map(str, files), "--out", str(out), "--levels", "3", "--usd", *extra],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        cwd=str(out.parent),
    )


def test_a_killed_worker_is_retried(inputs: dict[str, Path], tmp_path: Path) -> None:
    out = tmp_path / "out"
    proc = _start([inputs["slow"], inputs["cube"], inputs["grid"]], out, "--workers", "2")
    try:
        killed = _kill_writers(proc, out, "slow", 1)
        stdout, stderr = proc.communicate(timeout=300)
    finally:
        proc.kill()
    assert len(killed) == 1, "slow.blend was never seen mid-write"
    assert proc.returncode == 0, stdout + stderr
    assert "bidegree batch: 3 done, 0 failed" in stdout
    (line,) = [ln for ln in progress_lines(stdout) if "slow.blend" in ln]
    # Exactly 2: one worker died holding the task and nothing else may cost it an attempt (a
    # retry used by an OSError shows as "Compute Failed" in the workers' log, in stderr).
    assert "after 2 attempts" in line, stdout + stderr

    manifest = read_manifest(out)
    assert manifest["slow.blend"]["attempts"] == 2, stdout + stderr
    # A file that was waiting in the killed worker's queue counts an attempt too (distributed
    # counts it towards allowed-failures): with 3 files for 2 workers it may have been.
    assert manifest["cube.obj"]["attempts"] in (1, 2) and manifest["grid.obj"]["attempts"] in (1, 2)
    expected = {o["path"] for e in manifest.values() for o in e["outputs"]}
    assert len(expected) == 2 + 2 + 4  # slow.blend: a .blend and one USD per Suzanne
    assert output_files(out) == expected  # nothing partial, no partial folder left
    for entry in manifest.values():
        for o in entry["outputs"]:
            assert (out / o["path"]).stat().st_size == o["bytes"]
    assert len(blend_meshes(out / "slow.bidegree.blend")) == 3
    assert "def Mesh" in usd_text(out / "slow_Suzanne.001.usdc")


def test_a_partial_root_removed_meanwhile_costs_no_attempt(
    inputs: dict[str, Path], tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Workers share ``OUT/.bidegree-partial``: each removes it when it finds it empty (a file of
    its own started or finished). One doing so between ``os.makedirs``' check that the folder is
    there and its ``mkdir`` of another worker's partial folder must not fail that file's attempt
    (an ``OSError`` there is retried, and counted, by distributed)."""
    from bidegree.options import Options
    from bidegree_blender.batch.convert import PARTIAL_DIR, Job, convert_file

    out = tmp_path / "out"
    out.mkdir()
    mkdir, raced = os.mkdir, []

    def racing_mkdir(path: Any, mode: int = 0o777, **kwargs: Any) -> None:
        if Path(path).parent.name == PARTIAL_DIR and not raced:
            raced.append(path)
            os.rmdir(Path(path).parent)  # the other worker's rmdir, just then
        mkdir(path, mode, **kwargs)

    monkeypatch.setattr(os, "mkdir", racing_mkdir)
    record = convert_file(str(inputs["cube"]), Job(str(out), Options(levels=1)))
    monkeypatch.undo()
    assert raced
    assert record.ok, record.error
    assert output_files(out) == {"cube.bidegree.blend"}


@pytest.fixture
def scheduler(tmp_path: Path) -> Iterator[str]:
    """A dask scheduler and one worker started with distributed's own CLI.

    The worker has two threads: the batch still converts one file at a time in it, on one thread.
    """
    bindir = Path(sys.executable).parent
    info = tmp_path / "scheduler.json"
    procs = [
        subprocess.Popen(
            [
                *(bindir / "dask", "scheduler", "--host", "127.0.0.1", "--port", "0"),
                *("--no-dashboard", "--scheduler-file", str(info)),
            ],
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
            cwd=str(tmp_path),
        )
    ]
    try:
        deadline = time.monotonic() + 60
        while not info.exists() and time.monotonic() < deadline:
            time.sleep(0.1)
        address = json.loads(info.read_text())["address"]
        procs.append(
            subprocess.Popen(
                [bindir / "dask", "worker", address, *("--nthreads", "2", "--no-nanny")],
                stdout=subprocess.DEVNULL,
                stderr=subprocess.DEVNULL,
                cwd=str(tmp_path),
            )
        )
        yield address
    finally:
        for p in reversed(procs):
            p.terminate()
        for p in reversed(procs):
            try:
                p.wait(timeout=30)
            except subprocess.TimeoutExpired:
                p.kill()


def test_scheduler_and_resume(inputs: dict[str, Path], scheduler: str, tmp_path: Path) -> None:
    out = tmp_path / "out"
    files = [inputs["cube"], inputs["grid"], inputs["monkey"]]
    args = [*files, "--out", out, "--usda", "--levels", "1", "--scheduler", scheduler]
    proc = run_batch(*args, cwd=tmp_path)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert "3 done, 0 failed, 0 skipped" in proc.stdout
    first = read_manifest(out)
    assert {e["worker"] for e in first.values()} == {first["cube.obj"]["worker"]}  # one worker

    (out / "grid.usda").unlink()
    proc = run_batch(*args, "--resume", cwd=tmp_path)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    lines = progress_lines(proc.stdout)
    assert [ln.split(": ")[1].split(",")[0] for ln in lines] == ["skipped", "skipped", "ok"]
    assert "grid.obj: ok" in lines[2]
    assert "1 done, 0 failed, 2 skipped" in proc.stdout
    second = read_manifest(out)
    for name in ("cube.obj", "monkey.blend"):
        assert second[name] == first[name]  # untouched
    # The same USD bytes again (a .blend holds pointers and differs).
    assert second["grid.obj"]["outputs"][1] == first["grid.obj"]["outputs"][1]
    assert (out / "grid.usda").exists()


def test_a_file_that_keeps_killing_workers_fails_after_the_retries(
    inputs: dict[str, Path], tmp_path: Path
) -> None:
    out = tmp_path / "out"
    proc = _start([inputs["slow"]], out, "--workers", "2", "--retries", "1")
    try:
        killed = _kill_writers(proc, out, "slow", 3)
        stdout, stderr = proc.communicate(timeout=300)
    finally:
        proc.kill()
    assert len(killed) == 2, (killed, stdout + stderr)  # the first attempt and one retry
    assert proc.returncode == 1, stdout + stderr
    (line,) = progress_lines(stdout)
    assert "slow.blend: FAILED after 2 attempts: KilledWorker: " in line
    entry = read_manifest(out)["slow.blend"]
    assert (entry["status"], entry["attempts"], entry["outputs"]) == ("failed", 2, [])
    assert output_files(out) == set()
