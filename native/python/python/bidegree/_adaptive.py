"""Adaptive subdivision (the paper's §3): :func:`subdivide_adaptive` and its
:class:`AdaptiveResult`, a crack-free triangle mesh.
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from . import _convert as convert
from . import _native
from ._convert import FloatArray, UvMode
from ._errors import InvalidInputError, LevelOutOfRangeError
from ._mesh import Mesh, write_obj_arrays


class AdaptiveResult:
    """An adaptively subdivided surface as a crack-free triangle mesh.

    Attributes:
        points: (N, 3) in the dtype of the cage's points. Vertex ``i`` is, bit for bit, vertex
            ``vertex_id[i]`` of the uniform result at level ``vertex_level[i]``.
        triangles: int32 (T, 3), oriented as the cage's faces.
        face_origin: int32 (T,), the cage face of each triangle.
        triangle_level: int32 (T,), the level of the quadtree leaf each triangle comes from.
        vertex_level: int32 (N,), the level whose point each vertex carries (the finest level
            of the leaves around it).
        vertex_id: int64 (N,), the vertex's id in the uniform level ``vertex_level``.
        cage_vertex: int32 (N,), the cage vertex each vertex is, -1 for a vertex made by
            refinement (for vertex attributes such as vertex creases).
        vertex_sharpness: float32 (N,), the corner sharpness each vertex keeps at its level
            (the cage's corners, and the boundary rule's and non-manifold vertices' infinitely
            sharp ones, lowered by one per level; 10 stays 10; 0 elsewhere).
        leaves_per_level: int64 (max_level + 1,), quadtree leaves at each level.
        max_error: with ``measure_leaves=True``, the largest flatness error of any leaf
            (relative to the cage's bounding-box diagonal), else None.
        uvs: (3 T, 2) the cage's uvs at the triangle corners (corner ``k`` of triangle ``t``
            is row ``3 t + k``), subdivided in ``uv_mode``: each the uniform result's uv at
            that vertex's level, on the triangle's side of a seam; None without cage uvs.
        uv_mode: the face-varying mode of ``uvs`` and ``face_varying``.
        vertex_values: (N, C) the ``vertex_values`` given, at the output vertices (each at
            its level, as the points), or None; (N,) for values given as (cage vertices,).
        face_varying: name -> (3 T, C) for each set of ``face_varying`` given, as ``uvs``;
            (3 T,) for a set given as (cage corners,).
        edge_origin: int32 (3 T,), per triangle corner ``3 t + k``: the cage edge (row of
            ``cage_edges``) under the triangle's edge from corner ``k`` to ``k + 1``, -1 inside
            a cage face (as ``Plan.edge_origin``).
        edge_level: int32 (3 T,), the level of that edge.
        edge_sharpness: float32 (3 T,), the sharpness it keeps at its level (as
            ``Plan.edge_sharpness`` with the averaging rules).
        cage_edges: int32 (E0, 2), the cage's edges as vertex pairs (smaller first), ordered by
            pair.
    """

    def __init__(
        self,
        data: dict[str, Any],
        degree: int,
        max_level: int,
        tolerance: float,
        uv_mode: UvMode = "boundaries",
        names: tuple[str | None, ...] = (),
    ) -> None:
        self.points: FloatArray = data["points"]
        self.triangles: NDArray[np.int32] = convert.readonly(data["triangles"])
        self.face_origin: NDArray[np.int32] = convert.readonly(data["face_origin"])
        self.triangle_level: NDArray[np.int32] = convert.readonly(data["triangle_level"])
        self.vertex_level: NDArray[np.int32] = convert.readonly(data["vertex_level"])
        self.vertex_id: NDArray[np.int64] = convert.readonly(data["vertex_id"])
        self.cage_vertex: NDArray[np.int32] = convert.readonly(data["cage_vertex"])
        self.vertex_sharpness: NDArray[np.float32] = convert.readonly(data["vertex_sharpness"])
        self.leaves_per_level: NDArray[np.int64] = convert.readonly(data["leaves_per_level"])
        self.max_error: float | None = data["max_error"]
        self.degree = degree
        self.max_level = max_level
        self.tolerance = tolerance
        self.uv_mode: UvMode = uv_mode
        self.vertex_values: FloatArray | None = data["vertex_values"]
        self.edge_origin: NDArray[np.int32] = convert.readonly(data["edge_origin"])
        self.edge_level: NDArray[np.int32] = convert.readonly(data["edge_level"])
        self.edge_sharpness: NDArray[np.float32] = convert.readonly(data["edge_sharpness"])
        self.cage_edges: NDArray[np.int32] = convert.readonly(data["cage_edges"])
        sets = dict(zip(names, data["face_varying"], strict=True))
        self.uvs: FloatArray | None = sets.pop(None, None)
        self.face_varying: dict[str, FloatArray] = {
            name: values for name, values in sets.items() if name is not None
        }

    @property
    def num_vertices(self) -> int:
        """Number of output vertices."""
        return len(self.points)

    @property
    def num_triangles(self) -> int:
        """Number of output triangles."""
        return len(self.triangles)

    @property
    def num_leaves(self) -> int:
        """Number of quadtree leaves (quads before triangulation)."""
        return int(self.leaves_per_level.sum())

    @convert.memory_errors()
    def write_obj(self, path: str | os.PathLike[str]) -> None:
        """Writes the triangles as OBJ (``v``, ``vt`` per triangle corner when there are uvs,
        ``f``).

        Raises:
            BidegreeIOError: the file cannot be written.
        """
        points = np.ascontiguousarray(self.points)
        if points.dtype not in (np.float32, np.float64):
            points = points.astype(np.float64)
        sizes = np.full(len(self.triangles), 3, dtype=np.int64)
        write_obj_arrays(path, points, sizes, self.triangles.reshape(-1), self.uvs)

    def __repr__(self) -> str:
        return (
            f"AdaptiveResult(vertices={self.num_vertices}, triangles={self.num_triangles}, "
            f"leaves={self.num_leaves}, degree={self.degree}, max_level={self.max_level}, "
            f"tolerance={self.tolerance}, dtype={self.points.dtype})"
        )


@convert.memory_errors()
def subdivide_adaptive(
    mesh: Mesh,
    degree: int = 4,
    max_level: int = 4,
    tolerance: float = 1e-3,
    memory_budget: int | None = None,
    measure_leaves: bool = False,
    *,
    uv_mode: UvMode = "boundaries",
    vertex_values: ArrayLike | None = None,
    face_varying: Mapping[
        str, ArrayLike | tuple[ArrayLike, UvMode] | tuple[ArrayLike, UvMode, ArrayLike]
    ]
    | None = None,
) -> AdaptiveResult:
    """Subdivides ``mesh`` adaptively (the paper's §3): a quadtree per quad of level 1, refined
    while a node is not flat enough, up to ``max_level``, with neighbouring leaves (sharing an
    edge or a corner) at most one level apart, drawn as crack-free triangles.

    Args:
        mesh: the cage (3-D points; creases, corners and the boundary rule are honoured).
        degree: averaging steps per level, ``1..=MAX_DEGREE``.
        max_level: deepest level, ``1..=MAX_LEVELS``.
        tolerance: flatness tolerance relative to the diagonal of the cage's bounding box: a
            node is refined while the points of its children deviate from its bilinear patch by
            more than this. 0 refines everywhere (uniform ``max_level``).
        memory_budget: refuse work estimated above this many bytes (default 4 GiB).
        measure_leaves: also measure every leaf's error (one level more of work around the
            leaves) and report the largest as ``max_error``.
        uv_mode: the face-varying mode of the mesh's uvs and of ``face_varying`` (OpenSubdiv's
            six, as :meth:`Plan.evaluate_face_varying`).
        vertex_values: (cage vertices, C) any per-vertex attribute, carried through the same
            levels as the points (``AdaptiveResult.vertex_values``).
        face_varying: name -> (cage corners, C) further face-varying sets (each welded on its
            own), at the triangle corners (``AdaptiveResult.face_varying``); a set given as
            ``(values, mode)`` has its own mode instead of ``uv_mode``, one given as
            ``(values, mode, indices)`` is indexed as in :meth:`Plan.evaluate_face_varying`
            (``values`` (N, C), ``indices`` per face corner: the set's topology). The mesh's
            :attr:`Mesh.uv_indices` are its uvs' topology.

    Every vertex is bit for bit the vertex of the uniform result at its level, and so are its
    values; face-varying values are those of the uniform result at the vertex's level. Holes
    (and boundary ``"none"``) leave faces out as the uniform result does; non-manifold edges
    and vertices are infinitely sharp there as in the uniform result. Values given in another
    dtype than the points are converted to the points' dtype.

    Raises:
        NonFiniteError, DegenerateFaceError: bad geometry.
        NonManifoldEdgeError, InconsistentOrientationError, CreaseNotAnEdgeError: bad topology.
        DegreeOutOfRangeError, LevelOutOfRangeError, MemoryBudgetError, InvalidInputError.

    Warns:
        IsolatedVerticesWarning: the cage has vertices in no face (they are dropped).
    """
    if not isinstance(mesh, Mesh):
        raise InvalidInputError(f"mesh must be a bidegree.Mesh, not {type(mesh).__name__}")
    degree = convert.int_arg(degree, "degree")
    max_level = convert.int_arg(max_level, "max_level")
    if not 1 <= max_level <= _native.MAX_LEVELS:
        # The core refuses it too, but as "levels out of range 0..": say what adaptive allows.
        error = LevelOutOfRangeError(
            f"max_level {max_level} is out of range 1..={_native.MAX_LEVELS} (adaptive "
            "subdivision refines at least one level)"
        )
        error.levels, error.max = max_level, _native.MAX_LEVELS
        raise error
    tol = convert.tolerance(tolerance)
    uv_mode = convert.choice(uv_mode, convert.UV_MODES, "uv_mode")  # type: ignore[assignment]
    dtype = mesh.points.dtype
    values = None
    # Inputs given 1-D ((vertices,) / (corners,)) come back 1-D, as from Plan.evaluate.
    flat_values = False
    if vertex_values is not None:
        values, flat_values = convert.values_2d(
            vertex_values, mesh.num_vertices, "vertex_values", "vertices"
        )
        values = np.ascontiguousarray(values, dtype=dtype)
    names: list[str | None] = []
    sets: list[tuple[FloatArray, str, NDArray[np.uint32] | None]] = []
    flat_sets: set[str] = set()
    if mesh.uvs is not None:
        names.append(None)
        sets.append((np.ascontiguousarray(mesh.uvs, dtype=dtype), uv_mode, mesh.uv_indices))
    if face_varying is not None and not isinstance(face_varying, Mapping):
        raise InvalidInputError(
            f"face_varying must be a mapping of name -> values, not {type(face_varying).__name__}"
        )
    for name, given in (face_varying or {}).items():
        array, mode, indices = _face_varying_set(given, uv_mode)
        mode = convert.choice(mode, convert.UV_MODES, "uv_mode")
        what = f"face_varying[{name!r}]"
        index = None
        if indices is not None:
            table = convert.float_array(array, what)
            rows = len(table) if table.ndim else 0
            table, flat = convert.values_2d(table, rows, what, "indexed values")
            index = convert.face_varying_indices(indices, mesh.num_corners, rows, f"{what} indices")
            corners = table[index]
        else:
            corners, flat = convert.values_2d(array, mesh.num_corners, what, "face corners")
        if flat:
            flat_sets.add(str(name))
        names.append(str(name))
        sets.append((np.ascontiguousarray(corners, dtype=dtype), mode, index))
    data = _native.subdivide_adaptive(
        mesh._cage,
        mesh.points,
        degree,
        max_level,
        tol,
        mesh.boundary,
        convert.budget(memory_budget),
        bool(measure_leaves),
        values,
        sets,
    )
    used = np.zeros(mesh.num_vertices, dtype=bool)
    used[mesh.face_indices] = True
    convert.warn_isolated(np.flatnonzero(~used).astype(np.int32))
    if flat_values:
        data["vertex_values"] = data["vertex_values"].reshape(-1)
    data["face_varying"] = [
        values.reshape(-1) if name in flat_sets else values
        for name, values in zip(names, data["face_varying"], strict=True)
    ]
    return AdaptiveResult(data, degree, max_level, tol, uv_mode, tuple(names))


def _face_varying_set(given: Any, uv_mode: str) -> tuple[Any, str, Any]:
    """A ``face_varying`` entry as ``(values, mode, indices or None)``."""
    if not isinstance(given, tuple):
        return given, uv_mode, None
    if len(given) == 2:
        return given[0], given[1], None
    if len(given) == 3:
        return given
    raise InvalidInputError(
        f"a face_varying set is values, (values, mode) or (values, mode, indices), not a "
        f"tuple of {len(given)}"
    )
