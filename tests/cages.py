"""Cages shared by the Python tests: a unit cube and a regular torus."""

from __future__ import annotations

import bidegree
import numpy as np

CUBE_POINTS = np.array(
    [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0, 0, 1], [1, 0, 1], [1, 1, 1], [0, 1, 1]],
    dtype=np.float64,
)
CUBE_FACES = [[0, 3, 2, 1], [4, 5, 6, 7], [0, 1, 5, 4], [1, 2, 6, 5], [2, 3, 7, 6], [3, 0, 4, 7]]


def cube(dtype: type = np.float64, **kwargs: object) -> bidegree.Mesh:
    """The unit cube (outward faces), points of the given dtype; kwargs go to ``Mesh``."""
    return bidegree.Mesh(CUBE_POINTS.astype(dtype), CUBE_FACES, **kwargs)


def torus(
    n: int = 12, m: int = 8, big: float = 2.0, small: float = 0.7, **kwargs: object
) -> bidegree.Mesh:
    """A closed all-quad torus: every vertex has valence 4 (a regular mesh)."""
    i, j = np.meshgrid(np.arange(n), np.arange(m), indexing="ij")
    u, v = 2 * np.pi * i / n, 2 * np.pi * j / m
    points = np.stack(
        [
            (big + small * np.cos(v)) * np.cos(u),
            small * np.sin(v),
            (big + small * np.cos(v)) * np.sin(u),
        ],
        axis=-1,
    ).reshape(-1, 3)
    a, b = i * m + j, ((i + 1) % n) * m + j
    c, d = ((i + 1) % n) * m + (j + 1) % m, i * m + (j + 1) % m
    return bidegree.Mesh(points, np.stack([a, d, c, b], axis=-1).reshape(-1, 4), **kwargs)
