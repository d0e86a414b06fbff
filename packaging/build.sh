#!/usr/bin/env bash
# Build the bidegree wheel and the Blender extension zip (one command).
#
#   packaging/build.sh            -> dist/bidegree-*.whl and dist/bidegree-<version>.zip
#
# 1. abi3 manylinux_2_28 wheel with `maturin build --release --zig --compatibility manylinux_2_28`
#    (ziglang is pip-installed into the venv first); if zig fails, falls back to a plain
#    `maturin build --release` and says so.
# 2. Stages addon/bidegree with the wheel in wheels/ (manifest rewritten to name that wheel).
#    numpy is not bundled: Blender ships it.
# 3. Builds and validates the extension zip with Blender's own extension tool
#    (bl_pkg/cli/blender_ext.py from the bpy wheel, run as a plain script).
#
# Environment: VENV (default <repo>/.venv), DIST (default <repo>/dist),
#   BIDEGREE_NO_ZIG=1 skips zig/manylinux_2_28 (plain `maturin build --release`, reuses the cargo
#   cache of `maturin develop --release`: the fast path used by the Blender tests).
set -euo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
VENV="${VENV:-$ROOT/.venv}"
DIST="${DIST:-$ROOT/dist}"
PY="$VENV/bin/python"

log() { printf '[build] %s\n' "$*" >&2; }

[ -x "$PY" ] || { log "no Python at $PY (run scripts/bootstrap.sh first)"; exit 2; }
mkdir -p "$DIST"

# --- tools -----------------------------------------------------------------
if ! "$PY" -c "import maturin" 2>/dev/null && [ ! -x "$VENV/bin/maturin" ]; then
    log "installing maturin into $VENV"
    "$PY" -m pip install --quiet "maturin>=1.7,<2"
fi
MATURIN="$VENV/bin/maturin"
NO_ZIG="${BIDEGREE_NO_ZIG:-0}"
if [ "$NO_ZIG" != "1" ] && ! "$PY" -c "import ziglang" 2>/dev/null; then
    log "installing ziglang into $VENV"
    "$PY" -m pip install --quiet ziglang || log "could not install ziglang (will fall back)"
fi

# --- wheel -----------------------------------------------------------------
WHEEL_DIR="$(mktemp -d)"
trap 'rm -rf "$WHEEL_DIR"' EXIT
cd "$ROOT/native/python"
export PATH="$VENV/bin:$PATH"
if [ "$NO_ZIG" = "1" ]; then
    log "BIDEGREE_NO_ZIG=1: plain 'maturin build --release' (wheel tagged for this host's glibc)"
    "$MATURIN" build --release --out "$WHEEL_DIR"
elif "$MATURIN" build --release --zig --compatibility manylinux_2_28 --out "$WHEEL_DIR"; then
    log "built manylinux_2_28 wheel with zig"
else
    log "WARNING: 'maturin build --zig --compatibility manylinux_2_28' failed;"
    log "WARNING: falling back to a plain 'maturin build --release' (wheel tagged for this host's glibc)"
    rm -f "$WHEEL_DIR"/*.whl
    "$MATURIN" build --release --out "$WHEEL_DIR"
fi
WHEEL="$(ls -t "$WHEEL_DIR"/bidegree-*.whl | head -n 1)"
WHEEL_NAME="$(basename "$WHEEL")"
rm -f "$DIST"/bidegree-*.whl
cp "$WHEEL" "$DIST/"
log "wheel: $DIST/$WHEEL_NAME"

# --- extension -------------------------------------------------------------
find_blender_ext() {
    find "$("$PY" -c 'import sysconfig; print(sysconfig.get_paths()["purelib"])')/bpy" \
        -path '*bl_pkg/cli/blender_ext.py' 2>/dev/null | head -n 1
}
BLENDER_EXT="$(find_blender_ext)"
if [ -z "$BLENDER_EXT" ]; then
    log "installing bpy into $VENV (it carries Blender's extension tool, blender_ext.py)"
    "$PY" -m pip install --quiet "bpy==5.0.*"
    BLENDER_EXT="$(find_blender_ext)"
fi
[ -n "$BLENDER_EXT" ] || { log "blender_ext.py not found in the bpy package of $VENV"; exit 2; }

STAGE="$DIST/extension-staging"
rm -rf "$STAGE"
mkdir -p "$STAGE/bidegree/wheels"
(cd "$ROOT/addon/bidegree" && tar --exclude='__pycache__' --exclude='*.pyc' --exclude='wheels' -cf - .) \
    | (cd "$STAGE/bidegree" && tar -xf -)
cp "$DIST/$WHEEL_NAME" "$STAGE/bidegree/wheels/"
# Point the manifest at the wheel actually built (and nothing else).
"$PY" - "$STAGE/bidegree/blender_manifest.toml" "$WHEEL_NAME" <<'EOF'
import re, sys
path, wheel = sys.argv[1], sys.argv[2]
text = open(path, encoding="utf-8").read()
text, n = re.subn(r"(?m)^wheels\s*=\s*\[.*?\]", f'wheels = ["./wheels/{wheel}"]', text, flags=re.S)
if n != 1:
    sys.exit(f"{path}: expected exactly one 'wheels = [...]' line, found {n}")
open(path, "w", encoding="utf-8").write(text)
EOF

rm -f "$DIST"/bidegree-*.zip
"$PY" "$BLENDER_EXT" build --source-dir "$STAGE/bidegree" --output-dir "$DIST"
ZIP="$(ls -t "$DIST"/bidegree-*.zip | head -n 1)"
"$PY" "$BLENDER_EXT" validate "$ZIP"
# numpy must not be bundled (Blender ships it); the bidegree wheel must be.
"$PY" - "$ZIP" <<'EOF'
import sys, zipfile
names = zipfile.ZipFile(sys.argv[1]).namelist()
if any("numpy" in n.lower() for n in names):
    sys.exit(f"{sys.argv[1]}: numpy must not be bundled")
if not any(n.startswith("wheels/bidegree-") for n in names):
    sys.exit(f"{sys.argv[1]}: the bidegree wheel is missing")
EOF
log "extension: $ZIP"
echo "$ZIP"
