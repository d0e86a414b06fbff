"""Replays the fuzzer's regression files (``tests/fuzz_regressions/*.json``, written by
``scripts/fuzz.sh``): each case, once an abort, an internal error or another untyped outcome,
must now end as a result or a typed error. Also checks that the harness itself tells those
outcomes apart and runs."""

from __future__ import annotations

import json
import re
import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "scripts"))
import fuzz  # noqa: E402

CASES = sorted((ROOT / "tests" / "fuzz_regressions").glob("*.json"))


def _param(path: Path) -> object:
    reason = json.loads(path.read_text()).get("xfail")
    marks = [pytest.mark.xfail(strict=True, reason=reason)] if reason else []
    return pytest.param(path, id=path.stem, marks=marks)


@pytest.mark.parametrize("path", [_param(p) for p in CASES])
def test_regression_ends_as_a_result_or_a_typed_error(path: Path) -> None:
    outcome = fuzz.replay(path)
    assert outcome["outcome"] in ("success", "typed"), outcome


@pytest.mark.parametrize("mib", [384, 512, 640])
def test_a_deep_limit_under_a_tighter_address_space_is_a_memory_error(
    monkeypatch: pytest.MonkeyPatch, mib: int
) -> None:
    # The seed-1202 case (limit positions of degree 5 at 10 levels) fits the fuzzer's 3 GiB
    # (a SIGABRT before the limit's allocations were fallible). Since the limit extends only
    # around the cube's corners it fits 1 GiB too (832 MiB since its partial levels keep only
    # the children near the stencils' vertices, 768 MiB since limit tiles hold the regular
    # vertices without stencils); below that, wherever the address space runs out (the plan,
    # the stencils, the local extension's level-sized maps), the outcome is a typed
    # MemoryBudgetError, never a signal.
    monkeypatch.setattr(fuzz, "ADDRESS_SPACE", mib << 20)
    path = ROOT / "tests" / "fuzz_regressions" / "api-signal-sigabrt-fuzz1202-1.json"
    outcome = fuzz.replay(path)
    assert (outcome["outcome"], outcome["label"]) == ("typed", "MemoryBudgetError"), outcome
    assert outcome["detail"].startswith("out of memory: "), outcome


CUBE = [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0, 0, 1], [1, 0, 1], [1, 1, 1], [0, 1, 1]]
CUBE_FACES = [[0, 3, 2, 1], [4, 5, 6, 7], [0, 1, 5, 4], [1, 2, 6, 5], [2, 3, 7, 6], [3, 0, 4, 7]]


def _api_spec(**changes: object) -> dict[str, object]:
    spec = fuzz.gen_api(np.random.default_rng(0))
    spec.update(
        call="subdivide",
        dtype="float64",
        points=CUBE,
        faces=CUBE_FACES,
        creases=[],
        corners=[],
        uvs=None,
        degree=3,
        levels=1,
        output="primal",
        rules="averaging",
        limit=False,
        normals=False,
        memory_budget=None,
    )
    spec.update(changes)
    return spec


@pytest.mark.parametrize(
    ("changes", "outcome", "label"),
    [
        ({}, "success", "success"),
        ({"faces": [[0, 1, 1, 0]]}, "typed", "RepeatedVertexError"),
        ({"call": "panic"}, "other", "InternalError native/python/src/errors.rs"),
        ({"call": "abort"}, "other", "signal SIGABRT"),
    ],
    ids=["result", "typed", "panic", "abort"],
)
def test_the_harness_tells_outcomes_apart(
    changes: dict[str, object], outcome: str, label: str
) -> None:
    got = fuzz.run_case(_api_spec(**changes), fresh=True)
    assert (got["outcome"], got["label"]) == (outcome, label), got


def test_the_harness_runs(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    # A few cases of each kind from a fixed seed (each API case in a new interpreter: this
    # process has used the core, so it must not fork), to keep the script working.
    args = ["--cases", "6", "--seed", "7", "--cli-share", "0.5", "--fresh", "--out", str(tmp_path)]
    status = fuzz.main(args)
    counts = re.search(r"success (\d+), typed error (\d+), other (\d+)", capsys.readouterr().out)
    assert counts is not None
    assert sum(map(int, counts.groups())) == 6
    assert status == (1 if int(counts.group(3)) else 0)
