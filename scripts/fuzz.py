"""Hostile-input fuzzer for bidegree (run through ``scripts/fuzz.sh MINUTES``).

Two kinds of case, each run in its own child process under an address-space and CPU limit, so
that an abort, a crash, an out-of-memory kill or a hang is caught and counted:

- ``api``: a random polygon soup or a damaged well-formed cage (non-manifold edges of 3+
  faces, books of sheets, bowties, flipped faces, repeated vertices, zero-area faces, creases
  on loose vertex pairs, holes, corners, isolated vertices, extreme or non-finite coordinates,
  UVs) through the Python API with random options (degree, levels, output, rules, creasing,
  boundary including ``none``, limit, normals, adaptive, memory budget, plan evaluation of
  other channels, OBJ writing). The child is forked from this process, which
  never calls the core itself (so no thread pool exists at the fork).
- ``cli``: a mutated OBJ file (bytes flipped, inserted, deleted; lines swapped, duplicated,
  truncated; numbers replaced by huge, negative, NaN or garbage values; tags added (holes,
  ``interpolateboundary 0``); non-manifold fins, flipped faces, loose edges (``l``) and
  zero-area faces in the cage; BOM, NUL, line ends) through ``bidegree subdivide`` with random
  options.

Each case ends as *success* (a result, consistent and finite; the caller's arrays unchanged; for
the CLI exit 0 and an output file), *typed error* (a ``BidegreeError`` other than
``InternalError``; for the CLI exit 2 with one ``bidegree: error:`` line and no file left) or
*other* (anything else: an internal error, another exception, a signal, a timeout, a mutated
input, a traceback, a leftover file). Every *other* case is shrunk a little and written to
``tests/fuzz_regressions/`` (at most a few per distinct failure), where
``tests/test_hostile_fuzz.py`` replays it.
"""

from __future__ import annotations

import argparse
import base64
import contextlib
import hashlib
import json
import os
import re
import resource
import signal
import subprocess
import sys
import tempfile
import time
import warnings
from collections import Counter
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
REGRESSIONS = ROOT / "tests" / "fuzz_regressions"

#: Limits of a child: address space, CPU seconds, wall seconds.
ADDRESS_SPACE = 3 << 30
CPU_SECONDS = 120
WALL_SECONDS = 180
#: Regression files kept per distinct failure signature.
PER_SIGNATURE = 3

Spec = dict[str, Any]
Outcome = dict[str, Any]


# ---------------------------------------------------------------------------------------------
# Cases: random cages


def _grid(rng: np.random.Generator) -> tuple[np.ndarray, list[list[int]]]:
    """An n x m patch of quads (some split into triangles), maybe closed into a tube."""
    n, m = int(rng.integers(1, 6)), int(rng.integers(1, 6))
    i, j = np.meshgrid(np.arange(n + 1), np.arange(m + 1), indexing="ij")
    points = np.stack([i, j, rng.normal(0, 0.3, i.shape)], axis=-1).reshape(-1, 3).astype(float)
    faces: list[list[int]] = []
    for a in range(n):
        for b in range(m):
            q = [
                a * (m + 1) + b,
                (a + 1) * (m + 1) + b,
                (a + 1) * (m + 1) + b + 1,
                a * (m + 1) + b + 1,
            ]
            if rng.random() < 0.2:
                faces += [[q[0], q[1], q[2]], [q[0], q[2], q[3]]]
            else:
                faces.append(q)
    return points, faces


def _cube(rng: np.random.Generator) -> tuple[np.ndarray, list[list[int]]]:
    points = np.array(
        [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0, 0, 1], [1, 0, 1], [1, 1, 1], [0, 1, 1]],
        dtype=float,
    )
    faces = [[0, 3, 2, 1], [4, 5, 6, 7], [0, 1, 5, 4], [1, 2, 6, 5], [2, 3, 7, 6], [3, 0, 4, 7]]
    return points + rng.normal(0, 0.05, points.shape), faces


def _fan(rng: np.random.Generator) -> tuple[np.ndarray, list[list[int]]]:
    """A vertex of valence k with triangles or quads around it (open or closed)."""
    k = int(rng.integers(3, 12))
    angles = 2 * np.pi * np.arange(k) / k
    ring = np.stack([np.cos(angles), np.sin(angles), np.zeros(k)], axis=-1)
    points = np.vstack([[0, 0, 0.3], ring, 1.7 * ring])
    faces = []
    for s in range(k - int(rng.integers(0, 2))):
        t = (s + 1) % k
        if rng.random() < 0.5:
            faces.append([0, 1 + s, 1 + t])
        else:
            faces.append([0, 1 + s, 1 + k + s, 1 + t])
    return points, faces


def _soup(rng: np.random.Generator) -> tuple[np.ndarray, list[list[int]]]:
    """Random faces over random points: mostly not a manifold."""
    v = int(rng.integers(3, 40))
    points = rng.normal(0, 1, (v, 3))
    faces = []
    for _ in range(int(rng.integers(1, 20))):
        size = int(rng.integers(3, min(v, 8) + 1))
        faces.append([int(x) for x in rng.choice(v, size, replace=rng.random() < 0.1)])
    return points, faces


def _book(rng: np.random.Generator) -> tuple[np.ndarray, list[list[int]]]:
    """2-4 sheets of quads (or triangles) on one line: every edge of the line has 3+ faces
    (non-manifold); some sheets run the line the other way."""
    sheets, length = int(rng.integers(2, 5)), int(rng.integers(2, 5))
    line = np.stack([np.arange(length), np.zeros(length), np.zeros(length)], axis=-1)
    points = [line]
    faces: list[list[int]] = []
    for s in range(sheets):
        angle = 2 * np.pi * s / sheets + rng.normal(0, 0.1)
        offset = np.array([0.0, np.cos(angle), np.sin(angle)])
        points.append(line + offset)
        base = length * (s + 1)
        for i in range(length - 1):
            quad = [i, i + 1, base + i + 1, base + i]
            sheet = [quad] if rng.random() < 0.7 else [quad[:3], [quad[0], quad[2], quad[3]]]
            faces += [f[::-1] for f in sheet] if rng.random() < 0.4 else sheet
    return np.vstack(points).astype(float), faces


def _non_manifold(rng: np.random.Generator, points: np.ndarray, faces: list[list[int]]) -> tuple:
    """Some of: a fin (a new face on an existing edge: 3+ faces there), a bowtie (a second fan
    glued at one vertex), a face with a repeated vertex, a zero-area face (on three points of a
    line, or with all its points equal), several flipped faces."""
    faces = [list(f) for f in faces]
    if not faces:
        return points, faces
    if rng.random() < 0.3:
        f = faces[int(rng.integers(len(faces)))]
        i = int(rng.integers(len(f)))
        a, b = f[i], f[(i + 1) % len(f)]
        points = np.vstack([points, points[a] + rng.normal(0, 1, 3)])
        fin = [a, b, len(points) - 1]
        faces.append(fin if rng.random() < 0.5 else fin[::-1])
    if rng.random() < 0.15:
        v = int(rng.choice(faces[int(rng.integers(len(faces)))]))
        start = len(points)
        points = np.vstack([points, points[v] + rng.normal(0, 1, (3, 3))])
        faces += [[v, start, start + 1], [v, start + 1, start + 2]]
    if rng.random() < 0.15:
        f = faces[int(rng.integers(len(faces)))]
        if len(f) >= 3:
            f.insert(int(rng.integers(1, len(f))), f[0] if rng.random() < 0.5 else f[1])
    if rng.random() < 0.15:
        a, b = points[int(rng.integers(len(points)))], points[int(rng.integers(len(points)))]
        start = len(points)
        points = np.vstack([points, a, (a + b) / 2, b])
        faces.append([start, start + 1, start + 2])
    if rng.random() < 0.1:
        for v in faces[int(rng.integers(len(faces)))]:
            points[v] = points[faces[0][0]]
    if rng.random() < 0.15:
        for f in faces:
            if rng.random() < 0.3:
                f.reverse()
    return points, faces


def _damage(rng: np.random.Generator, points: np.ndarray, faces: list[list[int]]) -> tuple:
    """Some of: flipped, duplicated or dropped faces, isolated vertices, extreme coordinates,
    degenerate faces, non-finite values, bad indices; non-manifold damage (``_non_manifold``)."""
    faces = [list(f) for f in faces]
    if rng.random() < 0.35:
        points, faces = _non_manifold(rng, points, faces)
    if rng.random() < 0.1 and faces:
        faces[int(rng.integers(len(faces)))].reverse()
    if rng.random() < 0.05 and faces:
        faces.append(list(faces[int(rng.integers(len(faces)))]))
    if rng.random() < 0.1 and len(faces) > 1:
        faces.pop(int(rng.integers(len(faces))))
    if rng.random() < 0.2:
        points = np.vstack([points, rng.normal(0, 1, (int(rng.integers(1, 4)), 3))])
    if rng.random() < 0.15:
        points = points * 10.0 ** float(rng.choice([-300, -30, -8, 8, 30, 37, 300]))
    if rng.random() < 0.05:
        points[int(rng.integers(len(points)))] = rng.choice([np.nan, np.inf, -np.inf])
    if rng.random() < 0.05 and faces:
        f = faces[int(rng.integers(len(faces)))]
        points[f[1]] = points[f[0]]
    if rng.random() < 0.03 and faces:
        f = faces[int(rng.integers(len(faces)))]
        f[int(rng.integers(len(f)))] = int(rng.choice([-1, len(points), 2**31, -(2**40)]))
    if rng.random() < 0.03 and faces:
        faces[int(rng.integers(len(faces)))] = faces[0][:2]
    return points, faces


def _sharpness(rng: np.random.Generator) -> float:
    if rng.random() < 0.05:
        return float(rng.choice([-1.0, np.nan, -np.inf]))
    return float(rng.choice([0.0, 0.5, 1.0, 1.7, 2.5, 4.0, 10.0, np.inf, 1e30]))


def gen_api(rng: np.random.Generator) -> Spec:
    """A random API case."""
    makers = [_grid, _cube, _fan, _soup, _book]
    make = makers[int(rng.choice(5, p=[0.3, 0.2, 0.2, 0.15, 0.15]))]
    points, faces = _damage(rng, *make(rng))
    edges = [(f[i], f[(i + 1) % len(f)]) for f in faces for i in range(len(f))]
    creases = []
    for _ in range(int(rng.integers(0, 6)) if rng.random() < 0.5 else 0):
        a, b = (
            edges[int(rng.integers(len(edges)))]
            if edges and rng.random() < 0.85
            else tuple(int(x) for x in rng.integers(-1, len(points) + 1, 2))
        )
        creases.append([int(a), int(b), _sharpness(rng)])
    if rng.random() < 0.05:
        # A loose edge: two new vertices joined by a crease only (no face has that edge).
        points = np.vstack([points, rng.normal(0, 1, (2, 3))])
        creases.append([len(points) - 2, len(points) - 1, _sharpness(rng)])
    holes = []
    if rng.random() < 0.2 and faces:
        holes = [int(rng.integers(len(faces))) for _ in range(int(rng.integers(1, 3)))]
        if rng.random() < 0.1:
            holes.append(int(rng.choice([-1, len(faces), 2**40])))
        if rng.random() < 0.05:
            holes = list(range(len(faces)))
    corners = []
    for _ in range(int(rng.integers(0, 4)) if rng.random() < 0.4 else 0):
        vertex = int(rng.integers(len(points)) if rng.random() < 0.9 else rng.integers(-1, 2**33))
        corners.append([vertex, _sharpness(rng)])
    corners_total = sum(len(f) for f in faces)
    uvs = None
    if rng.random() < 0.2:
        uvs = rng.random((corners_total + int(rng.random() < 0.05), 2))
        if rng.random() < 0.1:
            uvs[0, 0] = np.nan
        uvs = uvs.tolist()
    call = str(
        rng.choice(
            ["subdivide", "plan", "adaptive", "estimate", "write"], p=[0.45, 0.2, 0.2, 0.05, 0.1]
        )
    )
    big_request = rng.random() < 0.05
    rules = str(rng.choice(["averaging", "classic"], p=[0.7, 0.3]))
    degree = int(rng.choice([1, 2, 3, 3, 4, 5, 6, 9, 12, 31]))
    if rng.random() < 0.05:
        degree = int(rng.choice([0, 32, -1, 2**40]))
    if rules == "classic" and rng.random() < 0.8:
        degree = int(rng.choice([1, 2, 3, 3]))
    output = str(rng.choice(["primal", "dual"], p=[0.8, 0.2]))
    return {
        "kind": "api",
        "call": call,
        "dtype": str(rng.choice(["float64", "float32"])),
        "points": points.tolist(),
        "faces": faces,
        "creases": creases,
        "corners": corners,
        "holes": holes,
        "uvs": uvs,
        "boundary": str(rng.choice(["edge-only", "edge-and-corner", "none"], p=[0.4, 0.4, 0.2])),
        "creasing": str(rng.choice(["uniform", "chaikin"])),
        "degree": degree,
        "levels": int(rng.integers(10, 17)) if big_request else int(rng.integers(0, 4)),
        "output": output,
        "rules": rules,
        "limit": bool(rng.random() < (0.25 if output == "primal" else 0.05)),
        "normals": bool(
            rng.random() < (0.25 if output == "primal" and rules == "averaging" else 0.05)
        ),
        "tolerance": float(rng.choice([0.0, 1e-4, 1e-3, 0.05, 1.0])),
        "max_level": int(rng.integers(0, 6)),
        "measure_leaves": bool(rng.random() < 0.2),
        "memory_budget": None
        if rng.random() < 0.5
        else int(rng.choice([1 << 16, 1 << 24, 1 << 28, 1 << 28])),
        "channels": int(rng.choice([1, 2, 3, 5])),
        "seed": int(rng.integers(1 << 31)),
    }


# ---------------------------------------------------------------------------------------------
# Cases: mutated OBJ files


def _obj_text(rng: np.random.Generator) -> str:
    make = [_grid, _cube, _fan, _book][int(rng.choice(4, p=[0.3, 0.3, 0.2, 0.2]))]
    points, faces = make(rng)
    if rng.random() < 0.3:
        points, faces = _non_manifold(rng, points, faces)
    lines = ["# fuzz cage", "o cage"] + [f"v {x!r} {y!r} {z!r}" for x, y, z in points]
    with_uvs = rng.random() < 0.4
    if with_uvs:
        lines += [f"vt {u:.3f} {v:.3f}" for u, v in rng.random((len(points), 2))]
    for f in faces:
        if with_uvs:
            lines.append("f " + " ".join(f"{v + 1}/{v + 1}" for v in f))
        else:
            lines.append("f " + " ".join(str(v + 1) for v in f))
    edges = [(f[i], f[(i + 1) % len(f)]) for f in faces for i in range(len(f))]
    for _ in range(int(rng.integers(0, 4))):
        a, b = edges[int(rng.integers(len(edges)))]
        lines.append(f"t crease 2/1/0 {a} {b} {_sharpness(rng) if rng.random() < 0.3 else 2.5}")
    if rng.random() < 0.3:
        lines.append(f"t corner 1/1/0 {int(rng.integers(len(points)))} 10")
    if rng.random() < 0.3:
        lines.append(f"t interpolateboundary 1/0/0 {int(rng.choice([0, 1, 2]))}")
    if rng.random() < 0.2:
        holes = " ".join(str(int(f)) for f in rng.integers(0, len(faces), int(rng.integers(1, 3))))
        lines.append(f"t hole {holes.count(' ') + 1}/0/0 {holes}")
    if rng.random() < 0.15:
        # Loose edges: `l` lines (between face vertices, or vertices no face uses).
        points_used = len(points)
        lines.append(f"v {rng.normal():.3f} {rng.normal():.3f} {rng.normal():.3f}")
        lines.append(f"l {int(rng.integers(1, points_used + 1))} {points_used + 1}")
    if rng.random() < 0.3:
        lines.append(f"t creasemethod 0/0/1 {rng.choice(['normal', 'chaikin'])}")
    return "\n".join(lines) + "\n"


_GARBAGE = [
    "nan",
    "inf",
    "-inf",
    "1e999",
    "-0",
    "0",
    "-1",
    "99999999999999999999",
    "x",
    "",
    "/",
    "//",
    "1/2/3/4",
    "\x00",
    "\ufeff",
    "é",
    "\\",
    "#",
    "t",
    "f",
    "v",
    "2147483648",
    "-2147483649",
    "1e-320",
    "3.4e38",
]


def mutate_obj(rng: np.random.Generator, text: str) -> bytes:
    """A few random mutations of OBJ text, at the line, token and byte level."""
    lines = text.split("\n")
    for _ in range(int(rng.choice([0, 0, 1, 1, 2, 4]))):
        op = int(rng.integers(9))
        i = int(rng.integers(len(lines)))
        if op == 0:  # replace a token
            tokens = lines[i].split(" ")
            tokens[int(rng.integers(len(tokens)))] = str(rng.choice(_GARBAGE))
            lines[i] = " ".join(tokens)
        elif op == 1:  # append garbage to a line
            lines[i] += " " + str(rng.choice(_GARBAGE))
        elif op == 2:  # duplicate or drop a line
            if rng.random() < 0.5:
                lines.insert(i, lines[i])
            else:
                lines.pop(i)
        elif op == 3:  # swap two lines
            j = int(rng.integers(len(lines)))
            lines[i], lines[j] = lines[j], lines[i]
        elif op == 4:  # a random tag
            name = str(
                rng.choice(
                    ["crease", "corner", "interpolateboundary", "creasemethod", "hole", "zz"]
                )
            )
            ints = " ".join(str(int(x)) for x in rng.integers(-2, 12, int(rng.integers(0, 5))))
            counts = f"{rng.integers(0, 5)}/{rng.integers(0, 3)}/{rng.integers(0, 2)}"
            lines.insert(i, f"t {name} {counts} {ints} 1.5")
        elif op == 5:  # an index out of range or negative
            lines.insert(i, f"f 1 {int(rng.integers(-5, 200))} 3")
        elif op == 6:  # a long line
            lines.insert(
                i,
                "f "
                + " ".join(str(int(x)) for x in rng.integers(1, 9, int(rng.integers(3, 2000)))),
            )
        elif op == 7:  # unknown or free-form statements
            lines.insert(
                i, str(rng.choice(["curv 0 1 1 2", "xyz 1", "vp 0.5", "l 1 2", "usemtl m", "g"]))
            )
        else:  # nothing at the line level
            pass
    joined = "\n".join(lines)
    ending = str(rng.choice(["\n", "\r\n", "\r"], p=[0.8, 0.1, 0.1]))
    data = bytearray(joined.replace("\n", ending).encode("utf-8", "surrogatepass"))
    if rng.random() < 0.1:
        data[:0] = b"\xef\xbb\xbf"
    for _ in range(int(rng.integers(0, 3)) if rng.random() < 0.3 else 0):  # byte flips
        if data:
            data[int(rng.integers(len(data)))] = int(rng.integers(256))
    if rng.random() < 0.05 and data:  # truncation
        del data[int(rng.integers(len(data))) :]
    return bytes(data)


def gen_cli(rng: np.random.Generator) -> Spec:
    """A random CLI case: a mutated OBJ file and options (a few of them out of range)."""
    degree = int(rng.choice([1, 2, 3, 4, 5])) if rng.random() < 0.95 else int(rng.choice([0, 40]))
    levels = int(rng.choice([0, 1, 2, 3])) if rng.random() < 0.95 else 17
    args = ["--degree", str(degree), "--levels", str(levels)]
    if rng.random() < 0.2:
        args += ["--output", "dual"]
    if rng.random() < 0.2:
        args += ["--rules", "classic"]
    if rng.random() < 0.2:
        args += ["--creasing", str(rng.choice(["uniform", "chaikin"]))]
    if rng.random() < 0.2:
        args += ["--boundary", str(rng.choice(["edge-only", "edge-and-corner", "none"]))]
    if rng.random() < 0.15:
        args += ["--limit"]
    if rng.random() < 0.15:
        args += ["--normals"]
    if rng.random() < 0.2:
        args += ["--memory-budget", str(rng.choice(["64k", "16M", "256M", "256M"]))]
    if rng.random() < 0.05:
        args += ["--max-input-bytes", str(rng.choice(["10", "1k", "1M"]))]
    out = str(rng.choice([".obj", ".obj", ".obj", ".usda", ".usdc"]))
    if rng.random() < 0.15:
        out = ".obj"
        args += [
            "--adaptive",
            "--tolerance",
            str(rng.choice([0, 1e-3, 0.1])),
            "--max-level",
            str(int(rng.integers(0, 5))),
        ]
    data = mutate_obj(rng, _obj_text(rng))
    return {"kind": "cli", "obj_b64": base64.b64encode(data).decode(), "args": args, "out": out}


# ---------------------------------------------------------------------------------------------
# Running one case (in the child)


def _result_hash(*arrays: Any) -> str:
    digest = hashlib.sha256()
    for a in arrays:
        if a is not None:
            digest.update(np.ascontiguousarray(a).tobytes())
    return digest.hexdigest()[:16]


def _check(condition: bool, what: str) -> None:
    if not condition:
        raise AssertionError(what)


@contextlib.contextmanager
def _unlimited() -> Iterator[None]:
    """The harness's own checks of a result, outside the case's address-space limit: numpy's
    temporaries over a large result (``np.isfinite`` of every point) would otherwise be refused
    there, a MemoryError of the harness counted as a finding of the core."""
    soft, hard = resource.getrlimit(resource.RLIMIT_AS)
    resource.setrlimit(resource.RLIMIT_AS, (hard, hard))
    try:
        yield
    finally:
        resource.setrlimit(resource.RLIMIT_AS, (soft, hard))


def _run_api(spec: Spec) -> Outcome:
    import bidegree

    warnings.simplefilter("ignore", bidegree.IsolatedVerticesWarning)
    with np.errstate(over="ignore"):  # 1e300 as float32 is inf: a case like any other
        points = np.array(spec["points"], dtype=spec["dtype"]).reshape(-1, 3)
    inputs: dict[str, Any] = {"points": points}
    kwargs: dict[str, Any] = {"boundary": spec["boundary"], "creasing": spec["creasing"]}
    if spec["creases"]:
        c = spec["creases"]
        inputs["crease_edges"] = np.array([[a, b] for a, b, _ in c], dtype=np.int64)
        inputs["crease_sharpness"] = np.array([s for _, _, s in c], dtype=np.float32)
        kwargs["creases"] = (inputs["crease_edges"], inputs["crease_sharpness"])
    if spec["corners"]:
        inputs["corner_vertices"] = np.array([v for v, _ in spec["corners"]], dtype=np.int64)
        inputs["corner_sharpness"] = np.array([s for _, s in spec["corners"]], dtype=np.float32)
        kwargs["corners"] = (inputs["corner_vertices"], inputs["corner_sharpness"])
    if spec.get("holes"):
        inputs["holes"] = np.array(spec["holes"], dtype=np.int64)
        kwargs["holes"] = inputs["holes"]
    if spec["uvs"] is not None:
        with np.errstate(over="ignore"):
            inputs["uvs"] = np.array(spec["uvs"], dtype=spec["dtype"]).reshape(-1, 2)
        kwargs["uvs"] = inputs["uvs"]
    sizes = np.array([len(f) for f in spec["faces"]], dtype=np.int64)
    flat = [v for f in spec["faces"] for v in f]
    inputs["face_indices"] = np.array(flat, dtype=np.int64) if flat else np.zeros(0, np.int64)
    inputs["face_sizes"] = sizes
    saved = {k: v.copy() for k, v in inputs.items()}
    options = {
        "degree": spec["degree"],
        "levels": spec["levels"],
        "output": spec["output"],
        "memory_budget": spec["memory_budget"],
        "rules": spec["rules"],
    }
    digest = ""
    try:
        if spec["call"] == "panic":  # the harness's own check of its classification
            bidegree._native._panic_for_tests()
        if spec["call"] == "abort":
            os.abort()
        mesh = bidegree.Mesh(
            points, face_sizes=inputs["face_sizes"], face_indices=inputs["face_indices"], **kwargs
        )
        call = spec["call"]
        if call in ("subdivide", "write"):
            result = bidegree.subdivide(
                mesh, **options, limit=spec["limit"], normals=spec["normals"]
            )
            # The result's arrays, some made on first access, under the limit; then the checks.
            points, sizes, indices = result.points, result.face_sizes, result.face_indices
            normals, uvs, num_faces = result.normals, result.uvs, result.num_faces
            n = len(points)
            with _unlimited():
                _check(np.isfinite(points).all(), "non-finite points in a result")
                _check(len(sizes) == num_faces, "face count")
                _check(int(sizes.sum()) == len(indices), "corner count")
                _check(
                    len(indices) == 0 or (indices.min() >= 0 and indices.max() < n),
                    "face index out of range",
                )
                if normals is not None:
                    _check(normals.shape == (len(indices), 3), "normals shape")
                if uvs is not None:
                    _check(uvs.shape == (len(indices), 2), "uvs shape")
                digest = _result_hash(points, indices, normals, uvs)
            if call == "write":
                with tempfile.TemporaryDirectory() as directory:
                    target = Path(directory) / "out.obj"
                    result.write_obj(target)
                    back = bidegree.Mesh.from_obj(target)
                    _check(back.num_faces == result.num_faces, "OBJ round trip")
                    _check(sorted(os.listdir(directory)) == ["out.obj"], "files left")
        elif call == "plan":
            plan = bidegree.Plan(mesh, **options, creasing=spec["creasing"])
            values = np.random.default_rng(spec["seed"]).normal(
                size=(mesh.num_vertices, spec["channels"])
            )
            out = plan.evaluate(values.astype(spec["dtype"]))
            _check(out.shape == (plan.num_output_vertices, spec["channels"]), "evaluate shape")
            if mesh.uvs is not None:
                plan.evaluate_face_varying(mesh.uvs)
            if spec["limit"]:
                plan.limit_positions()
            if spec["normals"]:
                plan.limit_surface()
            _ = plan.edges, plan.corner_edges, plan.face_origin
            with _unlimited():
                digest = _result_hash(out)
        elif call == "adaptive":
            result = bidegree.subdivide_adaptive(
                mesh,
                degree=spec["degree"],
                max_level=spec["max_level"],
                tolerance=spec["tolerance"],
                memory_budget=spec["memory_budget"],
                measure_leaves=spec["measure_leaves"],
            )
            points, triangles = result.points, result.triangles
            n = len(points)
            with _unlimited():
                _check(np.isfinite(points).all(), "non-finite adaptive points")
                _check(
                    len(triangles) == 0 or (triangles.min() >= 0 and triangles.max() < n),
                    "triangle index out of range",
                )
                digest = _result_hash(points, triangles)
        else:
            bidegree.estimate(mesh, spec["degree"], spec["levels"], spec["output"])
        outcome: Outcome = {"outcome": "success", "label": "success", "hash": digest}
    except bidegree.InternalError as exc:
        detail = getattr(exc, "detail", "") or ""
        where = re.search(r"at (\S+?):\d+", detail)
        outcome = {
            "outcome": "other",
            "label": f"InternalError {where.group(1) if where else ''}".strip(),
            "detail": detail[:1000],
        }
    except bidegree.BidegreeError as exc:
        outcome = {"outcome": "typed", "label": type(exc).__name__, "detail": str(exc)[:300]}
    except Exception as exc:  # anything untyped is a finding
        outcome = {
            "outcome": "other",
            "label": f"{type(exc).__name__}: {re.sub(r'[0-9]+', 'N', str(exc))[:80]}",
            "detail": repr(exc)[:500],
        }
    for name, copy in saved.items():
        if not np.array_equal(inputs[name], copy, equal_nan=inputs[name].dtype.kind == "f"):
            return {"outcome": "other", "label": f"input {name} was modified"}
    return outcome


def _limit_child() -> None:
    # The soft limit only, so that the harness can lift it for its own checks (`_unlimited`).
    hard = resource.getrlimit(resource.RLIMIT_AS)[1]
    soft = ADDRESS_SPACE if hard == resource.RLIM_INFINITY else min(ADDRESS_SPACE, hard)
    resource.setrlimit(resource.RLIMIT_AS, (soft, hard))
    resource.setrlimit(resource.RLIMIT_CPU, (CPU_SECONDS, CPU_SECONDS))


def run_api_case(spec: Spec, threads: int | None = None, fresh: bool = False) -> Outcome:
    """Runs an API case in a child (limited) and returns its outcome: forked from this process
    (fast; only from a process that never ran the core, whose thread pool would be missing in
    the child), or with ``fresh`` a new interpreter (from anywhere, e.g. a test)."""
    if fresh:
        env = {**os.environ, **({"RAYON_NUM_THREADS": str(threads)} if threads else {})}
        try:
            proc = subprocess.run(
                [sys.executable, __file__, "--run-api"],
                input=json.dumps(spec),
                capture_output=True,
                text=True,
                timeout=WALL_SECONDS,
                preexec_fn=_limit_child,
                env=env,
                check=False,
            )
        except subprocess.TimeoutExpired:
            return {"outcome": "other", "label": "timeout"}
        if proc.returncode < 0:
            return {"outcome": "other", "label": f"signal {signal.Signals(-proc.returncode).name}"}
        try:
            return json.loads(proc.stdout.splitlines()[-1])
        except (IndexError, json.JSONDecodeError):
            return {"outcome": "other", "label": f"child exited {proc.returncode} silently"}
    read, write = os.pipe()
    pid = os.fork()
    if pid == 0:  # the child
        try:
            os.close(read)
            if threads is not None:
                os.environ["RAYON_NUM_THREADS"] = str(threads)
            _limit_child()
            outcome = _run_api(spec)
        except BaseException as exc:  # MemoryError in the harness itself, and the like
            outcome = {"outcome": "other", "label": f"harness: {type(exc).__name__}"}
        with os.fdopen(write, "w") as pipe:
            json.dump(outcome, pipe)
        os._exit(0)
    os.close(write)
    deadline = time.monotonic() + WALL_SECONDS
    status = None
    while time.monotonic() < deadline:
        done, status = os.waitpid(pid, os.WNOHANG)
        if done:
            break
        time.sleep(0.002)
    else:
        os.kill(pid, signal.SIGKILL)
        os.waitpid(pid, 0)
        os.close(read)
        return {"outcome": "other", "label": "timeout"}
    with os.fdopen(read) as pipe:
        text = pipe.read()
    if os.WIFSIGNALED(status):
        return {"outcome": "other", "label": f"signal {signal.Signals(os.WTERMSIG(status)).name}"}
    if not text:
        return {"outcome": "other", "label": f"child exited {os.WEXITSTATUS(status)} silently"}
    return json.loads(text)


def _bidegree_command() -> list[str]:
    script = Path(sys.executable).parent / "bidegree"
    return [str(script)] if script.exists() else [sys.executable, "-m", "bidegree.cli"]


def run_cli_case(spec: Spec) -> Outcome:
    """Runs a CLI case in a child process (limited) and returns its outcome."""
    with tempfile.TemporaryDirectory() as directory:
        folder = Path(directory)
        cage = folder / "in.obj"
        cage.write_bytes(base64.b64decode(spec["obj_b64"]))
        out_dir = folder / "out"
        out_dir.mkdir()
        out = out_dir / f"result{spec['out']}"
        try:
            proc = subprocess.run(
                [*_bidegree_command(), "subdivide", str(cage), "-o", str(out), *spec["args"]],
                capture_output=True,
                text=True,
                errors="replace",
                timeout=WALL_SECONDS,
                preexec_fn=_limit_child,
                check=False,
            )
        except subprocess.TimeoutExpired:
            return {"outcome": "other", "label": "timeout"}
        left = sorted(os.listdir(out_dir))
        lines = (
            proc.stderr.split("\n")[:-1] if proc.stderr.endswith("\n") else proc.stderr.split("\n")
        )
        lines = [line for line in lines if line]
        errors = [line for line in lines if not line.startswith("bidegree: warning: ")]
        leak = re.search(r"Traceback|panicked|RUST_BACKTRACE|thread '", proc.stderr)
        if proc.returncode == 0 and not errors and left == [out.name] and not leak:
            return {"outcome": "success", "label": "success"}
        if (
            proc.returncode == 2
            and len(errors) == 1
            and errors[0].startswith("bidegree: error: ")
            and "internal error" not in errors[0]
            and not left
            and not leak
        ):
            label = re.sub(r"\d+", "N", errors[0].split(": ", 3)[-1])[:60]
            return {"outcome": "typed", "label": label, "detail": errors[0][:300]}
        if proc.returncode < 0:
            label = f"signal {signal.Signals(-proc.returncode).name}"
        elif "internal error" in proc.stderr:
            label = "internal error"
        elif leak:
            label = f"exit {proc.returncode} with {leak.group(0)}"
        elif left and proc.returncode != 0:
            label = "a file left after an error"
        else:
            label = f"exit {proc.returncode}, {len(errors)} stderr lines"
        return {"outcome": "other", "label": label, "detail": proc.stderr[-2000:]}


def run_case(spec: Spec, fresh: bool = False) -> Outcome:
    """The outcome of one case (of either kind), run in a child."""
    return run_api_case(spec, fresh=fresh) if spec["kind"] == "api" else run_cli_case(spec)


def replay(path: Path) -> Outcome:
    """Replays a regression file written by the fuzzer (each case in a new interpreter, so it
    can be called from a process that has used the core)."""
    return run_case(json.loads(path.read_text())["spec"], fresh=True)


# ---------------------------------------------------------------------------------------------
# Shrinking and regression files


def shrink(spec: Spec, label: str, fresh: bool, budget: int = 40) -> Spec:
    """A smaller API case with the same failure ``label``: fewer creases, corners, faces; lower
    levels and degree. At most ``budget`` child runs."""
    if spec["kind"] != "api":
        return spec
    best = spec
    tries = 0

    def attempt(candidate: Spec) -> bool:
        nonlocal best, tries
        tries += 1
        if tries > budget:
            return False
        if run_api_case(candidate, fresh=fresh).get("label") == label:
            best = candidate
            return True
        return False

    for key, simpler in (
        ("uvs", None),
        ("creases", []),
        ("corners", []),
        ("holes", []),
        ("levels", 1),
        ("degree", 3),
        ("dtype", "float64"),
    ):
        if best.get(key, simpler) != simpler:
            attempt({**best, key: simpler})
    i = 0
    while i < len(best["faces"]) and tries < budget:
        fewer = best["faces"][:i] + best["faces"][i + 1 :]
        if not (fewer and attempt({**best, "faces": fewer})):
            i += 1
    return best


def _slug(label: str) -> str:
    return re.sub(r"[^a-z0-9]+", "-", label.lower()).strip("-")[:50] or "case"


def save_regression(spec: Spec, outcome: Outcome, directory: Path, seed: int) -> Path | None:
    """Writes a regression file unless ``PER_SIGNATURE`` files for this failure exist."""
    directory.mkdir(parents=True, exist_ok=True)
    stem = f"{spec['kind']}-{_slug(outcome['label'])}"
    existing = sorted(directory.glob(f"{stem}-*.json"))
    if len(existing) >= PER_SIGNATURE:
        return None
    path = directory / f"{stem}-{len(existing) + 1}.json"
    record = {
        "found": time.strftime("%Y-%m-%d"),
        "seed": seed,
        "outcome": outcome,
        "spec": spec,
    }
    path.write_text(json.dumps(record, indent=1) + "\n")
    return path


# ---------------------------------------------------------------------------------------------
# The loop


def main(argv: list[str] | None = None) -> int:
    """Runs the fuzzer; exit status 1 if any case ended as *other*."""
    if argv is None and sys.argv[1:] == ["--run-api"]:  # the child of a fresh API case
        print(json.dumps(_run_api(json.loads(sys.stdin.read()))))
        return 0
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--minutes", type=float, default=1.0, help="how long to run")
    parser.add_argument("--cases", type=int, default=None, help="stop after this many cases")
    parser.add_argument("--seed", type=int, default=None, help="random seed (default: time)")
    parser.add_argument("--out", type=Path, default=REGRESSIONS, help="regression folder")
    parser.add_argument("--cli-share", type=float, default=0.35, help="share of CLI cases")
    parser.add_argument(
        "--fresh",
        action="store_true",
        help="run API cases in new interpreters instead of forks (slower; for a caller that "
        "has used the core)",
    )
    args = parser.parse_args(argv)
    seed = args.seed if args.seed is not None else int(time.time())
    rng = np.random.default_rng(seed)
    deadline = time.monotonic() + 60 * args.minutes
    counts: Counter[str] = Counter()
    labels: dict[str, Counter[str]] = {"typed": Counter(), "other": Counter()}
    kinds: Counter[str] = Counter()
    print(f"fuzz: seed {seed}, {args.minutes:g} minutes, regressions into {args.out}", flush=True)
    last_report = time.monotonic()
    n = 0
    while time.monotonic() < deadline and (args.cases is None or n < args.cases):
        n += 1
        spec = gen_cli(rng) if rng.random() < args.cli_share else gen_api(rng)
        outcome = run_case(spec, fresh=args.fresh)
        if (
            outcome["outcome"] == "success"
            and spec["kind"] == "api"
            and outcome.get("hash")
            and rng.random() < 0.05
        ):
            # Results are bitwise the same whatever the thread count.
            single = run_api_case(spec, threads=1, fresh=args.fresh)
            if single.get("hash") != outcome["hash"]:
                outcome = {"outcome": "other", "label": "result depends on the thread count"}
        counts[outcome["outcome"]] += 1
        kinds[f"{spec['kind']} {outcome['outcome']}"] += 1
        if outcome["outcome"] in labels:
            labels[outcome["outcome"]][outcome["label"]] += 1
        if outcome["outcome"] == "other":
            small = shrink(spec, outcome["label"], args.fresh)
            saved = save_regression(small, outcome, args.out, seed)
            print(
                f"fuzz: other: {outcome['label']}" + (f" -> {saved}" if saved else ""), flush=True
            )
        if time.monotonic() - last_report > 60:
            last_report = time.monotonic()
            print(f"fuzz: {n} cases: {dict(counts)}", flush=True)
    print(f"fuzz: {n} cases, seed {seed}")
    print(f"success {counts['success']}, typed error {counts['typed']}, other {counts['other']}")
    print("by kind: " + ", ".join(f"{k} {v}" for k, v in sorted(kinds.items())))
    for outcome in ("typed", "other"):
        if labels[outcome]:
            print(f"{outcome}:")
            for label, count in labels[outcome].most_common(25):
                print(f"  {count:6d}  {label}")
    return 1 if counts["other"] else 0


if __name__ == "__main__":
    sys.exit(main())
