#!/usr/bin/env bash
# The main job end to end: a headless Blender (bpy) batch run that subdivides a real mesh
# (Blender's Suzanne, saved as a .blend) at degree 4, writing the result (.blend) and a USD file
# into out/demo/.
set -euo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$ROOT"
bash scripts/bootstrap.sh
OUT="$ROOT/out/demo"
mkdir -p "$OUT"
.venv/bin/python scripts/make_demo_cage.py "$OUT/suzanne.blend"
.venv/bin/python -m bidegree_blender.batch "$OUT/suzanne.blend" --degree 4 --levels 2 --out "$OUT" --usd
ls -l "$OUT"
