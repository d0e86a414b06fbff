"""Reference surfaces from the real OpenSubdiv (Blender's Subdivision Surface modifier) for the
cages of ``tests/cages_dirty.py``, and the correspondences that compare bidegree with them.

Running OpenSubdiv is :func:`bidegree.compare.opensubdiv_surface` (holes, boundary ``none``,
loose edges, UVs and the six face-varying modes included); this module adds what a parity test
needs around it:

- :func:`blender_semantics`: what Blender's converter adds before OpenSubdiv sees the cage
  (``subdiv_converter_mesh.cc``, ``topology_refiner_factory.cc``): a vertex on a loose edge is
  infinitely sharp, and a vertex with exactly two edges gets the smaller of their sharpness
  added to its own. The result is a cage OpenSubdiv alone (and bidegree) subdivides the way
  Blender does.
- :func:`blender_uv_values`: the face-varying topology Blender builds from a UV map (which face
  corners share a value), as ``BKE_mesh_uv_vert_map_create`` with ``STD_UV_CONNECT_LIMIT``.
- :func:`point_gap`: positions by nearest point, both ways (as ``tests/test_classic_parity.py``).
- :func:`corner_map`: the corners of one refined mesh in the corner order of another mesh of
  the same surface (to compare UVs per face corner): vertices matched by position, faces by
  their cage face and vertex set, corners by their vertex inside the face. Robust to any
  numbering of vertices, faces and corners; it needs the positions to agree, which they do
  whenever the face-varying comparison means anything (positions do not depend on the
  face-varying mode), and one map serves every mode.
- :func:`face_varying_cage`: the face-varying mesh with a face-varying mode as its corners, the
  mapping of ``docs/research/face-varying.md`` in executable form.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from bidegree import compare
from cages_dirty import INF, DirtyCage

#: ``STD_UV_CONNECT_LIMIT`` (``BKE_mesh_mapping.hh``): UVs closer than this on both axes weld.
UV_CONNECT_LIMIT = np.float32(0.0001)


def _face_edges(cage: DirtyCage) -> dict[int, set[tuple[int, int]]]:
    """The edges at each vertex used by a face (as OpenSubdiv reconstructs them)."""
    edges: dict[int, set[tuple[int, int]]] = {}
    for face in cage.faces:
        for i, a in enumerate(face):
            b = face[(i + 1) % len(face)]
            key = (min(a, b), max(a, b))
            edges.setdefault(a, set()).add(key)
            edges.setdefault(b, set()).add(key)
    return edges


def blender_semantics(cage: DirtyCage) -> DirtyCage:
    """The cage with Blender's own additions made explicit, for OpenSubdiv (or bidegree) alone.

    ``is_infinite_sharp_vertex`` (``subdiv_converter_mesh.cc``): a vertex on a loose edge and on
    a face is infinitely sharp. ``assignComponentTags`` (``topology_refiner_factory.cc``): a
    vertex with exactly two edges gets ``min(sharpness of the two)`` added (capped at 10). The
    loose edges are then dropped (their other vertices are in no face; bidegree drops those).
    """
    edges = _face_edges(cage)
    edge_sharpness = {(min(a, b), max(a, b)): s for a, b, s in cage.sharp_edges}
    sharpness = dict(cage.sharp_vertices)
    for v, at in edges.items():
        if len(at) == 2:
            extra = min(edge_sharpness.get(e, 0.0) for e in at)
            if extra > 0:
                sharpness[v] = min(sharpness.get(v, 0.0) + extra, INF)
    for edge in cage.loose_edges:
        for v in edge:
            if v in edges:
                sharpness[v] = INF
    return cage.with_changes(
        cage.name, sharp_vertices=tuple(sorted(sharpness.items())), loose_edges=()
    )


def _uv_winding(cage: DirtyCage, uvs: np.ndarray) -> np.ndarray:
    """Per face: True when its UV polygon turns clockwise: Blender's ``cross_poly_v2 < 0``
    (``math_geom.cc``: the trapezium rule from the last corner, summed in float32)."""
    winding = np.zeros(len(cage.faces), dtype=bool)
    at = 0
    for f, n in enumerate(cage.face_sizes):
        p = uvs[at : at + n].astype(np.float32)
        at += n
        cross = np.float32(0.0)
        for k in range(n):
            prev, curr = p[k - 1], p[k]
            cross += (prev[0] - curr[0]) * (curr[1] + prev[1])
        winding[f] = cross < 0
    return winding


def blender_uv_values(cage: DirtyCage, uvs: np.ndarray | None = None) -> np.ndarray:
    """The face-varying value of each face corner as Blender hands it to OpenSubdiv.

    ``precalc_uv_layer`` (``subdiv_converter_mesh.cc``) calls ``BKE_mesh_uv_vert_map_create``
    with ``use_winding``: per vertex, its corners in reverse face order; the first corner left
    starts a value and takes every remaining corner whose UV is within ``STD_UV_CONNECT_LIMIT``
    of its own on both axes and whose face has the same UV winding; repeat. Values are numbered
    vertex by vertex. Corners of one vertex share a value only through these coordinates, never
    through an edge, so two islands touching at a vertex with equal UVs share a value.
    """
    uv = np.asarray(cage.uvs if uvs is None else uvs, dtype=np.float32)
    winding = _uv_winding(cage, uv)
    sizes = cage.face_sizes
    face_of = np.repeat(np.arange(sizes.size), sizes)
    verts = cage.face_indices
    values = np.full(verts.size, -1, dtype=np.int64)
    # Corners of each vertex, last face first (the map prepends corners face by face).
    order = np.lexsort((-np.arange(verts.size), verts))
    bounds = np.searchsorted(verts[order], np.arange(len(cage.points) + 1))
    count = 0
    for v in range(len(cage.points)):
        pending = list(order[bounds[v] : bounds[v + 1]])
        while pending:
            head, rest = pending[0], pending[1:]
            close = [
                c
                for c in rest
                if abs(uv[c, 0] - uv[head, 0]) < UV_CONNECT_LIMIT
                and abs(uv[c, 1] - uv[head, 1]) < UV_CONNECT_LIMIT
                and winding[face_of[c]] == winding[face_of[head]]
            ]
            for c in [head, *close]:
                values[c] = count
            count += 1
            pending = [c for c in rest if c not in close]
    return values


def point_gap(ours: np.ndarray, theirs: np.ndarray, diagonal: float) -> float:
    """Largest nearest-point distance between two point sets, both ways, over ``diagonal``."""
    one = compare.nearest_point_distances(np.asarray(ours, np.float64), theirs).max()
    two = compare.nearest_point_distances(np.asarray(theirs, np.float64), ours).max()
    return float(max(one, two) / diagonal)


def _cell_keys(cells: np.ndarray) -> np.ndarray:
    """One int64 per integer cell (..., 3) (coordinates within +-2^20)."""
    c = cells + (1 << 20)
    return (c[..., 0] << 42) | (c[..., 1] << 21) | c[..., 2]


def _match_vertices(ours: np.ndarray, theirs: np.ndarray, tolerance: float) -> np.ndarray:
    """For each of ``theirs``, the index of the nearest of ``ours`` within ``tolerance`` (-1 if
    none), through a grid of cells of ``4 * tolerance`` (one point of ``ours`` kept per cell:
    points closer than that are the same point for this purpose)."""
    ours = np.asarray(ours, dtype=np.float64)
    theirs = np.asarray(theirs, dtype=np.float64)
    lo = np.minimum(ours.min(axis=0), theirs.min(axis=0))
    cell = 4.0 * tolerance
    keys, first = np.unique(
        _cell_keys(np.floor((ours - lo) / cell).astype(np.int64)), return_index=True
    )
    base = np.floor((theirs - lo) / cell).astype(np.int64)
    best = np.full(len(theirs), -1, dtype=np.int64)
    best_d = np.full(len(theirs), tolerance)
    for offset in np.ndindex(3, 3, 3):
        k = _cell_keys(base + np.array(offset) - 1)
        pos = np.minimum(np.searchsorted(keys, k), keys.size - 1)
        candidate = np.where(keys[pos] == k, first[pos], -1)
        d = np.linalg.norm(ours[np.maximum(candidate, 0)] - theirs, axis=1)
        better = (candidate >= 0) & (d <= best_d)
        best[better], best_d[better] = candidate[better], d[better]
    return best


def corner_map(target: Any, source: compare.SurfaceMesh, *, tolerance: float) -> np.ndarray:
    """For each face corner of ``target``, the index of the same corner in ``source``.

    Both are refined meshes of the same surface whose faces all have the same size (every level
    from 1 on): ``target`` has points, face_sizes, face_indices and face_origin (a bidegree
    ``Result`` or a :class:`bidegree.compare.SurfaceMesh`). Vertices are matched by position
    within ``tolerance``, faces by their cage face and their set of vertices (duplicate faces
    pair off in order), corners by their vertex. Raises ``AssertionError`` saying what has no
    partner. ``source.uvs[corner_map(...)]`` are the reference UVs in ``target``'s corner order.
    """
    vertex = _match_vertices(target.points, source.points, tolerance)
    if (vertex < 0).any():
        j = int(np.flatnonzero(vertex < 0)[0])
        raise AssertionError(f"vertex {j} of the reference has no partner within {tolerance:g}")
    size = int(np.asarray(target.face_sizes)[0])
    for mesh in (target, source):
        if np.any(np.asarray(mesh.face_sizes) != size):
            raise AssertionError("corner_map needs faces of one size (a refined level)")
    ours = np.asarray(target.face_indices, dtype=np.int64).reshape(-1, size)
    theirs = vertex[np.asarray(source.face_indices, dtype=np.int64)].reshape(-1, size)
    if len(ours) != len(theirs):
        raise AssertionError(f"{len(ours)} faces against {len(theirs)} in the reference")

    def order(faces: np.ndarray, origin: Any) -> tuple[np.ndarray, np.ndarray]:
        rows = np.column_stack([np.asarray(origin, dtype=np.int64), np.sort(faces, axis=1)])
        return np.lexsort(rows.T[::-1]), rows

    ours_order, ours_rows = order(ours, target.face_origin)
    theirs_order, theirs_rows = order(theirs, source.face_origin)
    differ = np.any(ours_rows[ours_order] != theirs_rows[theirs_order], axis=1)
    if differ.any():
        f = int(ours_order[np.flatnonzero(differ)[0]])
        raise AssertionError(f"face {f} of the result (cage face {ours_rows[f, 0]}) has no partner")
    partner = np.empty(len(ours), dtype=np.int64)
    partner[ours_order] = theirs_order
    # Corner k of our face f is the corner of its partner face at the same vertex.
    same = ours[:, :, None] == theirs[partner][:, None, :]
    return (partner[:, None] * size + np.argmax(same, axis=2)).ravel()


#: OpenSubdiv's face-varying modes expressible as corners of the face-varying mesh.
SMOOTH_MODES = ("none", "corners-only", "corners-plus1", "corners-plus2", "boundaries")


def face_varying_cage(
    cage: DirtyCage, mode: str, values: np.ndarray | None = None
) -> tuple[DirtyCage, np.ndarray]:
    """The face-varying mesh of ``cage`` with ``mode`` as corners (``face-varying.md``, §5).

    Its vertices are the distinct values (``values``: one per face corner, default
    :func:`blender_uv_values`), its faces the cage's; a cage edge whose faces disagree on a value
    is one edge per side, so seams are boundaries. It carries the cage's vertex sharpness to
    every value of the vertex, the cage's creases to every face-varying edge over them, and the
    mode's corners (infinitely sharp):

    - ``none``: none beyond those (a value in one face is an ordinary curve vertex);
    - ``corners-only``: every value in one face at its vertex;
    - ``corners-plus1``: also every value of a vertex with 3 or more values, and both values of a
      2-valued vertex when either value's faces are crossed by an infinitely sharp edge or do
      not form one fan;
    - ``corners-plus2``: also both values of a 2-valued vertex when either is in one face, and
      the value of an interior single-valued vertex at the end of a seam;
    - ``boundaries``: every value on a seam or on the boundary (the ordinary 1-D rule then keeps
      those curves linear, with midpoints, at every degree).

    A value whose faces do not form one fan at its vertex (a bowtie of the face-varying mesh) is
    a corner in every mode. Returns the cage (points: the values, z = 0) and the ``(N, 2)``
    values. Not covered, and refused: OpenSubdiv's dependent sharpness (modes ``plus1``/``plus2``,
    a 2-valued vertex where the faces of exactly one value are crossed by semi-sharp edges) and
    geometric non-manifold edges. The cage's topological corners are corners under
    ``edge-and-corner``; under ``none`` the cage's boundary holes are holes.
    """
    if mode not in SMOOTH_MODES:
        raise ValueError(f"{mode!r} is not a smooth mode (one of {SMOOTH_MODES})")
    values = blender_uv_values(cage) if values is None else np.asarray(values, dtype=np.int64)
    count = int(values.max()) + 1
    table = np.zeros((count, 2))
    table[values] = np.asarray(cage.uvs, dtype=np.float64)
    verts = cage.face_indices
    sizes = cage.face_sizes
    starts = np.concatenate([[0], np.cumsum(sizes)[:-1]])
    nxt = np.arange(1, verts.size + 1)
    nxt[starts + sizes - 1] = starts
    vertex_of = np.zeros(count, dtype=np.int64)
    vertex_of[values] = verts
    # Edges of the face-varying mesh and of the cage, with their corners.
    fv_edges: dict[tuple[int, int], list[int]] = {}
    geo_faces: dict[tuple[int, int], int] = {}
    for c in range(verts.size):
        a, b = int(values[c]), int(values[nxt[c]])
        fv_edges.setdefault((min(a, b), max(a, b)), []).append(c)
        p, q = int(verts[c]), int(verts[nxt[c]])
        geo_faces[(min(p, q), max(p, q))] = geo_faces.get((min(p, q), max(p, q)), 0) + 1
    if any(n > 2 for n in geo_faces.values()):
        raise NotImplementedError("geometric non-manifold edges are not covered")
    crease = {(min(a, b), max(a, b)): s for a, b, s in cage.sharp_edges}
    seam_values = {x for (a, b), cs in fv_edges.items() if len(cs) == 1 for x in (a, b)}
    geo_boundary = {v for e, n in geo_faces.items() if n == 1 for v in e}
    span = np.bincount(values, minlength=count)
    by_vertex: dict[int, list[int]] = {}
    for x in range(count):
        by_vertex.setdefault(int(vertex_of[x]), []).append(x)

    def geo_edge(e: tuple[int, int]) -> tuple[int, int]:
        p, q = int(vertex_of[e[0]]), int(vertex_of[e[1]])
        return (min(p, q), max(p, q))

    def crossing(x: int, sharp: Any) -> bool:
        """A face-varying edge inside the faces of ``x`` whose sharpness passes ``sharp``."""
        return any(
            x in e and len(cs) == 2 and sharp(crease.get(geo_edge(e), 0.0))
            for e, cs in fv_edges.items()
        )

    def one_fan(x: int) -> bool:
        corners = [int(c) for c in np.flatnonzero(values == x)]
        group = {c: c for c in corners}

        def root(c: int) -> int:
            while group[c] != c:
                c = group[c]
            return c

        for e, cs in fv_edges.items():
            if x in e and len(cs) == 2:
                ends = [c if values[c] == x else int(nxt[c]) for c in cs]
                group[root(ends[0])] = root(ends[1])
        return len({root(c) for c in corners}) == 1

    corners = {x for x in range(count) if not one_fan(x)}
    if mode in ("corners-only", "corners-plus1", "corners-plus2"):
        corners |= {x for x in range(count) if span[x] == 1}
    if mode in ("corners-plus1", "corners-plus2"):
        for xs in by_vertex.values():
            if len(xs) >= 3:
                corners |= set(xs)
            elif len(xs) == 2:
                semi = [crossing(x, lambda s: 0 < s < INF) for x in xs]
                if semi[0] != semi[1]:
                    raise NotImplementedError("dependent sharpness is not covered")
                if any(crossing(x, lambda s: s >= INF) or not one_fan(x) for x in xs):
                    corners |= set(xs)
                if mode == "corners-plus2" and any(span[x] == 1 for x in xs):
                    corners |= set(xs)
    if mode == "corners-plus2":
        for v, xs in by_vertex.items():
            if len(xs) == 1 and xs[0] in seam_values and v not in geo_boundary:
                corners.add(xs[0])
    if mode == "boundaries":
        corners |= seam_values
    sharpness = {x: s for v, s in cage.sharp_vertices for x in by_vertex.get(v, [])}
    if cage.boundary == "edge-and-corner":  # the cage's topological corners are sharp
        lone = np.bincount(verts, minlength=len(cage.points)) == 1
        corners |= {x for x in range(count) if lone[vertex_of[x]]}
    sharpness.update({x: INF for x in corners})
    holes = cage.holes
    if cage.boundary == "none":
        holes = tuple(sorted(set(holes) | set(compare.boundary_none_holes(cage).tolist())))
    sharp_edges = tuple(
        (a, b, crease[geo_edge((a, b))]) for a, b in fv_edges if geo_edge((a, b)) in crease
    )
    points = np.column_stack([table, np.zeros(count)])
    fv_cage = DirtyCage(
        f"{cage.name}-{mode}",
        points,
        tuple(tuple(int(x) for x in values[s : s + n]) for s, n in zip(starts, sizes, strict=True)),
        sharp_edges=sharp_edges,
        sharp_vertices=tuple(sorted(sharpness.items())),
        holes=holes,
        boundary="edge-only",
    )
    return fv_cage, table
