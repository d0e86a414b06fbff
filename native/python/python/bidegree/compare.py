"""Compare bidegree's degree-N surface with the real OpenSubdiv Catmull-Clark surface of a cage.

What is compared
    bidegree subdivides the cage with the Zorin-Schröder repeated-averaging scheme of degree N
    (:func:`bidegree.subdivide`).  The reference is OpenSubdiv's Catmull-Clark surface of the
    *same* cage, with the same boundary rule and the same creases and corners, refined uniformly to
    the same number of levels (or, with ``limit=True``, the refined vertices pushed to their
    limit positions).  For degree 3 on a closed all-quad cage where every vertex has valence 4
    the two schemes coincide (both are uniform bicubic B-spline refinement), so their refined
    points are identical at every level; elsewhere (extraordinary vertices, other degrees) they
    differ slightly, and this module measures by how much.

How OpenSubdiv is run: Blender as a Python module (``bpy``)
    Blender's Subdivision Surface modifier *is* OpenSubdiv 3.x (Blender links it and evaluates
    the modifier with it).  The ``bpy`` wheel from PyPI therefore gives the real OpenSubdiv
    implementation without a C++ toolchain, CMake build or binding layer of our own: the cage is
    built as a bpy mesh with numpy fast paths (``foreach_set``), the modifier is configured
    (``use_limit_surface=False`` = uniform refinement, ``True`` = limit positions;
    ``boundary_smooth='ALL'`` = edge-only, ``'PRESERVE_CORNERS'`` = edge-and-corner; creases as
    the ``crease_edge`` / ``crease_vert`` float attributes, Blender value c = sqrt(sharpness / 10)
    clamped to 1, which Blender turns back into sharpness 10 c^2), the depsgraph evaluates it,
    and the result is read back with ``foreach_get``.  UVs go in as the UV map and come back per
    face corner, refined in one of OpenSubdiv's six face-varying modes (:data:`UV_SMOOTH`); every
    face carries its cage face's index through the modifier as an integer face attribute, which
    is how holes (which Blender does not have) are left out of the result, and boundary
    ``none`` (which Blender does not have either) is edge-only with OpenSubdiv's boundary faces
    as holes; loose edges go in as edges (Blender makes their vertices infinitely sharp).
    ``docs/research/`` says how each of these was checked against OpenSubdiv itself.  Binding
    OpenSubdiv directly from Rust
    (e.g. the ``opensubdiv-petite`` crate behind a cargo feature) remains possible later; it would
    remove the bpy dependency of this tool but needs a C++ build of OpenSubdiv.

How distances are measured
    Point-to-surface distances both ways: every vertex of the bidegree mesh to the OpenSubdiv
    mesh, and every (face-referenced) vertex of the OpenSubdiv mesh to the bidegree mesh.  The
    target surface is the polygon mesh fan-triangulated; the distance is the exact Euclidean
    distance to the nearest triangle (not to the nearest vertex), found with a sparse uniform grid
    (numpy only; scipy is not required): triangles are binned into every cell their bounding box
    overlaps; a query looks at the (at most 2x2x2) cells overlapped by the cube of half-size
    r = cell/2 around it, prunes candidates with cheap bounds (distance to a vertex, distance to
    the bounding box), evaluates the exact point-to-triangle distance of the rest, and is final
    when the best distance is <= r (no triangle outside those cells can be closer).  Unresolved
    queries are retried on a coarser grid whose r covers their best candidate.  Reported: max,
    RMS and mean per direction and symmetric (the max of both directions is the vertex-sampled
    Hausdorff distance), each also relative to the diagonal of the cage's bounding box.  The
    distance between the two *vertex sets* (nearest vertex, both ways) is reported too: it is ~0
    exactly when the refined points coincide.  Cost: about 20-30 microseconds per vertex and
    direction on a small machine (a 262,144-face comparison takes ~15 s); meant for moderate
    meshes.

Report
    :func:`write_usd` writes the bidegree USD (see :mod:`bidegree.usd`) with the distances as
    ``primvars:distance`` on ``/Bidegree/Result`` and the OpenSubdiv surface, with its own
    distances, as ``/Bidegree/OpenSubdiv``; :func:`write_plot` draws both surfaces, the bidegree
    surface coloured by distance and a histogram (matplotlib, Agg).
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np

__all__ = [
    "UV_SMOOTH",
    "Comparison",
    "SurfaceMesh",
    "add_arguments",
    "blender_mesh",
    "boundary_none_holes",
    "compare",
    "distances_to_mesh",
    "nearest_point_distances",
    "opensubdiv_surface",
    "point_triangle_distances",
    "run",
    "triangulate",
    "write_plot",
]

#: Blender's Subdivision Surface modifier accepts at most this many levels.
MAX_BPY_LEVELS = 11

_CHUNK = 65_536  # (query, triangle) pairs evaluated at once (cache-sized)


@dataclass
class SurfaceMesh:
    """A polygon mesh: points (N, 3) float64, face_sizes (F,) int32, face_indices (sum,) int32;
    optionally the cage face of each face (F,) int32 and face-varying values (sum, 2) float64."""

    points: np.ndarray
    face_sizes: np.ndarray
    face_indices: np.ndarray
    face_origin: np.ndarray | None = None
    uvs: np.ndarray | None = None

    @property
    def num_vertices(self) -> int:
        return int(self.points.shape[0])

    @property
    def num_faces(self) -> int:
        return int(self.face_sizes.size)

    def used_vertices(self) -> np.ndarray:
        """Indices of the vertices referenced by at least one face (sorted)."""
        return np.unique(self.face_indices)


# --------------------------------------------------------------------------------------------
# geometry: triangles, point-to-triangle distance, grid search


def triangulate(face_sizes: np.ndarray, face_indices: np.ndarray) -> np.ndarray:
    """Fan-triangulate polygons: (T, 3) int64 vertex indices, T = sum(size - 2)."""
    sizes = np.asarray(face_sizes, dtype=np.int64)
    idx = np.asarray(face_indices, dtype=np.int64)
    starts = np.zeros(sizes.size, dtype=np.int64)
    np.cumsum(sizes[:-1], out=starts[1:])
    ntri = sizes - 2
    face = np.repeat(np.arange(sizes.size, dtype=np.int64), ntri)
    tri_starts = np.zeros(sizes.size, dtype=np.int64)
    np.cumsum(ntri[:-1], out=tri_starts[1:])
    k = np.arange(face.size, dtype=np.int64) - tri_starts[face]  # fan triangle number in face
    base = starts[face]
    return np.stack([idx[base], idx[base + k + 1], idx[base + k + 2]], axis=1)


def _dot(ax, ay, az, bx, by, bz):
    return ax * bx + ay * by + az * bz


def _segment_sqdist(px, py, pz, ax, ay, az, bx, by, bz):
    ex, ey, ez = bx - ax, by - ay, bz - az
    wx, wy, wz = px - ax, py - ay, pz - az
    ee = _dot(ex, ey, ez, ex, ey, ez)
    t = np.divide(_dot(wx, wy, wz, ex, ey, ez), ee, out=np.zeros_like(ee), where=ee > 0)
    np.clip(t, 0.0, 1.0, out=t)
    dx, dy, dz = wx - t * ex, wy - t * ey, wz - t * ez
    return _dot(dx, dy, dz, dx, dy, dz)


def _sqdist_soa(
    px: np.ndarray, py: np.ndarray, pz: np.ndarray, tri: tuple[np.ndarray, ...]
) -> np.ndarray:
    """Squared point-triangle distance; ``tri`` = (ax, ay, az, bx, by, bz, cx, cy, cz) columns."""
    ax, ay, az, bx, by, bz, cx, cy, cz = tri
    d2 = _segment_sqdist(px, py, pz, ax, ay, az, bx, by, bz)
    np.minimum(d2, _segment_sqdist(px, py, pz, bx, by, bz, cx, cy, cz), out=d2)
    np.minimum(d2, _segment_sqdist(px, py, pz, cx, cy, cz, ax, ay, az), out=d2)
    # interior: the projection onto the plane lies inside the triangle
    e0x, e0y, e0z = bx - ax, by - ay, bz - az
    e1x, e1y, e1z = cx - ax, cy - ay, cz - az
    nx = e0y * e1z - e0z * e1y
    ny = e0z * e1x - e0x * e1z
    nz = e0x * e1y - e0y * e1x
    nn = _dot(nx, ny, nz, nx, ny, nz)
    inside = nn > 0
    for ux, uy, uz, vx, vy, vz in (
        (ax, ay, az, bx, by, bz),
        (bx, by, bz, cx, cy, cz),
        (cx, cy, cz, ax, ay, az),
    ):
        ex, ey, ez = vx - ux, vy - uy, vz - uz
        wx, wy, wz = px - ux, py - uy, pz - uz
        # (e x w) . n >= 0  <=>  p projects to the inner side of edge u->v
        side = _dot(ey * wz - ez * wy, ez * wx - ex * wz, ex * wy - ey * wx, nx, ny, nz)
        inside &= side >= 0
    plane = _dot(px - ax, py - ay, pz - az, nx, ny, nz)
    plane_d2 = np.divide(plane * plane, nn, out=np.zeros_like(nn), where=nn > 0)
    return np.where(inside, np.minimum(plane_d2, d2), d2)


def point_triangle_distances(
    p: np.ndarray, a: np.ndarray, b: np.ndarray, c: np.ndarray
) -> np.ndarray:
    """Exact Euclidean distance from each point ``p[i]`` to triangle ``(a[i], b[i], c[i])``.

    All arrays are (M, 3).  Degenerate triangles (segments, points) are handled: the distance is
    then the distance to the segment or point.
    """
    cols = [np.asarray(x, dtype=np.float64) for x in (p, a, b, c)]
    tri = tuple(cols[i][:, k] for i in (1, 2, 3) for k in range(3))
    return np.sqrt(_sqdist_soa(cols[0][:, 0], cols[0][:, 1], cols[0][:, 2], tri))


_KEY_BITS = 20
_KEY_BIAS = 1 << (_KEY_BITS - 1)


def _cell_keys(cells: np.ndarray) -> np.ndarray:
    """Pack integer cell coordinates (..., 3) into int64 keys (coordinates clipped to +-2^19)."""
    c = np.clip(cells, -_KEY_BIAS, _KEY_BIAS - 1) + _KEY_BIAS
    return (c[..., 0] << (2 * _KEY_BITS)) | (c[..., 1] << _KEY_BITS) | c[..., 2]


class _TriangleGrid:
    """Sparse uniform grid of triangles, each binned into every cell its bounding box overlaps."""

    def __init__(self, lo: np.ndarray, tmin: np.ndarray, tmax: np.ndarray, h: float) -> None:
        self.lo = lo
        self.h = h
        cmin = np.floor((tmin - lo) / h).astype(np.int64)
        cmax = np.floor((tmax - lo) / h).astype(np.int64)
        self.cmin = [np.ascontiguousarray(cmin[:, k]) for k in range(3)]
        span = cmax - cmin + 1
        count = span.prod(axis=1)
        tri = np.repeat(np.arange(tmin.shape[0], dtype=np.int64), count)
        first = np.zeros(count.size, dtype=np.int64)
        np.cumsum(count[:-1], out=first[1:])
        k = np.arange(tri.size, dtype=np.int64) - first[tri]
        sx, sy = span[tri, 0], span[tri, 1]
        cell = cmin[tri] + np.stack([k % sx, (k // sx) % sy, k // (sx * sy)], axis=1)
        keys = _cell_keys(cell)
        order = np.argsort(keys, kind="stable")
        keys = keys[order]
        self.tris = tri[order]
        self.keys, self.starts, self.counts = np.unique(keys, return_index=True, return_counts=True)

    def lookup(self, queries: np.ndarray, radius: float) -> tuple[np.ndarray, ...]:
        """The (up to 8) cells that the cube of half-size ``radius`` (<= h / 2) around each query
        overlaps: per query the lowest cell ``c0`` (M, 3), and per slot (M, 8) the start position
        into ``tris`` and the count (0 = empty, missing or repeated cell)."""
        rel = (queries - self.lo) / self.h
        c0 = np.floor(rel - radius / self.h).astype(np.int64)
        c1 = np.floor(rel + radius / self.h).astype(np.int64)  # c0 or c0 + 1 per axis
        m = queries.shape[0]
        keys = np.empty((m, 8), dtype=np.int64)
        valid = np.ones((m, 8), dtype=bool)
        same = c1 == c0
        for s in range(8):
            pick = _SLOT_PICK[s]
            keys[:, s] = _cell_keys(np.where(pick, c1, c0))
            # a slot that repeats another one (c1 == c0 on a picked axis) is skipped
            valid[:, s] = ~np.any(pick & same, axis=1)
        pos = np.minimum(np.searchsorted(self.keys, keys), self.keys.size - 1)
        hit = (self.keys[pos] == keys) & valid
        return c0, self.starts[pos], np.where(hit, self.counts[pos], 0)

    def pairs(
        self, c0: np.ndarray, starts: np.ndarray, counts: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """Expand :meth:`lookup` output into unique (query, triangle) pairs grouped by query.

        A triangle overlapping several of a query's cells is kept only from the lowest of them
        (per axis: max(triangle's first cell, c0))."""
        m, nslots = starts.shape
        n = counts.ravel()
        pair_qs = np.repeat(np.arange(m * nslots, dtype=np.int64), n)
        first = np.zeros(n.size, dtype=np.int64)
        np.cumsum(n[:-1], out=first[1:])
        offset = np.arange(pair_qs.size, dtype=np.int64) - np.repeat(first, n)
        pair_t = self.tris[np.repeat(starts.ravel(), n) + offset]
        pair_q = pair_qs // nslots
        slot = pair_qs - pair_q * nslots
        keep = np.ones(pair_q.size, dtype=bool)
        for k in range(3):
            c0k = c0[:, k].take(pair_q)
            cell = c0k + ((slot >> (2 - k)) & 1)
            keep &= cell == np.maximum(self.cmin[k].take(pair_t), c0k)
        return pair_q[keep], pair_t[keep]


_SLOT_PICK = np.array([[(s >> 2) & 1, (s >> 1) & 1, s & 1] for s in range(8)], dtype=bool)


def _grid_search(
    grid: _TriangleGrid,
    sub: np.ndarray,
    radius: float,
    tcols: list[np.ndarray],
    bmin: list[np.ndarray],
    bmax: list[np.ndarray],
) -> np.ndarray:
    """Best distance from each query to the triangles in its cells (inf when there are none)."""
    best = np.full(sub.shape[0], np.inf)
    n_queries = sub.shape[0]
    c0, starts, counts = grid.lookup(sub, radius)
    # process queries in blocks of about _CHUNK (query, cell entry) pairs
    cum = np.cumsum(counts.sum(axis=1))
    q0 = 0
    while q0 < n_queries:
        base = cum[q0 - 1] if q0 else 0
        q1 = max(int(np.searchsorted(cum, base + _CHUNK, side="right")), q0 + 1)
        q1 = min(q1, n_queries)
        pair_q, pair_t = grid.pairs(c0[q0:q1], starts[q0:q1], counts[q0:q1])
        if pair_q.size:
            qs = sub[q0:q1]
            px, py, pz = (qs[:, k].take(pair_q) for k in range(3))
            run = np.flatnonzero(np.r_[True, pair_q[1:] != pair_q[:-1]])
            # cheap bounds: distance to the first vertex (upper), to the bounding box (lower);
            # both computed without rounding trouble (the vertex is exactly on the triangle)
            dx, dy, dz = ((px, py, pz)[k] - tcols[k].take(pair_t) for k in range(3))
            upper = np.minimum.reduceat(dx * dx + dy * dy + dz * dz, run)
            lower = np.zeros_like(px)
            for k, pk in enumerate((px, py, pz)):
                gap = np.maximum(
                    np.maximum(bmin[k].take(pair_t) - pk, pk - bmax[k].take(pair_t)), 0.0
                )
                lower += gap * gap
            counts_run = np.diff(np.r_[run, pair_q.size])
            keep = lower <= np.repeat(upper, counts_run) * (1.0 + 1e-9)
            pair_q, pair_t = pair_q[keep], pair_t[keep]
            px, py, pz = px[keep], py[keep], pz[keep]
            if pair_q.size == 0:  # cannot happen (the bounding pair is kept); stay safe
                q0 = q1
                continue
            d2 = _sqdist_soa(px, py, pz, tuple(col.take(pair_t) for col in tcols))
            # pairs are grouped by query: reduce each query's run
            run = np.flatnonzero(np.r_[True, pair_q[1:] != pair_q[:-1]])
            best[q0 + pair_q[run]] = np.sqrt(np.minimum.reduceat(d2, run))
        q0 = q1
    return best


def _nearest_triangle_distances(
    queries: np.ndarray, points: np.ndarray, triangles: np.ndarray
) -> np.ndarray:
    """Distance from each query point (M, 3) to the nearest triangle (T, 3) of ``points``.

    Exact: a query is final once the best distance found is <= the search radius r, because
    every triangle that comes within r of the query has its bounding box in the searched cells.
    An unresolved query is retried on a coarser grid whose radius covers the best candidate
    found so far (or 4x coarser when none was found).
    """
    queries = np.asarray(queries, dtype=np.float64)
    points = np.asarray(points, dtype=np.float64)
    m = queries.shape[0]
    result = np.full(m, np.inf)
    if m == 0:
        return result
    if triangles.shape[0] == 0:
        raise ValueError("the target mesh has no triangles")
    cols = [np.ascontiguousarray(points[:, k]) for k in range(3)]
    tcols = [cols[k][triangles[:, j]] for j in range(3) for k in range(3)]
    a = np.stack(tcols[0:3], axis=1)
    b = np.stack(tcols[3:6], axis=1)
    c = np.stack(tcols[6:9], axis=1)
    tmin = np.minimum(np.minimum(a, b), c)
    tmax = np.maximum(np.maximum(a, b), c)
    bmin = [np.ascontiguousarray(tmin[:, k]) for k in range(3)]
    bmax = [np.ascontiguousarray(tmax[:, k]) for k in range(3)]
    lo = np.minimum(tmin.min(axis=0), queries.min(axis=0))
    hi = np.maximum(tmax.max(axis=0), queries.max(axis=0))
    world = float(np.linalg.norm(hi - lo))
    extent = (tmax - tmin).max(axis=1)
    h = float(extent.mean())
    if h == 0.0:  # points only: typical spacing of points on a surface
        h = world / math.sqrt(triangles.shape[0])
    # bound the number of cells per triangle, and keep the cell size positive
    h = max(h, float(extent.max()) / 32.0, world * 1e-5, 1e-300)
    # Each query has a level e (cell size h * 2^e, search radius half of it).  A query whose
    # best candidate is farther than the radius moves to the level whose radius covers that
    # candidate, where it is then certain to be resolved.
    level = np.zeros(m, dtype=np.int64)
    pending = np.ones(m, dtype=bool)
    while pending.any():
        e = int(level[pending].min())
        active = np.flatnonzero(pending & (level == e))
        cell = h * 2.0**e
        radius = 0.5 * cell
        grid = _TriangleGrid(lo, tmin, tmax, cell)
        best = _grid_search(grid, queries[active], radius, tcols, bmin, bmax)
        done = best <= radius
        if radius > world:  # the searched cells contain every triangle
            done[:] = True
        result[active[done]] = best[done]
        pending[active[done]] = False
        todo = ~done
        need = np.full(int(todo.sum()), e + 2, dtype=np.int64)
        finite = np.isfinite(best[todo])
        need[finite] = np.maximum(
            e + 1, np.ceil(np.log2(2.0 * best[todo][finite] / h)).astype(np.int64)
        )
        level[active[todo]] = need
    return result


def distances_to_mesh(queries: np.ndarray, mesh: SurfaceMesh) -> np.ndarray:
    """Exact distance from each query point (M, 3) to the (fan-triangulated) surface of ``mesh``."""
    return _nearest_triangle_distances(
        queries, mesh.points, triangulate(mesh.face_sizes, mesh.face_indices)
    )


def nearest_point_distances(queries: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Distance from each query point (M, 3) to the nearest of ``points`` (K, 3)."""
    n = np.asarray(points).shape[0]
    degenerate = np.repeat(np.arange(n, dtype=np.int64)[:, None], 3, axis=1)
    return _nearest_triangle_distances(queries, points, degenerate)


# --------------------------------------------------------------------------------------------
# OpenSubdiv through bpy


def _blender_crease(sharpness: np.ndarray) -> np.ndarray:
    """Blender crease value c with sharpness = 10 c^2 (c clamped to [0, 1]; inf -> 1)."""
    s = np.asarray(sharpness, dtype=np.float64)
    s = np.where(np.isposinf(s), 10.0, s)
    return np.clip(np.sqrt(np.clip(s, 0.0, None) / 10.0), 0.0, 1.0).astype(np.float32)


def _pair_arrays(value: Any) -> tuple[np.ndarray, np.ndarray] | None:
    if value is None:
        return None
    first, second = value
    first, second = np.asarray(first), np.asarray(second)
    if first.size == 0:
        return None
    return first, second


#: Face-varying modes (OpenSubdiv's ``Sdc::Options::FVarLinearInterpolation``, issue 14's names)
#: -> Blender's ``uv_smooth`` (``BKE_subdiv_fvar_interpolation_from_uv_smooth``). Blender's
#: ``NONE`` is OpenSubdiv's linear ``ALL`` and Blender's ``SMOOTH_ALL`` OpenSubdiv's ``NONE``.
UV_SMOOTH = {
    "none": "SMOOTH_ALL",
    "corners-only": "PRESERVE_CORNERS",
    "corners-plus1": "PRESERVE_CORNERS_AND_JUNCTIONS",
    "corners-plus2": "PRESERVE_CORNERS_JUNCTIONS_AND_CONCAVE",
    "boundaries": "PRESERVE_BOUNDARIES",
    "all": "NONE",
}

#: Name of the face attribute that carries each cage face's index through the modifier.
_ORIGIN = "bidegree_compare_origin"


def _edge_keys(a: np.ndarray, b: np.ndarray, n: int) -> np.ndarray:
    lo, hi = np.minimum(a, b).astype(np.int64), np.maximum(a, b).astype(np.int64)
    return lo * n + hi


def boundary_none_holes(cage: Any) -> np.ndarray:
    """The faces OpenSubdiv makes holes under ``VTX_BOUNDARY_NONE`` (sorted face indices).

    ``Far::TopologyRefinerFactoryBase::prepareComponentTagsAndSharpness``: every face at a vertex
    that has a boundary edge (one face) which the user did not make infinitely sharp. A degenerate
    edge (a face repeating a vertex consecutively) is an edge of its own with one face there.
    """
    sizes = np.asarray(cage.face_sizes, dtype=np.int64)
    idx = np.asarray(cage.face_indices, dtype=np.int64)
    n = int(np.asarray(cage.points).shape[0])
    starts = np.zeros(sizes.size, dtype=np.int64)
    np.cumsum(sizes[:-1], out=starts[1:])
    face = np.repeat(np.arange(sizes.size), sizes)
    nxt = np.arange(1, idx.size + 1)
    nxt[starts + sizes - 1] = starts
    a, b = idx, idx[nxt]
    keys = _edge_keys(a, b, n)
    _, inverse, counts = np.unique(keys, return_inverse=True, return_counts=True)
    boundary = (counts[inverse] == 1) | (a == b)
    creases = _pair_arrays(getattr(cage, "creases", None))
    if creases is not None:
        pairs, sharp = creases
        pairs = np.asarray(pairs, dtype=np.int64).reshape(-1, 2)
        infinite = np.asarray(sharp, dtype=np.float64) >= 10.0
        sharp_keys = _edge_keys(pairs[infinite, 0], pairs[infinite, 1], n)
        boundary &= ~np.isin(keys, sharp_keys)
    open_vertices = np.zeros(n, dtype=bool)
    open_vertices[a[boundary]] = True
    open_vertices[b[boundary]] = True
    return np.unique(face[open_vertices[idx]])


def blender_mesh(cage: Any, name: str) -> Any:
    """A new ``bpy.types.Mesh`` of ``cage`` as :func:`opensubdiv_surface` hands it to Blender.

    Faces (a face may repeat a vertex), ``loose_edges`` when present, each face's index in the
    integer face attribute ``bidegree_compare_origin`` (Blender's modifier carries it to every
    child face), ``uvs`` as the UV map ``UVMap``, creases and corners as the ``crease_edge`` /
    ``crease_vert`` attributes (Blender value ``c`` with sharpness ``10 c^2``). The caller owns
    the mesh (``bpy.data.meshes.remove``).
    """
    import bpy

    points = np.asarray(cage.points, dtype=np.float32)
    sizes = np.asarray(cage.face_sizes, dtype=np.int32)
    indices = np.asarray(cage.face_indices, dtype=np.int32)
    starts = np.zeros(sizes.size, dtype=np.int32)
    np.cumsum(sizes[:-1], out=starts[1:])
    uvs = getattr(cage, "uvs", None)
    loose = np.asarray(getattr(cage, "loose_edges", None) or [], dtype=np.int32).reshape(-1, 2)
    me = bpy.data.meshes.new(name)
    try:
        me.vertices.add(points.shape[0])
        me.vertices.foreach_set("co", points.ravel())
        if len(loose):
            me.edges.add(len(loose))
            me.edges.foreach_set("vertices", loose.ravel())
        me.loops.add(indices.size)
        me.loops.foreach_set("vertex_index", indices)
        me.polygons.add(sizes.size)
        me.polygons.foreach_set("loop_start", starts)
        me.update(calc_edges=True)
        origin = me.attributes.new(_ORIGIN, "INT", "FACE")
        origin.data.foreach_set("value", np.arange(sizes.size, dtype=np.int32))
        if uvs is not None:
            layer = me.uv_layers.new(name="UVMap")
            layer.data.foreach_set("uv", np.asarray(uvs, dtype=np.float32).ravel())

        creases = _pair_arrays(getattr(cage, "creases", None))
        if creases is not None:
            pairs, sharp = creases
            pairs = np.asarray(pairs, dtype=np.int64).reshape(-1, 2)
            edge_verts = np.empty(2 * len(me.edges), dtype=np.int32)
            me.edges.foreach_get("vertices", edge_verts)
            edge_verts = np.sort(edge_verts.reshape(-1, 2).astype(np.int64), axis=1)
            n = points.shape[0]
            edge_keys = edge_verts[:, 0] * n + edge_verts[:, 1]
            order = np.argsort(edge_keys)
            sp = np.sort(pairs, axis=1)
            want = sp[:, 0] * n + sp[:, 1]
            pos = np.minimum(np.searchsorted(edge_keys[order], want), order.size - 1)
            found = edge_keys[order][pos] == want
            if not np.all(found):
                bad = pairs[~found][0]
                raise ValueError(f"crease ({bad[0]}, {bad[1]}) is not an edge of the cage")
            values = np.zeros(len(me.edges), dtype=np.float32)
            values[order[pos]] = _blender_crease(sharp)
            attr = me.attributes.new("crease_edge", "FLOAT", "EDGE")
            attr.data.foreach_set("value", values)
        corners = _pair_arrays(getattr(cage, "corners", None))
        if corners is not None:
            verts, sharp = corners
            values = np.zeros(points.shape[0], dtype=np.float32)
            values[np.asarray(verts, dtype=np.int64)] = _blender_crease(sharp)
            attr = me.attributes.new("crease_vert", "FLOAT", "POINT")
            attr.data.foreach_set("value", values)
        me.update()
    except BaseException:
        bpy.data.meshes.remove(me)
        raise
    return me


def opensubdiv_surface(
    cage: Any,
    levels: int,
    *,
    limit: bool = False,
    boundary: str | None = None,
    uv_mode: str = "all",
) -> SurfaceMesh:
    """OpenSubdiv Catmull-Clark surface of ``cage`` after ``levels`` uniform levels (via bpy).

    Args:
        cage: a :class:`bidegree.Mesh` or anything with its attributes (points, face_sizes,
            face_indices, creases, corners, boundary; ``uvs`` (one per face corner), ``holes``
            (face indices) and ``loose_edges`` (vertex pairs) are read when present).
        levels: refinement levels, 0..11 (Blender's limit).
        limit: False = uniformly refined points; True = the refined vertices at their limit
            positions.
        boundary: ``"edge-only"``, ``"edge-and-corner"`` or ``"none"``; default: the cage's.
        uv_mode: how ``cage.uvs`` is refined, one of :data:`UV_SMOOTH` (OpenSubdiv's
            face-varying modes; ``"all"`` is linear).

    Blender has no holes and no boundary mode ``none``; both are what OpenSubdiv makes of them:
    the refinement of the whole cage (holes do not change any rule; under ``none`` the boundary
    rule reaches no vertex of a face that is kept, see ``docs/research/non-manifold.md``), with
    the faces that come from a hole (``none``: from :func:`boundary_none_holes`) left out.
    Blender makes a vertex on a loose edge infinitely sharp and drops vertices in no face.

    Returns the refined mesh: points float64 (only vertices of the faces kept), ``face_origin``
    (the cage face of each face) and, when the cage has UVs, ``uvs`` per face corner.
    """
    import bpy  # Blender as a Python module: runs OpenSubdiv

    levels = int(levels)
    if not 0 <= levels <= MAX_BPY_LEVELS:
        raise ValueError(
            f"OpenSubdiv (Blender) levels must be in 0..{MAX_BPY_LEVELS}, got {levels}"
        )
    boundary = boundary or str(getattr(cage, "boundary", "edge-only"))
    smooth = {"edge-only": "ALL", "edge-and-corner": "PRESERVE_CORNERS", "none": "ALL"}.get(
        boundary
    )
    if smooth is None:
        raise ValueError(f"unknown boundary mode {boundary!r}")
    if uv_mode not in UV_SMOOTH:
        raise ValueError(f"unknown face-varying mode {uv_mode!r}; one of {sorted(UV_SMOOTH)}")

    has_uvs = getattr(cage, "uvs", None) is not None
    given = getattr(cage, "holes", None)  # a sequence or an array (never tested for truth)
    holes = np.asarray([] if given is None else given, dtype=np.int64)
    if boundary == "none":
        holes = np.union1d(holes, boundary_none_holes(cage))

    me = blender_mesh(cage, "bidegree_compare_cage")
    obj = None
    try:
        obj = bpy.data.objects.new("bidegree_compare_cage", me)
        bpy.context.scene.collection.objects.link(obj)
        mod = obj.modifiers.new("OpenSubdiv", "SUBSURF")
        mod.subdivision_type = "CATMULL_CLARK"
        mod.levels = levels
        mod.render_levels = levels
        mod.use_limit_surface = bool(limit)
        mod.quality = 10 if limit else mod.quality
        mod.boundary_smooth = smooth
        mod.use_creases = True
        mod.use_custom_normals = False
        mod.uv_smooth = UV_SMOOTH[uv_mode]

        depsgraph = bpy.context.evaluated_depsgraph_get()
        evaluated = obj.evaluated_get(depsgraph)
        out = evaluated.to_mesh()
        try:
            nv, nf, nl = len(out.vertices), len(out.polygons), len(out.loops)
            co = np.empty(3 * nv, dtype=np.float32)
            out.vertices.foreach_get("co", co)
            loop_total = np.empty(nf, dtype=np.int32)
            out.polygons.foreach_get("loop_total", loop_total)
            loop_start = np.empty(nf, dtype=np.int32)
            out.polygons.foreach_get("loop_start", loop_start)
            vidx = np.empty(nl, dtype=np.int32)
            out.loops.foreach_get("vertex_index", vidx)
            face_origin = np.empty(nf, dtype=np.int32)
            out.attributes[_ORIGIN].data.foreach_get("value", face_origin)
            corner_uvs = None
            if has_uvs:
                corner_uvs = np.empty(2 * nl, dtype=np.float32)
                out.uv_layers["UVMap"].data.foreach_get("uv", corner_uvs)
                corner_uvs = corner_uvs.reshape(-1, 2).astype(np.float64)
        finally:
            evaluated.to_mesh_clear()
    finally:
        if obj is not None:
            bpy.data.objects.remove(obj, do_unlink=True)
        bpy.data.meshes.remove(me)

    # Faces in loop order (Blender stores them so; be safe if not), holes left out.
    order = np.argsort(loop_start, kind="stable")
    if holes.size:
        order = order[~np.isin(face_origin[order], holes)]
    loop_start, loop_total, face_origin = loop_start[order], loop_total[order], face_origin[order]
    ends = np.cumsum(loop_total, dtype=np.int64)
    total = int(ends[-1]) if ends.size else 0
    corners_kept = np.repeat(loop_start - (ends - loop_total), loop_total) + np.arange(total)
    vidx = vidx[corners_kept]
    if corner_uvs is not None:
        corner_uvs = corner_uvs[corners_kept]
    # drop vertices no kept face uses (Blender keeps loose ones; bidegree drops them)
    used = np.unique(vidx)
    remap = np.full(nv, -1, dtype=np.int64)
    remap[used] = np.arange(used.size)
    pts = co.reshape(-1, 3).astype(np.float64)[used]
    return SurfaceMesh(
        pts,
        loop_total.astype(np.int32),
        remap[vidx].astype(np.int32),
        face_origin=face_origin.astype(np.int32),
        uvs=corner_uvs,
    )


# --------------------------------------------------------------------------------------------
# comparison


def _stats(d: np.ndarray, diagonal: float) -> dict[str, float]:
    d = np.asarray(d, dtype=np.float64)
    out = {
        "max": float(d.max()) if d.size else 0.0,
        "rms": float(np.sqrt(np.mean(d * d))) if d.size else 0.0,
        "mean": float(d.mean()) if d.size else 0.0,
    }
    for key in ("max", "rms", "mean"):
        out[f"{key}_relative"] = out[key] / diagonal if diagonal > 0 else float("nan")
    return out


@dataclass
class Comparison:
    """Result of :func:`compare` (distances in the cage's units)."""

    degree: int
    levels: int
    boundary: str
    limit: bool
    diagonal: float
    cage: Any
    result: Any  # bidegree.Result
    opensubdiv: SurfaceMesh
    forward: np.ndarray  # per bidegree vertex: distance to the OpenSubdiv surface
    backward: np.ndarray  # per OpenSubdiv vertex: distance to the bidegree surface
    vertex_forward: np.ndarray  # per bidegree vertex: distance to the nearest OpenSubdiv vertex
    vertex_backward: np.ndarray  # per OpenSubdiv vertex: distance to the nearest bidegree vertex
    seconds: dict[str, float] = field(default_factory=dict)

    @property
    def stats(self) -> dict[str, dict[str, float]]:
        """max / rms / mean (absolute and ``*_relative`` to the cage diagonal) per direction."""
        both = np.concatenate([self.forward, self.backward])
        vboth = np.concatenate([self.vertex_forward, self.vertex_backward])
        return {
            "bidegree_to_opensubdiv": _stats(self.forward, self.diagonal),
            "opensubdiv_to_bidegree": _stats(self.backward, self.diagonal),
            "symmetric": _stats(both, self.diagonal),
            "vertex_sets": _stats(vboth, self.diagonal),
        }

    @property
    def hausdorff(self) -> float:
        """Vertex-sampled symmetric Hausdorff distance between the two surfaces."""
        return max(float(self.forward.max()), float(self.backward.max()))

    @property
    def hausdorff_relative(self) -> float:
        return self.hausdorff / self.diagonal if self.diagonal > 0 else float("nan")

    def summary(self) -> str:
        """Human-readable table of the numbers."""
        r, o = self.result, self.opensubdiv
        mode = "limit positions" if self.limit else "uniform refinement"
        lines = [
            f"bidegree degree {self.degree}, {self.levels} levels ({r.output}, {self.boundary}) "
            f"vs OpenSubdiv Catmull-Clark ({mode}, {self.levels} levels)",
            f"cage: {len(self.cage.points)} vertices, {len(self.cage.face_sizes)} faces; "
            f"bounding-box diagonal {self.diagonal:.6g}",
            f"bidegree: {len(r.points)} vertices, {len(r.face_sizes)} faces; "
            f"OpenSubdiv: {o.num_vertices} vertices, {o.num_faces} faces",
            f"{'':28s}{'max':>12s}{'rms':>12s}{'mean':>12s}"
            "   (relative to diagonal: max, rms, mean)",
        ]
        names = {
            "bidegree_to_opensubdiv": "bidegree -> OpenSubdiv",
            "opensubdiv_to_bidegree": "OpenSubdiv -> bidegree",
            "symmetric": "both (Hausdorff = max)",
            "vertex_sets": "vertex sets (nearest pt)",
        }
        for key, s in self.stats.items():
            lines.append(
                f"{names[key]:28s}{s['max']:12.4e}{s['rms']:12.4e}{s['mean']:12.4e}   "
                f"({s['max_relative']:.3e}, {s['rms_relative']:.3e}, {s['mean_relative']:.3e})"
            )
        return "\n".join(lines)


def _bbox_diagonal(points: np.ndarray) -> float:
    p = np.asarray(points, dtype=np.float64)
    return float(np.linalg.norm(p.max(axis=0) - p.min(axis=0)))


def compare(
    cage: Any,
    degree: int = 3,
    levels: int = 2,
    *,
    limit: bool = False,
    output: str = "primal",
    result: Any = None,
) -> Comparison:
    """Subdivide ``cage`` with bidegree and with OpenSubdiv and measure the distances.

    Args:
        cage: a :class:`bidegree.Mesh`; its boundary mode, creases and corners apply to both.
        degree, levels, output: bidegree options (see :func:`bidegree.subdivide`).
        limit: compare against OpenSubdiv's limit positions instead of its uniform refinement.
        result: an already computed ``bidegree.subdivide(cage, degree, levels, output)``.
    """
    import bidegree

    seconds: dict[str, float] = {}
    t0 = time.perf_counter()
    if result is None:
        result = bidegree.subdivide(cage, degree=degree, levels=levels, output=output)
    seconds["bidegree"] = time.perf_counter() - t0
    boundary = str(getattr(cage, "boundary", "edge-only"))
    t0 = time.perf_counter()
    osd = opensubdiv_surface(cage, levels, limit=limit, boundary=boundary)
    seconds["opensubdiv"] = time.perf_counter() - t0

    res_mesh = SurfaceMesh(
        np.asarray(result.points, dtype=np.float64),
        np.asarray(result.face_sizes, dtype=np.int32),
        np.asarray(result.face_indices, dtype=np.int32),
    )
    t0 = time.perf_counter()
    forward = distances_to_mesh(res_mesh.points, osd)
    backward = distances_to_mesh(osd.points, res_mesh)
    seconds["surface_distances"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    vertex_forward = nearest_point_distances(res_mesh.points, osd.points)
    vertex_backward = nearest_point_distances(osd.points, res_mesh.points)
    seconds["vertex_distances"] = time.perf_counter() - t0
    return Comparison(
        degree=int(degree),
        levels=int(levels),
        boundary=boundary,
        limit=bool(limit),
        diagonal=_bbox_diagonal(cage.points),
        cage=cage,
        result=result,
        opensubdiv=osd,
        forward=forward,
        backward=backward,
        vertex_forward=vertex_forward,
        vertex_backward=vertex_backward,
        seconds=seconds,
    )


def write_usd(comparison: Comparison, path: str, *, up_axis: str = "Y") -> None:
    """Report USD: cage, bidegree result with ``primvars:distance`` and /Bidegree/OpenSubdiv."""
    from bidegree import usd

    usd.export(
        path,
        comparison.cage,
        comparison.result,
        up_axis=up_axis,
        distances=comparison.forward,
        extra_meshes={"OpenSubdiv": (comparison.opensubdiv, comparison.backward)},
    )


# --------------------------------------------------------------------------------------------
# plot

_MAX_PLOT_FACES = 40_000


def _display(points: np.ndarray, up_axis: str) -> np.ndarray:
    """Map to matplotlib's Z-up frame (Y-up data: (x, y, z) -> (x, -z, y))."""
    p = np.asarray(points, dtype=np.float64)
    if up_axis == "Y":
        return np.stack([p[:, 0], -p[:, 2], p[:, 1]], axis=1)
    return p


_ELEV, _AZIM = 28.0, -55.0  # matplotlib view of the 3D panels


def _is_closed(face_sizes: np.ndarray, face_indices: np.ndarray) -> bool:
    """True when every edge is shared by exactly two faces."""
    sizes = np.asarray(face_sizes, dtype=np.int64)
    idx = np.asarray(face_indices, dtype=np.int64)
    starts = np.zeros(sizes.size, dtype=np.int64)
    np.cumsum(sizes[:-1], out=starts[1:])
    nxt = np.arange(1, idx.size + 1, dtype=np.int64)
    nxt[starts + sizes - 1] = starts
    a, b = idx, idx[nxt]
    keys = np.minimum(a, b) * (int(idx.max()) + 1) + np.maximum(a, b)
    _, counts = np.unique(keys, return_counts=True)
    return bool(np.all(counts == 2))


def _face_polys(mesh: SurfaceMesh, up_axis: str) -> tuple[list[np.ndarray], np.ndarray, np.ndarray]:
    """Polygons to draw (display frame), their unit normals, and their face indices.

    Faces turned away from the camera are left out on closed meshes (matplotlib sorts polygons
    by mean depth only, so back faces would otherwise show through); at most
    ``_MAX_PLOT_FACES`` evenly spaced faces are drawn.
    """
    pts = _display(mesh.points, up_axis)
    sizes = np.asarray(mesh.face_sizes, dtype=np.int64)
    idx = np.asarray(mesh.face_indices, dtype=np.int64)
    starts = np.zeros(sizes.size, dtype=np.int64)
    np.cumsum(sizes[:-1], out=starts[1:])
    # vector area per face (Newell's formula around the first vertex)
    nxt = np.arange(1, idx.size + 1, dtype=np.int64)
    nxt[starts + sizes - 1] = starts
    origin = np.repeat(pts[idx[starts]], sizes, axis=0)
    cross = np.cross(pts[idx] - origin, pts[idx[nxt]] - origin)
    normals = np.add.reduceat(cross, starts, axis=0)
    length = np.linalg.norm(normals, axis=1, keepdims=True)
    normals = np.divide(normals, length, out=np.zeros_like(normals), where=length > 0)
    faces = np.arange(sizes.size)
    if _is_closed(sizes, idx):
        elev, azim = np.radians(_ELEV), np.radians(_AZIM)
        eye = np.array([np.cos(elev) * np.cos(azim), np.cos(elev) * np.sin(azim), np.sin(elev)])
        faces = faces[normals @ eye > 0]
    if faces.size > _MAX_PLOT_FACES:  # keep the drawing responsive: evenly spaced subset
        faces = faces[np.linspace(0, faces.size - 1, _MAX_PLOT_FACES).astype(np.int64)]
    polys = [pts[idx[starts[f] : starts[f] + sizes[f]]] for f in faces]
    return polys, normals[faces], faces


def _shade(normals: np.ndarray) -> np.ndarray:
    light = np.array([-0.4, -0.6, 0.7])
    light /= np.linalg.norm(light)
    return 0.35 + 0.65 * np.abs(normals @ light)


def _setup_axes(ax: Any, pts: np.ndarray, title: str) -> None:
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    span = np.maximum(hi - lo, 1e-3 * max(float((hi - lo).max()), 1e-12))
    center = (lo + hi) / 2
    ax.set_xlim(center[0] - span[0] / 2, center[0] + span[0] / 2)
    ax.set_ylim(center[1] - span[1] / 2, center[1] + span[1] / 2)
    ax.set_zlim(center[2] - span[2] / 2, center[2] + span[2] / 2)
    ax.set_box_aspect(tuple(span), zoom=1.25)
    ax.view_init(elev=_ELEV, azim=_AZIM)
    ax.set_axis_off()
    ax.set_title(title, fontsize=10)


def write_plot(comparison: Comparison, path: str, *, up_axis: str = "Y") -> None:
    """PNG: both surfaces side by side, bidegree coloured by distance, and a histogram."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from mpl_toolkits.mplot3d.art3d import Poly3DCollection

    c = comparison
    res_mesh = SurfaceMesh(
        np.asarray(c.result.points, dtype=np.float64),
        np.asarray(c.result.face_sizes),
        np.asarray(c.result.face_indices),
    )
    fig = plt.figure(figsize=(13, 10), dpi=110)
    mode = "limit" if c.limit else "uniform"
    fig.suptitle(
        f"bidegree degree {c.degree} vs OpenSubdiv Catmull-Clark — {c.levels} levels, "
        f"{c.boundary}, OpenSubdiv {mode}; Hausdorff {c.hausdorff:.3e} "
        f"({c.hausdorff_relative:.2e} of the diagonal)",
        fontsize=11,
    )
    all_pts = _display(np.concatenate([res_mesh.points, c.opensubdiv.points]), up_axis)
    base = np.array([0.62, 0.72, 0.88])
    for slot, mesh, title in (
        (1, res_mesh, f"bidegree degree {c.degree} ({len(res_mesh.face_sizes)} faces)"),
        (2, c.opensubdiv, f"OpenSubdiv Catmull-Clark ({c.opensubdiv.num_faces} faces)"),
    ):
        ax = fig.add_subplot(2, 2, slot, projection="3d")
        polys, normals, _ = _face_polys(mesh, up_axis)
        colors = np.clip(base[None, :] * _shade(normals)[:, None], 0, 1)
        ax.add_collection3d(
            Poly3DCollection(polys, facecolors=colors, edgecolors=colors, linewidths=0.2)
        )
        _setup_axes(ax, all_pts, title)

    # distance-coloured bidegree surface
    ax = fig.add_subplot(2, 2, 3, projection="3d")
    polys, normals, faces = _face_polys(res_mesh, up_axis)
    sizes = np.asarray(res_mesh.face_sizes, dtype=np.int64)
    face_of_corner = np.repeat(np.arange(sizes.size), sizes)
    face_dist = np.bincount(
        face_of_corner, weights=c.forward[np.asarray(res_mesh.face_indices)], minlength=sizes.size
    ) / np.maximum(sizes, 1)
    face_dist = face_dist[faces]
    vmax = float(c.forward.max()) if c.forward.size and c.forward.max() > 0 else 1.0
    cmap = plt.get_cmap("inferno")
    norm = matplotlib.colors.Normalize(vmin=0.0, vmax=vmax)
    colors = cmap(norm(face_dist))[:, :3] * (0.55 + 0.45 * _shade(normals))[:, None]
    ax.add_collection3d(
        Poly3DCollection(
            polys,
            facecolors=np.clip(colors, 0, 1),
            edgecolors=np.clip(colors, 0, 1),
            linewidths=0.2,
        )
    )
    _setup_axes(ax, all_pts, "bidegree coloured by distance to OpenSubdiv")
    mappable = matplotlib.cm.ScalarMappable(norm=norm, cmap=cmap)
    fig.colorbar(mappable, ax=ax, shrink=0.6, pad=0.02, label="distance")

    # histogram
    ax = fig.add_subplot(2, 2, 4)
    rel_f = c.forward / c.diagonal if c.diagonal > 0 else c.forward
    rel_b = c.backward / c.diagonal if c.diagonal > 0 else c.backward
    top = max(float(rel_f.max(initial=0)), float(rel_b.max(initial=0)))
    bins = np.linspace(0.0, top if top > 0 else 1e-9, 50)
    ax.hist(rel_f, bins=bins, alpha=0.65, label="bidegree vertex → OpenSubdiv surface")
    ax.hist(rel_b, bins=bins, alpha=0.65, label="OpenSubdiv vertex → bidegree surface")
    ax.set_yscale("log")
    ax.set_ylim(0.8, ax.get_ylim()[1] * 200)  # headroom for the legend and the numbers
    ax.set_xlabel("distance / bounding-box diagonal of the cage")
    ax.set_ylabel("vertices")
    ax.legend(fontsize=8, loc="upper right", bbox_to_anchor=(1.0, 0.82))
    s = c.stats
    text = "\n".join(
        f"{name:>9s}: max {s[key]['max_relative']:.2e}  rms {s[key]['rms_relative']:.2e}  "
        f"mean {s[key]['mean_relative']:.2e}"
        for name, key in (
            ("bd→osd", "bidegree_to_opensubdiv"),
            ("osd→bd", "opensubdiv_to_bidegree"),
            ("vertices", "vertex_sets"),
        )
    )
    ax.text(
        0.02, 0.97, text, transform=ax.transAxes, fontsize=8, family="monospace",
        va="top", bbox={"facecolor": "white", "alpha": 0.8, "edgecolor": "0.8"},
    )  # fmt: skip
    ax.set_title("distance histogram (relative to the cage diagonal)", fontsize=10)
    fig.tight_layout(rect=(0, 0, 1, 0.96))
    fig.savefig(path)
    plt.close(fig)


# --------------------------------------------------------------------------------------------
# CLI hook (registered by bidegree.cli as the `compare` subcommand)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Arguments of ``bidegree compare``."""
    parser.description = (
        "Compare bidegree's degree-N surface with OpenSubdiv's Catmull-Clark surface of the same "
        "cage (OpenSubdiv run through Blender's bpy module) and print the distances."
    )
    parser.add_argument("input", help="cage OBJ file")
    parser.add_argument("--degree", type=int, default=3, help="bidegree degree (default 3)")
    parser.add_argument("--levels", type=int, default=2, help="subdivision levels (default 2)")
    parser.add_argument(
        "--boundary",
        choices=("edge-only", "edge-and-corner"),
        default=None,
        help="boundary rule for both (default: the OBJ's, else edge-only)",
    )
    parser.add_argument(
        "--kind", choices=("primal", "dual"), default="primal", help="bidegree output mesh"
    )
    parser.add_argument(
        "--limit", action="store_true", help="compare with OpenSubdiv's limit positions"
    )
    parser.add_argument("-o", "--output", help="report USD (.usda/.usdc) with both surfaces")
    parser.add_argument("--plot", help="report PNG")
    parser.add_argument("--up-axis", choices=("Y", "Z"), default="Y", help="up axis (default Y)")


def usd_extensions() -> tuple[str, ...]:
    """File extensions accepted for the report USD."""
    from bidegree import usd

    return usd.SUPPORTED_EXTENSIONS


def run(args: argparse.Namespace) -> int:
    """Run ``bidegree compare``; returns the exit status."""
    import bidegree

    try:
        # check the output paths first: the comparison can take a while
        for out, exts in ((args.output, usd_extensions()), (args.plot, None)):
            if not out:
                continue
            directory = os.path.dirname(os.path.abspath(out))
            if not os.path.isdir(directory):
                raise bidegree.BidegreeIOError(f"{out}: directory {directory} does not exist")
            if exts is not None and os.path.splitext(out)[1].lower() not in exts:
                raise bidegree.InvalidInputError(f"{out}: the report must be {' or '.join(exts)}")
        mesh = bidegree.Mesh.from_obj(args.input, boundary=args.boundary)
        comparison = compare(mesh, args.degree, args.levels, limit=args.limit, output=args.kind)
        print(comparison.summary())
        if args.output:
            write_usd(comparison, args.output, up_axis=args.up_axis)
            print(f"wrote {args.output}")
        if args.plot:
            write_plot(comparison, args.plot, up_axis=args.up_axis)
            print(f"wrote {args.plot}")
    except (bidegree.BidegreeError, ValueError, OSError) as exc:
        print(f"bidegree compare: error: {exc}", file=sys.stderr)
        return 1
    return 0
