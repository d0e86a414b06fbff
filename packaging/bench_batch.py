"""Benchmark (not a test): batch throughput here and on a local dask cluster.

The input is Suzanne with two levels of Catmull-Clark applied (7,872 quads) saved as a .blend and
copied 20 times; each copy is subdivided at degree 4, level 3 (503,808 faces) and written as
``.bidegree.blend`` and ``.usdc``. Every run is ``python -m bidegree_blender.batch`` in a child
process, timed from its start to its exit (interpreter, ``bpy`` import and cluster start
included), in these modes:

* the local batch (one process, files one after another);
* ``--workers 1`` and ``--workers 2`` (a ``LocalCluster`` of worker processes, one thread each).

Printed: wall time, files per minute, the work the manifest records (the sum of the files'
conversion times) and, from extra one-file runs of the local batch and of ``--workers 1``, the
fixed start-up cost of a cluster, the extra time per extra file of ``--workers 1`` over the local
batch, ``((W1(20) - W1(1)) - (L(20) - L(1))) / 19``, and the part of it spent outside the
conversions. Then the scheduling overhead alone, the same difference for 40 cube OBJs at level 1
(milliseconds of work each).

Usage: ``.venv/bin/python packaging/bench_batch.py [--files 20] [--levels 3] [--keep DIR]``
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

CUBE_OBJ = (
    "v -1 -1 -1\nv 1 -1 -1\nv 1 1 -1\nv -1 1 -1\nv -1 -1 1\nv 1 -1 1\nv 1 1 1\nv -1 1 1\n"
    "f 1 4 3 2\nf 5 6 7 8\nf 1 2 6 5\nf 2 3 7 6\nf 3 4 8 7\nf 4 1 5 8\n"
)
MAKE_CAGE = """
import sys, bpy
bpy.ops.wm.read_factory_settings(use_empty=True)
bpy.ops.mesh.primitive_monkey_add(size=2.0)
ob = bpy.context.active_object
ob.name = "Suzanne"
mod = ob.modifiers.new("Subdivision", "SUBSURF")
mod.levels = 2
bpy.ops.object.modifier_apply(modifier=mod.name)
bpy.ops.wm.save_as_mainfile(filepath=sys.argv[1])
"""


def _run(inputs: list[Path], out: Path, levels: int, extra: list[str]) -> tuple[float, float]:
    """Wall seconds of one batch run, and the conversion seconds its manifest records."""
    shutil.rmtree(out, ignore_errors=True)
    cmd = [sys.executable, "-m", "bidegree_blender.batch", *map(str, inputs), "--out", str(out)]
    cmd += ["--degree", "4", "--levels", str(levels), *extra]
    t0 = time.perf_counter()
    proc = subprocess.run(cmd, capture_output=True, text=True, check=False)
    wall = time.perf_counter() - t0
    if proc.returncode != 0:
        sys.exit(f"batch failed ({proc.returncode}):\n{proc.stdout[-3000:]}\n{proc.stderr[-3000:]}")
    entries = json.loads((out / "bidegree-manifest.json").read_text())["files"]
    assert len(entries) == len(inputs) and all(e["status"] == "done" for e in entries)
    return wall, sum(e["seconds"] for e in entries)


def _load() -> str:
    return "load average {:.2f} {:.2f} {:.2f}".format(*os.getloadavg())


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--files", type=int, default=20)
    parser.add_argument("--levels", type=int, default=3)
    parser.add_argument("--tiny", type=int, default=40, help="cubes for the overhead alone")
    parser.add_argument("--keep", help="work in this folder and keep it (default: a temporary one)")
    args = parser.parse_args()

    work = Path(args.keep or tempfile.mkdtemp(prefix="bidegree-bench-batch-"))
    work.mkdir(parents=True, exist_ok=True)
    cage = work / "suzanne.blend"
    subprocess.run([sys.executable, "-c", MAKE_CAGE, str(cage)], check=True, capture_output=True)
    inputs = []
    for i in range(args.files):
        inputs.append(work / f"suzanne_{i:02d}.blend")
        shutil.copyfile(cage, inputs[-1])
    out = work / "out"

    print(f"{args.files} copies of Suzanne (7,872 quads), degree 4, level {args.levels}, --usd")
    print(f"before: {_load()} on {os.cpu_count()} cores")
    modes = [("local batch", ["--usd"]), ("--workers 1", ["--usd", "--workers", "1"])]
    modes.append(("--workers 2", ["--usd", "--workers", "2"]))
    one = {name: _run(inputs[:1], out, args.levels, extra) for name, extra in modes[:2]}
    print(f"{'mode':<12} {'wall s':>8} {'files/min':>10} {'work s':>8} {'ratio':>6}")
    runs = {}
    for name, extra in modes:
        runs[name] = wall, work_s = _run(inputs, out, args.levels, extra)
        ratio = runs["local batch"][0] / wall
        print(f"{name:<12} {wall:8.1f} {60 * args.files / wall:10.1f} {work_s:8.1f} {ratio:6.2f}")
    (l1, _), (w1, w1_work) = one["local batch"], one["--workers 1"]
    print(f"one file: local {l1:.1f} s, --workers 1 {w1:.1f} s (cluster start-up {w1 - l1:.1f} s)")
    if args.files > 1:
        (ln, _), (wn, wn_work) = runs["local batch"], runs["--workers 1"]
        extra_ms = 1000 * ((wn - w1) - (ln - l1)) / (args.files - 1)
        gap_ms = 1000 * ((wn - w1) - (wn_work - w1_work)) / (args.files - 1)
        print(f"per extra file, --workers 1 against the local batch: {extra_ms:+.0f} ms")
        print(f"per extra file, --workers 1 outside the conversion (scheduling): {gap_ms:.0f} ms")

    # The overhead alone: a cube at level 1 (milliseconds of work), no USD.
    cube = work / "cube.obj"
    cube.write_text(CUBE_OBJ)
    tiny = []
    for i in range(args.tiny):
        tiny.append(work / f"cube_{i:02d}.obj")
        shutil.copyfile(cube, tiny[-1])
    walls = {}
    for name, extra in (("local", []), ("w1", ["--workers", "1"])):
        for files in (tiny[:1], tiny):
            walls[name, len(files)] = _run(files, out, 1, extra)[0]
    n = args.tiny
    (l1, ln), (w1, wn) = (walls["local", 1], walls["local", n]), (walls["w1", 1], walls["w1", n])
    per_file = 1000 * ((wn - w1) - (ln - l1)) / (n - 1)
    print(f"{n} cubes at level 1: local {ln:.1f} s, --workers 1 {wn:.1f} s")
    print(f"scheduling overhead per file (cubes, --workers 1 minus local): {per_file:.0f} ms")
    print(f"after: {_load()}")
    shutil.rmtree(out, ignore_errors=True)
    if not args.keep:
        shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    main()
