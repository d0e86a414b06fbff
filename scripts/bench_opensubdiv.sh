#!/usr/bin/env bash
# The benchmark against OpenSubdiv's C++ library (issue 5; not a test). Installs what it needs
# (Debian/Ubuntu: libosd-dev and g++ through apt-get, with sudo when not root), compiles
# bench/opensubdiv/driver.cpp with -O3 -march=native into target/osd/, then runs
# `cargo bench -p bidegree --bench opensubdiv` with BIDEGREE_OSD_DRIVER pointing at it (the bench
# keeps one driver per cage running and interleaves its timings with bidegree's).
# The BIDEGREE_BENCH_* variables documented in native/core/benches/opensubdiv.rs pass through
# (e.g. BIDEGREE_BENCH_CAGES=4k for a quick run).
set -euo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
log() { printf '[bench_opensubdiv] %s\n' "$*" >&2; }

if [ ! -f /usr/include/opensubdiv/far/topologyRefinerFactory.h ] || ! command -v g++ >/dev/null 2>&1; then
    command -v apt-get >/dev/null 2>&1 || {
        log "OpenSubdiv headers missing and no apt-get: install OpenSubdiv 3.x (libosdCPU) and g++"
        exit 2
    }
    SUDO=""
    [ "$(id -u)" -eq 0 ] || SUDO="sudo"
    log "installing libosd-dev and g++"
    $SUDO apt-get install -y libosd-dev g++ >/dev/null 2>&1 || {
        $SUDO apt-get update >/dev/null
        $SUDO apt-get install -y libosd-dev g++ >/dev/null
    }
fi
command -v cargo >/dev/null 2>&1 || { log "Rust (cargo) is required"; exit 2; }

TARGET="${CARGO_TARGET_DIR:-$ROOT/target}"
DRIVER="$TARGET/osd/osd_driver"
mkdir -p "$TARGET/osd"
if [ ! -x "$DRIVER" ] || [ "$ROOT/bench/opensubdiv/driver.cpp" -nt "$DRIVER" ]; then
    log "compiling $DRIVER (g++ -O3 -march=native, -losdCPU)"
    g++ -std=c++17 -O3 -march=native -o "$DRIVER" "$ROOT/bench/opensubdiv/driver.cpp" -losdCPU
fi

# A balloon device that reports free pages to its host (virtio feature bit 5) makes the first
# touch of a transparent huge page bimodal by process (README, the extension's allocator).
for features in /sys/bus/virtio/drivers/virtio_balloon/virtio*/features; do
    if [ -r "$features" ] && [ "$(cut -c6 "$features")" = 1 ]; then
        log "warning: this VM reports free pages to its host; rows that touch new memory can be several times slower in some processes (MIMALLOC_ALLOW_THP=0 steadies them: README)"
    fi
done
log "$(date -u +%H:%M:%S) UTC, load average before the run: $(cut -d' ' -f1-3 /proc/loadavg) on $(nproc) cores"
cd "$ROOT"
BIDEGREE_OSD_DRIVER="$DRIVER" cargo bench -p bidegree --bench opensubdiv
log "$(date -u +%H:%M:%S) UTC, load average after the run: $(cut -d' ' -f1-3 /proc/loadavg)"
