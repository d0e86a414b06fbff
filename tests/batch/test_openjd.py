"""The Open Job Description job template (issue 17): ``openjd check`` accepts it and
``openjd run`` (the reference runtime, openjd-cli) converts files with it on this machine."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

from conftest import ROOT, output_files, read_manifest, usd_text

TEMPLATE = ROOT / "packaging" / "openjd" / "template.yaml"
OPENJD = Path(sys.executable).parent / "openjd"


def _openjd(*args: str, cwd: Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [str(OPENJD), *args],
        capture_output=True,
        text=True,
        cwd=str(cwd),
        timeout=600,
        check=False,
    )


def test_template_passes_openjd_check(tmp_path: Path) -> None:
    proc = _openjd("check", str(TEMPLATE), cwd=tmp_path)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert "passes validation checks" in proc.stdout


def test_openjd_run_converts_two_files(inputs: dict[str, Path], tmp_path: Path) -> None:
    out = tmp_path / "out"
    params = tmp_path / "params.json"
    params.write_text(
        json.dumps(
            {
                "Inputs": [str(inputs["cube"]), str(inputs["monkey"])],
                "OutputDir": str(out),
                "Degree": 3,
                "Levels": 1,
                "Usd": "usda",
                "Python": sys.executable,
            }
        )
    )
    proc = _openjd("run", str(TEMPLATE), "--job-param", f"file://{params}", cwd=tmp_path)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert "Chunks run: 2" in proc.stdout  # one task per input file
    assert output_files(out) == {
        "cube.bidegree.blend",
        "cube.usda",
        "monkey.bidegree.blend",
        "monkey.usda",
    }
    manifest = read_manifest(out)  # both tasks' entries: merged, not overwritten
    assert set(manifest) == {"cube.obj", "monkey.blend"}
    for entry in manifest.values():
        assert entry["status"] == "done"
        assert (entry["degree"], entry["levels"], entry["settings"]["usd"]) == (3, 1, "usda")
    assert "bidegree:degree = 3" in usd_text(out / "monkey.usda")
