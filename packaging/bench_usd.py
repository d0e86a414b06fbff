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

Each write is timed as the median of ``--repeat`` repetitions (everything ``export`` does:
validation, normals, stage, crate file, rename). Prints the times, the ratio surface / grid,
the file sizes and the load average before and after (the machine may be shared: compare
ratios from one run, not times across runs).

Usage: ``.venv/bin/python packaging/bench_usd.py [--faces 3900] [--degree 4] [--levels 4]
[--repeat 5] [--out DIR]``.
"""

from __future__ import annotations

import argparse
import math
import os
import statistics
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


def _median_s(fn: Callable[[], None], repeat: int) -> float:
    times = []
    for _ in range(max(1, repeat)):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times)


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
    """Subdivide, write both meshes ``args.repeat`` times each into ``out``, print the table."""
    print(f"load average before: {_load()}")
    cage = make_cage(args.faces)
    surface = bidegree.subdivide(cage, args.degree, args.levels)
    grid = make_grid(len(surface.face_sizes), surface)
    print(
        f"cage {cage.num_faces:,} faces; surface degree {args.degree}, {args.levels} levels; "
        f"median of {args.repeat}; {os.cpu_count()} CPUs"
    )
    header = f"{'mesh':<22} {'faces':>10} {'points':>10} {'write s':>9} {'ratio':>7} {'file MB':>9}"
    print(header)
    print("-" * len(header))
    grid_time = None
    rows = (
        ("grid", "grid", grid, "first-use"),
        ("surface", "surface", surface, "first-use"),
        ("surface, result order", "surface_result_order", surface, "result"),
    )
    for name, stem, result, order in rows:
        path = os.path.join(out, f"{stem}.usdc")

        def write(r: Any = result, p: str = path, o: str = order) -> None:
            usd.export(p, cage, r, point_order=o)

        seconds = _median_s(write, args.repeat)
        grid_time = grid_time or seconds
        print(
            f"{name:<22} {len(result.face_sizes):>10,} {len(result.points):>10,} "
            f"{seconds:>9.3f} {seconds / grid_time:>6.2f}x {os.path.getsize(path) / 1e6:>9.2f}"
        )
    print("ratio = write time / the grid's (target: surface at most 1.5x)")
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
