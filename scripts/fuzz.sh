#!/usr/bin/env bash
# Hostile-input fuzzing for MINUTES (default 30): random polygon soups through the Python API
# and mutated OBJ files through the CLI, each case in a child process under an address-space
# limit (scripts/fuzz.py says how). Prints the counts of success / typed error / other; every
# "other" case is written to tests/fuzz_regressions/, which tests/test_hostile_fuzz.py replays.
# Exit status 1 when a case ended as "other". Extra arguments go to fuzz.py (--seed N, ...).
set -euo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
MINUTES="${1:-30}"
shift || true
bash "$ROOT/scripts/bootstrap.sh" >&2
exec "$ROOT/.venv/bin/python" "$ROOT/scripts/fuzz.py" --minutes "$MINUTES" "$@"
