#!/usr/bin/env bash
# Runs every test: formatting and lints, the Rust tests (release mode), the Python, USD and
# OpenSubdiv-comparison tests under numpy 1.26 (the .venv that has bpy 5.0), the Blender tests
# against the installed extension (their own process), the batch tests (their own process: bpy,
# dask, openjd), the same Blender tests under the manifest's minimum Blender (bpy 4.2 LTS, a
# second virtualenv: they take ~20 s, so all of them run there), and the Python API tests once
# more under numpy 2.x in a third virtualenv.
set -euo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$ROOT"
log() { printf '\n[test] %s\n' "$*" >&2; }

bash scripts/bootstrap.sh
PY="$ROOT/.venv/bin/python"

log "formatting and lints"
cargo fmt --all -- --check
cargo clippy --workspace --all-targets --release -- -D warnings
"$ROOT/.venv/bin/ruff" check native/python/python addon tests packaging scripts
"$ROOT/.venv/bin/ruff" format --check native/python/python addon tests packaging scripts

log "Rust tests"
cargo test --release -p bidegree

log "Python, USD and OpenSubdiv tests (numpy $("$PY" -c 'import numpy; print(numpy.__version__)'))"
"$PY" -m pytest -q tests --ignore=tests/blender --ignore=tests/batch

log "Blender tests (real bpy, the built extension installed)"
"$PY" -m pytest -q tests/blender

log "Batch tests (real bpy, a dask LocalCluster and scheduler with worker processes, openjd)"
"$PY" -m pytest -q tests/batch

log "Blender tests under the manifest's minimum Blender ($(sed -n 's/^blender_version_min = "\(.*\)"/\1/p' addon/bidegree/blender_manifest.toml): bpy 4.2 LTS)"
BPY42="$ROOT/.venv-bpy42"
if [ ! -x "$BPY42/bin/python" ]; then
    "$("$PY" -c 'import sys; print(sys._base_executable)')" -m venv "$BPY42"
fi
if ! "$BPY42/bin/python" -c 'import bpy, pxr, pytest, sys; sys.exit(bpy.app.version[:2] != (4, 2))' 2>/dev/null; then
    "$BPY42/bin/python" -m pip install --quiet "bpy==4.2.*" "usd-core>=24.8" pytest
fi
"$BPY42/bin/python" -m pip install --quiet --force-reinstall --no-deps "$(ls -t dist/bidegree-*.whl | head -n 1)"
"$BPY42/bin/python" -m pytest -q tests/blender -p no:cacheprovider

log "Python API tests under numpy 2"
NP2="$ROOT/.venv-numpy2"
if [ ! -x "$NP2/bin/python" ]; then
    "$("$PY" -c 'import sys; print(sys._base_executable)')" -m venv "$NP2"
fi
if ! "$NP2/bin/python" -c 'import numpy, pytest, sys; sys.exit(int(numpy.__version__.split(".")[0]) < 2)' 2>/dev/null; then
    "$NP2/bin/python" -m pip install --quiet "numpy>=2" pytest
fi
"$NP2/bin/python" -m pip install --quiet --force-reinstall --no-deps "$(ls -t dist/bidegree-*.whl | head -n 1)"
"$NP2/bin/python" -m pytest -q tests/test_api.py tests/test_cli.py -p no:cacheprovider
