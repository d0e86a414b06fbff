"""Benchmark (not a test): a ``.usdc`` write of a bidegree surface against a grid of its size.

Issue 16's target: writing a 1M-face bidegree surface to ``.usdc`` takes at most 1.5x the time
of writing a plain grid mesh of the same face count. Both go through :func:`bidegree.usd.export`
(what the CLI, the add-on and the batch call), with the same cage, in one run:

* **surface**: ``bidegree.subdivide`` of the generated cage of ``bidegree bench``
  (:func:`bidegree.bench.make_cage`: a cube-sphere with valence 3, 5 and 6 vertices;
  ``--faces 3900`` makes 3,762 faces, 961,536 at degree 4 and 4 levels), its points in the
  level order of the subdivision (old vertices | edge points | face points per level);
* **grid**: a k x k' quad grid in row-major order with as many faces, passed as a Result-like
  object (points, faces, degree, levels, output, boundary);
* **surface, result order**: the surface again with ``point_order="result"`` (its points in
  the level order, as every write was before the first-use order: the crate's integer
  compression of the scattered ``faceVertexIndices`` dominates).

Each write is timed as the median of ``--repeat`` rounds, each round writing every row twice and
timing the second write (everything ``export`` does: validation, normals, stage, crate file,
rename). Prints the wall, user CPU and system CPU times (when other work shares the cores the
user time is the steadiest; the system time, mostly page faults of new numpy buffers, swings
several-fold), the ratios to the grid (of the medians, and the range over the rounds of the wall
time's), the file sizes and the load average before and after (the machine may be shared:
compare ratios from one run, not times across runs).

Usage: ``.venv/bin/python packaging/bench_usd.py [--faces 3900] [--degree 4] [--levels 4]
[--repeat 5] [--out DIR]``.
"""

from __future__ import annotations

import argparse
import math
import os
import tempfile
import time
from collections.abc import Callable
from types import SimpleNamespace
from typing import Any

import bidegree
import numpy as np
from bidegree import usd
from bidegree.bench import make_cage


def _load() -> str:
    return "{:.2f} {:.2f} {:.2f}".format(*os.getloadavg())


def _seconds(fn: Callable[[], None]) -> tuple[float, float, float]:
    """Wall-clock, user CPU and system CPU seconds (this process, all its threads) of
    ``fn()``."""
    wall, before = time.perf_counter(), os.times()
    fn()
    after = os.times()
    return time.perf_counter() - wall, after.user - before.user, after.system - before.system


def make_grid(faces: int, like: Any) -> SimpleNamespace:
    """A Result-like quad grid of about ``faces`` faces (exactly k * k', k = round(sqrt)),
    vertices numbered row by row, on a gentle bump (so that its normals vary); ``degree``,
    ``levels``, ``output`` and ``boundary`` are copied from ``like``."""
    k = max(1, round(math.sqrt(faces)))
    k2 = max(1, round(faces / k))
    i, j = np.meshgrid(np.arange(k + 1), np.arange(k2 + 1), indexing="ij")
    x, y = i / k, j / k2
    z = 0.1 * np.sin(np.pi * x) * np.sin(np.pi * y)
    points = np.stack([x, y, z], axis=-1).reshape(-1, 3).astype(np.float32)
    a = (i[:-1, :-1] * (k2 + 1) + j[:-1, :-1]).reshape(-1)
    quads = np.stack([a, a + k2 + 1, a + k2 + 2, a + 1], axis=-1)  # counter-clockwise in XY
    return SimpleNamespace(
        points=points,
        face_sizes=np.full(len(quads), 4, dtype=np.int32),
        face_indices=quads.reshape(-1).astype(np.int32),
        uvs=None,
        degree=like.degree,
        levels=like.levels,
        output=like.output,
        boundary=like.boundary,
    )


def run(args: argparse.Namespace, out: str) -> None:
    """Subdivide, write every row ``args.repeat`` times into ``out`` (round by round), print
    the table."""
    print(f"load average before: {_load()}")
    cage = make_cage(args.faces)
    surface = bidegree.subdivide(cage, args.degree, args.levels)
    grid = make_grid(len(surface.face_sizes), surface)
    print(
        f"cage {cage.num_faces:,} faces; surface degree {args.degree}, {args.levels} levels; "
        f"median of {args.repeat}; {os.cpu_count()} CPUs"
    )
    rows = (
        ("grid", grid, "first-use"),
        ("surface", surface, "first-use"),
        ("surface, result order", surface, "result"),
    )
    paths = [
        os.path.join(out, name.replace(", ", "_").replace(" ", "_") + ".usdc") for name, *_ in rows
    ]
    # Round by round (each row once per round), so that a change of the machine's load during
    # the run weighs on every row alike; each timed write right after an untimed one of the same
    # row, so that none pays for what another row's write left behind (a write after the
    # result-order row's pays up to 1 s more in page faults, as the allocator gives memory back).
    times = np.zeros((len(rows), max(1, args.repeat), 3))  # row, round, (wall, user, sys)
    for k in range(times.shape[1]):
        for j, ((_, result, order), path) in enumerate(zip(rows, paths, strict=True)):
            usd.export(path, cage, result, point_order=order)
            times[j, k] = _seconds(
                lambda r=result, p=path, o=order: usd.export(p, cage, r, point_order=o)
            )
    median = np.median(times, axis=1)  # row, (wall, user, sys)
    rounds = times[:, :, 0] / times[0, :, 0]
    header = (
        f"{'mesh':<22} {'faces':>10} {'points':>10} {'wall s':>7} {'ratio':>6} "
        f"{'per round':>10} {'user s':>6} {'ratio':>6} {'sys s':>6} {'file MB':>8}"
    )
    print(header)
    print("-" * len(header))
    for j, ((name, result, _), path) in enumerate(zip(rows, paths, strict=True)):
        print(
            f"{name:<22} {len(result.face_sizes):>10,} {len(result.points):>10,} "
            f"{median[j, 0]:>7.3f} {median[j, 0] / median[0, 0]:>5.2f}x "
            f"{rounds[j].min():>5.2f}-{rounds[j].max():.2f}x "
            f"{median[j, 1]:>6.3f} {median[j, 1] / median[0, 1]:>5.2f}x {median[j, 2]:>6.3f} "
            f"{os.path.getsize(path) / 1e6:>8.2f}"
        )
    print(
        "wall s, user s, sys s = medians (user: this process's user CPU time, the steadiest on "
        "a shared machine; sys: mostly page faults of new buffers, which swing with other "
        "work); ratio = to the grid's (target: surface at most 1.5x); per round = range of the "
        "wall ratio to the grid's write of the same round"
    )
    print(f"load average after: {_load()}")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--faces", type=int, default=3900, help="approximate cage faces")
    parser.add_argument("--degree", type=int, default=4)
    parser.add_argument("--levels", type=int, default=4)
    parser.add_argument("--repeat", type=int, default=5, help="median of N writes (default 5)")
    parser.add_argument("--out", help="keep the files in this directory (default: a temporary one)")
    args = parser.parse_args()
    if args.out:
        run(args, args.out)
    else:
        with tempfile.TemporaryDirectory(prefix="bench_usd.") as out:
            run(args, out)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
