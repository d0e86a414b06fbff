"""``bidegree analyze``: the paper's §4 analysis from the command line and from Python."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import bidegree
import numpy as np
import pytest
from bidegree import _native, analyze


def run_cli(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "bidegree", "analyze", *args],
        capture_output=True,
        text=True,
        timeout=120,
    )


def test_cli_reports_c1_and_the_biquartic_subdominant_eigenvalue(tmp_path: Path) -> None:
    done = run_cli("--degree", "4", "--valence", "5", "--plot", str(tmp_path / "plots"))
    assert done.returncode == 0, done.stderr
    assert "C1: yes" in done.stdout
    # DESIGN.md: the biquartic subdominant eigenvalue at valence 5.
    assert "lambda1 = 0.568235" in done.stdout
    assert "C2: no" in done.stdout
    names = ["eigenvalues", "subdominant", "characteristic_map", "jacobian", "basis"]
    for name in names:
        png = tmp_path / "plots" / f"{name}.png"
        assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n", name
        assert png.stat().st_size > 20_000, name


def test_cli_refuses_bad_arguments(tmp_path: Path) -> None:
    done = run_cli("--degree", "4", "--valence", "2")
    assert done.returncode != 0
    assert "valence" in done.stderr and "Traceback" not in done.stderr
    (tmp_path / "file").write_text("x")
    done = run_cli("--plot", str(tmp_path / "file"))
    assert done.returncode != 0 and "not a directory" in done.stderr


def test_analysis_dict() -> None:
    result = _native.analyze(3, 5, 3)
    k, n = 5, 1 + 5 * 2 * 3
    assert result["matrix"].shape == (n, n)
    assert result["labels"].shape == (n, 3)
    assert result["eigenvalues"].dtype == np.complex128
    # The blocks' spectra are the matrix's (leading eigenvalues; the nilpotent part's zeros are
    # only known to a root of the deflation threshold).
    full = np.linalg.eigvals(result["matrix"])
    full = full[np.argsort(-np.abs(full))]
    ours = result["eigenvalues"]
    big = np.abs(ours) > 1e-2
    assert np.allclose(np.sort_complex(ours[big]), np.sort_complex(full[: big.sum()]), atol=1e-8)
    assert len(result["blocks"]) == k and result["blocks"][0].shape == (7, 7)
    assert result["c1"] and result["winding"] == 1 and result["jacobian_min"] > 0
    assert result["subdominant"][0].real == pytest.approx(0.549988, abs=1e-6)
    assert result["map_points"].shape[0] == k


def test_symbol_matches_the_blocks() -> None:
    # B(2 pi m / k) is the Fourier block of mode m at any valence (here from valence 8 to 5).
    symbol = analyze.Symbol(4)
    result = _native.analyze(4, 5, 0)
    for m in range(1, 5):
        assert np.allclose(symbol.block(2 * np.pi * m / 5), result["blocks"][m], atol=1e-14)
    assert symbol.subdominant(5) == pytest.approx(0.568235, abs=1e-6)


def test_errors_are_bidegree_errors() -> None:
    with pytest.raises(bidegree.BidegreeError):
        _native.analyze(40, 5)
    with pytest.raises(bidegree.BidegreeError):
        _native.basis_function(4, 5, 9)
