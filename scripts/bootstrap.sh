#!/usr/bin/env bash
# Prepares a fresh machine (Python 3.11 and Rust given; nothing else assumed) and is cheap to
# re-run: a virtualenv at <repo>/.venv with bpy, usd-core, maturin, pytest, matplotlib and ruff
# (and the batch's farm extra: dask.distributed, tqdm; and openjd-cli);
# the bidegree wheel and the Blender extension zip built into dist/ (packaging/build.sh, host
# wheel); and that wheel installed into .venv, so `.venv/bin/bidegree` and
# `.venv/bin/python -c "import bidegree"` work.
set -euo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
VENV="$ROOT/.venv"
log() { printf '[bootstrap] %s\n' "$*" >&2; }

find_python() {
    for candidate in "${PYTHON:-}" python3.11 python3; do
        [ -n "$candidate" ] || continue
        if command -v "$candidate" >/dev/null 2>&1 &&
            "$candidate" -c 'import sys; sys.exit(sys.version_info[:2] != (3, 11))' 2>/dev/null; then
            echo "$candidate"
            return 0
        fi
    done
    return 1
}

if [ ! -x "$VENV/bin/python" ]; then
    PY311="$(find_python)" || { log "Python 3.11 is required (the bpy package exists only for 3.11)"; exit 2; }
    log "creating $VENV with $PY311"
    "$PY311" -m venv "$VENV"
fi
PY="$VENV/bin/python"

# Python dependencies (bpy pins numpy < 2; the numpy 2 run uses a second virtualenv).
if ! "$PY" -c "import bpy, pxr, maturin, pytest, matplotlib" >/dev/null 2>&1 || [ ! -x "$VENV/bin/ruff" ]; then
    log "installing Python dependencies into $VENV"
    "$PY" -m pip install --quiet --upgrade pip
    "$PY" -m pip install --quiet "bpy==5.0.*" "usd-core>=24.8" "maturin>=1.7,<2" pytest matplotlib ruff
fi

command -v cargo >/dev/null 2>&1 || { log "Rust (cargo) is required"; exit 2; }

# The wheel and the extension zip; then the wheel itself into the venv (not an editable
# install: tests and users import the installed package).
BIDEGREE_NO_ZIG="${BIDEGREE_NO_ZIG:-1}" bash "$ROOT/packaging/build.sh" >/dev/null
WHEEL="$(ls -t "$ROOT"/dist/bidegree-*.whl | head -n 1)"
log "installing $(basename "$WHEEL") into $VENV"
"$PY" -m pip install --quiet --force-reinstall --no-deps "$WHEEL"
# The batch's optional 'farm' extra (dask.distributed, tqdm) from the wheel's own metadata, and
# the Open Job Description CLI that checks and runs packaging/openjd/template.yaml (tests).
if ! "$PY" -c "import distributed, tqdm" >/dev/null 2>&1 || [ ! -x "$VENV/bin/openjd" ]; then
    log "installing the farm extra (dask.distributed, tqdm) and openjd-cli into $VENV"
    "$PY" -m pip install --quiet "$WHEEL[farm]" "openjd-cli>=0.8"
fi
"$PY" -c "import bidegree; print('[bootstrap] bidegree', bidegree.__version__, 'ready in', '$VENV')" >&2
