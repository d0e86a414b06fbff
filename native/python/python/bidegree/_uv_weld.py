"""Blender's UV topology for its Subdivision Surface: :func:`blender_uv_indices`.

bidegree's own rule (``Plan.evaluate_face_varying``, ``Mesh(uvs=...)``) welds the corners of a
vertex whose values are exactly equal, or follows given indices (OpenSubdiv's, OBJ's ``vt``).
Blender welds by a tolerance and the UV winding instead (``precalc_uv_layer`` in
``subdiv_converter_mesh.cc`` calls ``BKE_mesh_uv_vert_map_create`` with ``use_winding``, in
``mesh_mapping.cc``): this module reproduces that as indices, so the add-on (and anyone
comparing with Blender) gives Blender's seams.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from . import _convert as convert
from ._errors import InvalidInputError

#: Blender's ``STD_UV_CONNECT_LIMIT`` (``BKE_mesh_mapping.hh``): the largest difference per axis
#: (exclusive) of two UVs of one vertex that Blender welds.
BLENDER_UV_LIMIT = np.float32(1e-4)


def blender_uv_indices(
    face_sizes: ArrayLike, face_indices: ArrayLike, uvs: ArrayLike
) -> NDArray[np.int64]:
    """The face-varying topology Blender's Subdivision Surface gives ``uvs`` (one per face
    corner), as one index into ``uvs`` per face corner: give both to
    ``Plan.evaluate_face_varying(uvs, indices=...)`` or ``Mesh(uvs=uvs, uv_indices=...)``.

    Blender's rule, in float32 as Blender computes it: each face has a UV winding (its UV
    polygon's trapezium-rule area ``cross_poly_v2`` is negative); the corners of a vertex are
    taken last face first, the first one left starts a value and takes every remaining corner
    whose UV is within :data:`BLENDER_UV_LIMIT` of its own on both axes (not transitively) and
    whose face has the same winding; repeat. The value is that first corner's UV (the last
    corner of the group: the one a serial face loop writes last), so the index of every corner
    of a group is that corner. Blender writes the values from parallel tasks per face
    (``set_face_varying_data_from_uv`` in ``subdiv_eval.cc``), so where a group's UVs differ
    (within the limit) its own value is any of them, run by run: the surfaces then agree to the
    limit, not exactly.
    """
    sizes = convert.int_array(face_sizes, "face_sizes")
    verts = convert.int_array(face_indices, "face_indices")
    uv = np.asarray(convert.float_array(uvs, "uvs"), dtype=np.float32)
    if sizes.ndim != 1 or verts.ndim != 1 or int(sizes.sum()) != len(verts):
        raise InvalidInputError("face_sizes and face_indices must be 1-D, face_sizes summing up")
    if uv.shape != (len(verts), 2):
        raise InvalidInputError(f"uvs must have shape ({len(verts)}, 2), not {uv.shape}")
    corners = len(verts)
    starts = np.zeros(len(sizes), dtype=np.int64)
    np.cumsum(sizes[:-1], out=starts[1:])
    # cross_poly_v2 (math_geom.cc): from the last corner, summed in corner order, float32.
    prev = np.arange(corners) - 1
    prev[starts] = starts + sizes - 1
    term = (uv[prev, 0] - uv[:, 0]) * (uv[:, 1] + uv[prev, 1])
    cross = np.zeros(len(sizes), dtype=np.float32)
    for k in range(int(sizes.max()) if len(sizes) else 0):
        has = np.flatnonzero(sizes > k)
        cross[has] += term[starts[has] + k]
    winding = np.repeat(cross < 0, sizes)

    # Corners of each vertex, last first.
    order = np.lexsort((-np.arange(corners), verts))
    first = np.ones(corners, dtype=bool)
    first[1:] = verts[order[1:]] != verts[order[:-1]]
    head = order[np.maximum.accumulate(np.where(first, np.arange(corners), 0))]

    def close(c: NDArray[np.int64], to: NDArray[np.int64]) -> NDArray[np.bool_]:
        near = (np.abs(uv[c] - uv[to]) < BLENDER_UV_LIMIT).all(axis=1)
        return near & (winding[c] == winding[to])

    index = np.empty(corners, dtype=np.int64)
    index[order] = head
    # Vertices whose corners are all close to the first: one value (the common case).
    apart = ~close(order, head)
    by_vertex = verts[order]
    for v in np.unique(by_vertex[apart]):
        lo, hi = np.searchsorted(by_vertex, [v, v + 1])
        pending = order[lo:hi]
        while len(pending):
            seed = np.full(len(pending) - 1, pending[0])
            group = np.concatenate([[True], close(pending[1:], seed)])
            index[pending[group]] = pending[0]
            pending = pending[~group]
    return index
