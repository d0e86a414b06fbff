"""``bidegree bench``: subdivision throughput against a plain memory copy (a benchmark, not a
test).

For each degree, the number of levels is chosen so that the output has about ``--target-faces``
faces (4M by default), from a generated cage with extraordinary vertices: a cube-sphere (valence
3 at the cube corners) with a few quads split into triangles along a diagonal (valence 5 and 6).
It prints output faces per second

- fresh: :func:`bidegree.subdivide` (validation, topology, evaluation),
- cached: :meth:`bidegree.Plan.evaluate` of moved points through a plan built beforehand,
- copy: ``np.copyto`` of an array as large as the evaluated output (same dtype),

all measured in the same run (best of ``--repeat``), and the time ratio cached / copy: how many
memory copies of the output one cached evaluation costs.
"""

from __future__ import annotations

import argparse
import math
import os
import time
from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray

import bidegree

__all__ = ["add_arguments", "make_cage", "parse_degrees", "run"]

# Cube faces as (origin, u, v) in units of the grid size k, with u x v the outward normal, so
# that every quad (i, j) -> (i+1, j) -> (i+1, j+1) -> (i, j+1) is counter-clockwise seen from
# outside.
_CUBE_FACES = (
    ((1, 0, 0), (0, 1, 0), (0, 0, 1)),  # +X
    ((0, 0, 0), (0, 0, 1), (0, 1, 0)),  # -X
    ((0, 1, 0), (0, 0, 1), (1, 0, 0)),  # +Y
    ((0, 0, 0), (1, 0, 0), (0, 0, 1)),  # -Y
    ((0, 0, 1), (1, 0, 0), (0, 1, 0)),  # +Z
    ((0, 0, 0), (0, 1, 0), (1, 0, 0)),  # -Z
)


def make_cage(faces: int = 3000, dtype: type[np.floating] = np.float32) -> bidegree.Mesh:
    """A closed cage of about ``faces`` faces with extraordinary vertices, built with numpy.

    A cube whose sides are k x k quad grids, welded and projected onto the unit sphere (the 8
    cube corners have valence 3); on each side the quads at (p, p) and (p+1, p+1), p = k // 3,
    are split into two triangles along their common diagonal, which makes vertices of valence 5
    (diagonal ends) and 6 (shared by both diagonals).
    """
    k = max(3, round(math.sqrt(max(faces, 6) / 6)))
    i, j = np.meshgrid(np.arange(k + 1), np.arange(k + 1), indexing="ij")
    grids = []
    for origin, u, v in _CUBE_FACES:
        o, uu, vv = (np.array(x, dtype=np.int64) for x in (origin, u, v))
        grids.append(o * k + i[..., None] * uu + j[..., None] * vv)  # (k+1, k+1, 3)
    lattice = np.stack(grids).reshape(-1, 3)
    unique, vertex_of = np.unique(lattice, axis=0, return_inverse=True)
    vertex_of = vertex_of.reshape(6, k + 1, k + 1)

    a = vertex_of[:, :-1, :-1]
    b = vertex_of[:, 1:, :-1]
    c = vertex_of[:, 1:, 1:]
    d = vertex_of[:, :-1, 1:]
    quads = np.stack([a, b, c, d], axis=-1)  # (6, k, k, 4)

    p = k // 3
    split = np.zeros((6, k, k), dtype=bool)
    split[:, p, p] = True
    split[:, p + 1, p + 1] = True
    kept = quads[~split].reshape(-1, 4)
    cut = quads[split].reshape(-1, 4)
    triangles = np.concatenate([cut[:, [0, 1, 2]], cut[:, [0, 2, 3]]])

    face_sizes = np.concatenate(
        [np.full(len(kept), 4, dtype=np.int64), np.full(len(triangles), 3, dtype=np.int64)]
    )
    face_indices = np.concatenate([kept.reshape(-1), triangles.reshape(-1)])
    centred = unique.astype(np.float64) - k / 2.0
    points = centred / np.linalg.norm(centred, axis=1, keepdims=True)
    return bidegree.Mesh(points.astype(dtype), face_sizes=face_sizes, face_indices=face_indices)


def parse_degrees(text: str) -> list[int]:
    """``"1-9"``, ``"3"``, ``"1,3,5-7"`` -> list of degrees."""
    degrees: list[int] = []
    try:
        for part in text.split(","):
            part = part.strip()
            if "-" in part:
                low, high = (int(x) for x in part.split("-", 1))
                degrees.extend(range(low, high + 1))
            elif part:
                degrees.append(int(part))
    except ValueError:
        raise argparse.ArgumentTypeError(f"bad degree list {text!r} (e.g. 1-9 or 1,3,5)") from None
    if not degrees:
        raise argparse.ArgumentTypeError("no degrees given")
    return degrees


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Arguments of ``bidegree bench``."""
    parser.add_argument(
        "--degrees", type=parse_degrees, default=list(range(1, 10)), help="e.g. 1-9 (default)"
    )
    parser.add_argument(
        "--faces",
        type=int,
        default=3900,
        help="approximate cage faces (default 3900: ~4M faces at 5 levels)",
    )
    parser.add_argument(
        "--target-faces",
        type=int,
        default=4_000_000,
        help="choose levels for about this many output faces (default 4M)",
    )
    parser.add_argument("--repeat", type=int, default=3, help="best of N timings (default 3)")
    parser.add_argument(
        "--dtype", choices=("float32", "float64"), default="float32", help="point precision"
    )


def _best(repeat: int, work: Callable[[], object]) -> float:
    best = math.inf
    for _ in range(max(1, repeat)):
        start = time.perf_counter()
        work()
        best = min(best, time.perf_counter() - start)
    return best


def _levels_for(mesh: bidegree.Mesh, degree: int, target: int) -> tuple[int, int]:
    """The level count whose output face count is closest (in ratio) to ``target``."""
    best_levels, best_faces, best_error = 1, 0, math.inf
    for levels in range(1, bidegree.MAX_LEVELS + 1):
        faces = bidegree.estimate(mesh, degree, levels)["faces"]
        error = abs(math.log(max(faces, 1) / target))
        if error < best_error:
            best_levels, best_faces, best_error = levels, faces, error
        if faces > target:
            break
    return best_levels, best_faces


def _measure(
    mesh: bidegree.Mesh, moved: NDArray[np.floating], degree: int, levels: int, repeat: int
) -> tuple[int, float, float, float]:
    """Output faces and best times of fresh subdivision, cached evaluation and a copy."""
    plans: list[bidegree.Plan] = []
    fresh_time = _best(repeat, lambda: plans.append(bidegree.subdivide(mesh, degree, levels).plan))
    plan = plans[-1]
    plans.clear()
    outputs: list[NDArray[np.floating]] = []
    cached_time = _best(repeat, lambda: outputs.append(plan.evaluate(moved)))
    source = np.ones_like(outputs[-1])
    outputs.clear()
    target = np.empty_like(source)
    copy_time = _best(repeat, lambda: np.copyto(target, source))
    return plan.num_output_faces, fresh_time, cached_time, copy_time


def run(args: argparse.Namespace) -> int:
    """Runs the benchmark and prints a table; returns 0."""
    dtype = np.float32 if args.dtype == "float32" else np.float64
    mesh = make_cage(args.faces, dtype)
    valence = np.bincount(mesh.face_indices, minlength=mesh.num_vertices)
    counts = np.bincount(valence)
    irregular = ", ".join(f"{n} of valence {v}" for v, n in enumerate(counts) if n and v != 4)
    print(
        f"cage: {mesh.num_vertices} vertices, {mesh.num_faces} faces ({irregular}); "
        f"{args.dtype} points; best of {args.repeat}; {os.cpu_count()} CPUs"
    )
    rng = np.random.default_rng(1)
    moved = (mesh.points + rng.normal(0, 0.01, mesh.points.shape)).astype(dtype)

    header = (
        f"{'degree':>6} {'levels':>6} {'out faces':>11} {'fresh Mf/s':>11} "
        f"{'cached Mf/s':>12} {'copy Mf/s':>10} {'cached/copy':>12}"
    )
    print(header)
    print("-" * len(header))
    for degree in args.degrees:
        levels, _ = _levels_for(mesh, degree, args.target_faces)
        faces, fresh_time, cached_time, copy_time = _measure(
            mesh, moved, degree, levels, args.repeat
        )
        print(
            f"{degree:>6} {levels:>6} {faces:>11,} {faces / fresh_time / 1e6:>11.2f} "
            f"{faces / cached_time / 1e6:>12.2f} {faces / copy_time / 1e6:>10.1f} "
            f"{cached_time / copy_time:>11.1f}x"
        )
    print(
        "Mf/s = million output faces per second; copy = np.copyto of an array the size of the "
        "evaluated points; cached/copy = time of one cached evaluation in memory copies."
    )
    return 0
