"""bidegree: subdivision surfaces of any degree by repeated averaging (Zorin & Schröder).

Degree 1 is bilinear, 2 a Doo-Sabin variant, 3 a Catmull-Clark variant, 4 biquartic, and so on.
The work happens in a Rust core (``bidegree._native``); this module checks and converts
arguments (numpy in, numpy out) and documents the API::

    import numpy as np, bidegree
    cage = bidegree.Mesh(points, faces)
    result = bidegree.subdivide(cage, degree=4, levels=3)
    result.points, result.face_sizes, result.face_indices

    plan = bidegree.Plan(cage, degree=4, levels=3)       # topology work done once
    moved = plan.evaluate(deformed_points)               # cheap per frame, any number of channels

Arrays handed to bidegree are never modified. Points stay float32 if given as float32 and
float64 if given as float64 (other numeric types become float64). The GIL is released while the
core works. Errors are subclasses of :class:`BidegreeError`, one per kind of problem.
"""

from __future__ import annotations

import itertools
import operator
import os
import warnings
from collections.abc import Sequence
from functools import cached_property
from typing import Any, Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from . import _native
from ._errors import (
    BidegreeError,
    BidegreeIOError,
    CreaseNotAnEdgeError,
    DegenerateFaceError,
    DegreeOutOfRangeError,
    EmptyMeshError,
    FaceTooSmallError,
    InconsistentOrientationError,
    IndexOutOfRangeError,
    InternalError,
    InvalidInputError,
    IsolatedVerticesWarning,
    LevelOutOfRangeError,
    MemoryBudgetError,
    NonFiniteError,
    NonManifoldEdgeError,
    RepeatedVertexError,
)

__all__ = [
    "DEFAULT_MEMORY_BUDGET",
    "INFINITELY_SHARP",
    "MAX_DEGREE",
    "MAX_LEVELS",
    "AdaptiveResult",
    "BidegreeError",
    "BidegreeIOError",
    "CreaseNotAnEdgeError",
    "DegenerateFaceError",
    "DegreeOutOfRangeError",
    "EmptyMeshError",
    "FaceTooSmallError",
    "InconsistentOrientationError",
    "IndexOutOfRangeError",
    "InternalError",
    "InvalidInputError",
    "IsolatedVerticesWarning",
    "LevelOutOfRangeError",
    "MemoryBudgetError",
    "Mesh",
    "NonFiniteError",
    "NonManifoldEdgeError",
    "Plan",
    "RepeatedVertexError",
    "Result",
    "__version__",
    "estimate",
    "subdivide",
    "subdivide_adaptive",
]

__version__: str = _native.__version__

#: Highest supported degree.
MAX_DEGREE: int = _native.MAX_DEGREE
#: Highest number of levels.
MAX_LEVELS: int = _native.MAX_LEVELS
#: Memory budget of a request unless told otherwise (4 GiB).
DEFAULT_MEMORY_BUDGET: int = _native.DEFAULT_MEMORY_BUDGET
#: Sharpness at or above which a crease or corner is infinitely sharp (as in OpenSubdiv).
INFINITELY_SHARP: float = _native.INFINITELY_SHARP

Output = Literal["primal", "dual"]
Boundary = Literal["edge-only", "edge-and-corner"]
Rules = Literal["averaging", "classic"]
Creasing = Literal["uniform", "chaikin"]
FloatArray = NDArray[np.float32] | NDArray[np.float64]

_OUTPUTS = ("primal", "dual")
_BOUNDARIES = ("edge-only", "edge-and-corner")
_RULES = ("averaging", "classic")
_CREASING = ("uniform", "chaikin")
_INT64_MIN, _INT64_MAX = -(2**63), 2**63 - 1


# ---------------------------------------------------------------------------------------------
# Argument conversion (no per-element Python work except for inputs that are Python lists)


def _float_array(values: ArrayLike, what: str) -> FloatArray:
    """A C-contiguous float32 (if given float32) or float64 copy-free view or copy of ``values``."""
    try:
        array = np.asarray(values)
    except (TypeError, ValueError) as exc:
        raise InvalidInputError(f"{what} is not a numeric array: {exc}") from None
    if array.dtype == np.float32:
        dtype: type[np.floating[Any]] = np.float32
    elif array.dtype.kind in "fiub":
        dtype = np.float64
    else:
        raise InvalidInputError(f"{what} must be numeric, not {array.dtype}")
    # ascontiguousarray also turns Fortran order and foreign byte order into what Rust reads.
    return np.ascontiguousarray(array, dtype=dtype)


def _int_array(values: ArrayLike, what: str) -> NDArray[np.int64]:
    """A C-contiguous int64 array of ``values`` (integers only; unsigned beyond int64 refused)."""
    try:
        array = np.asarray(values)
    except (TypeError, ValueError) as exc:
        raise InvalidInputError(f"{what} is not an integer array: {exc}") from None
    if array.size == 0:
        return np.zeros(array.shape, dtype=np.int64)
    if array.dtype.kind not in "iub":
        raise InvalidInputError(f"{what} must contain integers, not {array.dtype}")
    if array.dtype.kind == "u" and array.dtype.itemsize >= 8 and int(array.max()) > _INT64_MAX:
        raise IndexOutOfRangeError(f"{what} has index {int(array.max())}, beyond int64")
    return np.ascontiguousarray(array, dtype=np.int64)


def _readonly(array: np.ndarray) -> np.ndarray:
    array.setflags(write=False)
    return array


def _owned(array: np.ndarray, source: Any, copy: bool = True) -> np.ndarray:
    """``array`` as an array that shares no memory with the caller's ``source`` (unless
    ``copy`` is False: arrays bidegree made itself and hands over)."""
    if copy and isinstance(source, np.ndarray) and np.shares_memory(array, source):
        return array.copy()
    return array


def _int_arg(value: Any, what: str) -> int:
    """An integer option (numpy integers accepted), clamped to int64 for the core."""
    if isinstance(value, bool):
        raise InvalidInputError(f"{what} must be an integer, not a bool")
    try:
        number = operator.index(value)
    except TypeError:
        raise InvalidInputError(f"{what} must be an integer, not {type(value).__name__}") from None
    return min(max(number, _INT64_MIN), _INT64_MAX)


def _choice(value: Any, choices: tuple[str, ...], what: str) -> str:
    if not isinstance(value, str) or value not in choices:
        allowed = " or ".join(repr(c) for c in choices)
        raise InvalidInputError(f"{what} must be {allowed}, not {value!r}")
    return value


def _budget(memory_budget: int | None) -> int | None:
    if memory_budget is None:
        return None
    budget = _int_arg(memory_budget, "memory_budget")
    if budget < 0:
        raise InvalidInputError(f"memory_budget must be >= 0, not {budget}")
    return min(budget, 2**64 - 1)


def _sharpness(values: ArrayLike, count: int, what: str) -> NDArray[np.float32]:
    try:
        sharpness = np.asarray(values, dtype=np.float32)
    except (TypeError, ValueError) as exc:
        raise InvalidInputError(f"{what} sharpness must be numbers: {exc}") from None
    if sharpness.ndim == 0:
        sharpness = np.full(count, sharpness, dtype=np.float32)
    if sharpness.shape != (count,):
        raise InvalidInputError(
            f"{what} sharpness must have shape ({count},) (one per {what}), not {sharpness.shape}"
        )
    return np.array(sharpness, dtype=np.float32, order="C")


def _pair(value: Any, what: str) -> tuple[Any, Any]:
    try:
        first, second = value
    except (TypeError, ValueError):
        raise InvalidInputError(
            f"{what} must be a pair (indices, sharpness), not {type(value).__name__}"
        ) from None
    return first, second


def _values_2d(values: ArrayLike, rows: int, what: str, expected: str) -> tuple[FloatArray, bool]:
    """``values`` as a (rows, C) float array; a 1-D input counts as C = 1 (flag returned)."""
    array = _float_array(values, what)
    flat = array.ndim == 1
    if flat:
        array = array.reshape(-1, 1)
    if array.ndim != 2:
        raise InvalidInputError(f"{what} must have shape ({expected}, C), not {array.shape}")
    if array.shape[0] != rows:
        raise InvalidInputError(
            f"{what} has {array.shape[0]} rows but the cage has {rows} {expected}"
        )
    if array.shape[1] == 0:
        raise InvalidInputError(f"{what} must have at least one channel")
    return array, flat


# ---------------------------------------------------------------------------------------------
# Mesh


class Mesh:
    """A subdivision cage: points, polygonal faces, and optional creases, corners, face-varying
    UVs and boundary rule. Construction checks shapes, face sizes, indices and repeated vertices;
    the rest of the topology (manifold edges, consistent orientation, creases that are edges) is
    checked when a :class:`Plan` is built, the geometry (finite points, no zero-area face) by
    :func:`subdivide`.

    Args:
        points: (V, 3) coordinates, float32 or float64 (other numbers become float64).
        faces: the faces as sequences of vertex indices (counter-clockwise), or an (F, k) integer
            array of faces of equal size. Alternatively give ``face_sizes`` and ``face_indices``.
        face_sizes: (F,) number of corners of each face.
        face_indices: (sum of face_sizes,) vertex of each face corner, faces one after the other.
        creases: ``(edges, sharpness)``: (K, 2) vertex pairs that are mesh edges and (K,)
            sharpness values (or one for all); ``>= 10`` or ``inf`` is infinitely sharp.
        corners: ``(vertices, sharpness)``: (K,) vertices and (K,) sharpness values (or one).
        uvs: (corners, 2) face-varying texture coordinates, one per face corner.
        boundary: ``"edge-only"`` (boundary edges are sharp) or ``"edge-and-corner"`` (also
            boundary vertices of a single face are corners).

    Raises:
        InvalidInputError: wrong shapes or types, bad sharpness or boundary values.
        EmptyMeshError, FaceTooSmallError, RepeatedVertexError, IndexOutOfRangeError: bad faces,
            creases or corners.
    """

    def __init__(
        self,
        points: ArrayLike,
        faces: Sequence[Sequence[int]] | ArrayLike | None = None,
        *,
        face_sizes: ArrayLike | None = None,
        face_indices: ArrayLike | None = None,
        creases: tuple[ArrayLike, ArrayLike] | None = None,
        corners: tuple[ArrayLike, ArrayLike] | None = None,
        uvs: ArrayLike | None = None,
        boundary: Boundary = "edge-only",
    ) -> None:
        # Mesh.from_obj hands over arrays nobody else holds: no defensive copies for those.
        copy = not getattr(self, "_arrays_are_ours", False)
        pts = _owned(_float_array(points, "points"), points, copy)
        if pts.ndim != 2 or pts.shape[1] != 3:
            raise InvalidInputError(f"points must have shape (V, 3), not {pts.shape}")

        if faces is not None:
            if face_sizes is not None or face_indices is not None:
                raise InvalidInputError("give either faces or face_sizes + face_indices, not both")
            sizes, indices = self._faces_to_arrays(faces)
        else:
            if face_sizes is None or face_indices is None:
                raise InvalidInputError("give faces, or both face_sizes and face_indices")
            sizes = _owned(_int_array(face_sizes, "face_sizes"), face_sizes, copy)
            indices = _owned(_int_array(face_indices, "face_indices"), face_indices, copy)
            if sizes.ndim != 1 or indices.ndim != 1:
                raise InvalidInputError(
                    f"face_sizes and face_indices must be 1-D, not {sizes.shape} and "
                    f"{indices.shape}"
                )

        crease_pair: tuple[NDArray[np.int64], NDArray[np.float32]] | None = None
        if creases is not None:
            edges_in, sharp_in = _pair(creases, "creases")
            edges = _int_array(edges_in, "crease edges")
            if edges.size == 0:
                edges = edges.reshape(0, 2)
            if edges.ndim != 2 or edges.shape[1] != 2:
                raise InvalidInputError(f"crease edges must have shape (K, 2), not {edges.shape}")
            crease_pair = (_owned(edges, edges_in), _sharpness(sharp_in, len(edges), "crease"))

        corner_pair: tuple[NDArray[np.int64], NDArray[np.float32]] | None = None
        if corners is not None:
            vertices_in, sharp_in = _pair(corners, "corners")
            vertices = _int_array(vertices_in, "corner vertices").reshape(-1)
            corner_pair = (
                _owned(vertices, vertices_in),
                _sharpness(sharp_in, len(vertices), "corner"),
            )

        uv_array: FloatArray | None = None
        if uvs is not None:
            uv_array = _owned(_float_array(uvs, "uvs"), uvs, copy)
            if uv_array.ndim != 2 or uv_array.shape[1] != 2:
                raise InvalidInputError(
                    f"uvs must have shape (corners, 2) (face-varying), not {uv_array.shape}"
                )
            if len(uv_array) != len(indices):
                raise InvalidInputError(
                    f"{len(uv_array)} uvs but the mesh has {len(indices)} face corners "
                    "(uvs are face-varying: one per face corner)"
                )

        self._boundary: Boundary = _choice(boundary, _BOUNDARIES, "boundary")  # type: ignore[assignment]
        empty_i = np.zeros(0, dtype=np.int64)
        empty_f = np.zeros(0, dtype=np.float32)
        self._cage = _native.Cage(
            len(pts),
            sizes,
            indices,
            crease_pair[0].reshape(-1) if crease_pair else empty_i,
            crease_pair[1] if crease_pair else empty_f,
            corner_pair[0] if corner_pair else empty_i,
            corner_pair[1] if corner_pair else empty_f,
        )
        self._points = _readonly(pts)
        self._face_sizes = _readonly(sizes)
        self._face_indices = _readonly(indices)
        self._creases = (
            (_readonly(crease_pair[0]), _readonly(crease_pair[1])) if crease_pair else None
        )
        self._corners = (
            (_readonly(corner_pair[0]), _readonly(corner_pair[1])) if corner_pair else None
        )
        self._uvs = _readonly(uv_array) if uv_array is not None else None

    @staticmethod
    def _faces_to_arrays(faces: Any) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
        if isinstance(faces, np.ndarray):
            array = _int_array(faces, "faces")
            if array.ndim != 2:
                raise InvalidInputError(
                    f"a faces array must have shape (F, k) (faces of k corners), not {array.shape}"
                )
            sizes = np.full(array.shape[0], array.shape[1], dtype=np.int64)
            return sizes, array.reshape(-1).copy()
        try:
            face_list = [list(face) for face in faces]
        except TypeError:
            raise InvalidInputError(
                "faces must be a sequence of sequences of vertex indices"
            ) from None
        sizes = np.fromiter((len(face) for face in face_list), dtype=np.int64, count=len(face_list))
        flat = list(itertools.chain.from_iterable(face_list))
        indices = _int_array(flat, "faces") if flat else np.zeros(0, dtype=np.int64)
        return sizes, indices.reshape(-1)

    @classmethod
    def from_obj(cls, path: str | os.PathLike[str], *, boundary: Boundary | None = None) -> Mesh:
        """Reads an OBJ file: ``v``, ``vt`` (as face-varying uvs when every face corner has
        one), ``f`` (any index form, negative indices), and OpenSubdiv's ``t crease``,
        ``t corner`` and ``t interpolateboundary`` tags.

        Args:
            path: the file.
            boundary: overrides the file's ``t interpolateboundary`` tag; without either the
                boundary is ``"edge-only"``.

        Raises:
            BidegreeIOError: the file cannot be read or is malformed (``path:LINE: message``).
            BidegreeError: the topology is invalid (see :class:`Mesh`).
        """
        data = _native.read_obj(os.fspath(path))
        uvs = None
        if data["face_uvs"] is not None:
            uvs = data["uvs"][data["face_uvs"]]
        creases = None
        if len(data["crease_sharpness"]):
            creases = (data["crease_edges"], data["crease_sharpness"])
        corners = None
        if len(data["corner_sharpness"]):
            corners = (data["corner_vertices"], data["corner_sharpness"])
        chosen = boundary if boundary is not None else (data["boundary"] or "edge-only")
        mesh = cls.__new__(cls)
        mesh._arrays_are_ours = True
        mesh.__init__(  # type: ignore[misc]
            data["points"],
            face_sizes=data["face_sizes"],
            face_indices=data["face_indices"],
            creases=creases,
            corners=corners,
            uvs=uvs,
            boundary=chosen,
        )
        del mesh._arrays_are_ours
        return mesh

    def write_obj(self, path: str | os.PathLike[str]) -> None:
        """Writes the cage's points, faces and uvs as OBJ (creases and corners are not kept)."""
        _write_obj(path, self._points, self._face_sizes, self._face_indices, self._uvs)

    @property
    def points(self) -> FloatArray:
        """(V, 3) points (read-only; float32 or float64 as given)."""
        return self._points

    @property
    def face_sizes(self) -> NDArray[np.int64]:
        """(F,) corners per face (read-only)."""
        return self._face_sizes

    @property
    def face_indices(self) -> NDArray[np.int64]:
        """Vertex of each face corner (read-only)."""
        return self._face_indices

    @property
    def creases(self) -> tuple[NDArray[np.int64], NDArray[np.float32]] | None:
        """``((K, 2) edges, (K,) sharpness)`` or None."""
        return self._creases

    @property
    def corners(self) -> tuple[NDArray[np.int64], NDArray[np.float32]] | None:
        """``((K,) vertices, (K,) sharpness)`` or None."""
        return self._corners

    @property
    def uvs(self) -> FloatArray | None:
        """(corners, 2) face-varying uvs or None."""
        return self._uvs

    @property
    def boundary(self) -> Boundary:
        """``"edge-only"`` or ``"edge-and-corner"``."""
        return self._boundary

    @property
    def num_vertices(self) -> int:
        """Number of points (including isolated ones)."""
        return len(self._points)

    @property
    def num_faces(self) -> int:
        """Number of faces."""
        return len(self._face_sizes)

    @property
    def num_corners(self) -> int:
        """Number of face corners (the length of ``face_indices``)."""
        return len(self._face_indices)

    def __repr__(self) -> str:
        extras = []
        if self._creases is not None:
            extras.append(f"creases={len(self._creases[1])}")
        if self._corners is not None:
            extras.append(f"corners={len(self._corners[1])}")
        if self._uvs is not None:
            extras.append("uvs")
        extra = (", " + ", ".join(extras)) if extras else ""
        return (
            f"Mesh(vertices={self.num_vertices}, faces={self.num_faces}, "
            f"boundary={self._boundary!r}, dtype={self._points.dtype}{extra})"
        )


def _write_obj(
    path: str | os.PathLike[str],
    points: FloatArray,
    face_sizes: NDArray[np.integer[Any]],
    face_indices: NDArray[np.integer[Any]],
    uvs: FloatArray | None,
) -> None:
    offsets = np.zeros(len(face_sizes) + 1, dtype=np.uint32)
    np.cumsum(face_sizes, out=offsets[1:], dtype=np.uint32)
    indices = np.ascontiguousarray(face_indices, dtype=np.uint32)
    if uvs is not None:
        uvs = np.ascontiguousarray(uvs, dtype=points.dtype)
    _native.write_obj(os.fspath(path), points, offsets, indices, uvs)


# ---------------------------------------------------------------------------------------------
# Plan and Result


def _warn_isolated(isolated: NDArray[np.int32], stacklevel: int) -> None:
    if len(isolated):
        shown = ", ".join(str(v) for v in isolated[:10])
        more = ", ..." if len(isolated) > 10 else ""
        warnings.warn(
            f"{len(isolated)} isolated vertices (in no face) are dropped from the output: "
            f"[{shown}{more}]",
            IsolatedVerticesWarning,
            stacklevel=stacklevel + 1,
        )


class Plan:
    """The topology work of a subdivision, done once: evaluate it for any number of point sets
    (a deforming cage, per-frame) or other per-vertex attributes.

    Args:
        mesh: the cage.
        degree: averaging steps per level, ``1..=MAX_DEGREE`` (3 ~ Catmull-Clark, 4 biquartic).
        levels: refinement levels, ``0..=MAX_LEVELS``; each multiplies the face count by ~4.
        output: ``"primal"`` (the drawing mesh) or ``"dual"`` (the true dual mesh).
        memory_budget: refuse requests estimated to need more bytes (default 4 GiB).
        rules: ``"averaging"`` (repeated averaging, any degree) or ``"classic"`` (degrees 1..3:
            3 is Catmull-Clark exactly as OpenSubdiv's catmark, 2 the original Doo-Sabin).
        creasing: ``"uniform"`` or ``"chaikin"``: how classic degree-3 semi-sharp creases
            decrease from level to level (OpenSubdiv's creasing method; Blender uses uniform).

    Raises:
        NonManifoldEdgeError, InconsistentOrientationError, CreaseNotAnEdgeError: bad topology.
        DegreeOutOfRangeError, LevelOutOfRangeError, MemoryBudgetError, InvalidInputError.

    Warns:
        IsolatedVerticesWarning: the cage has vertices in no face (they are dropped).
    """

    _native_plan: Any
    _mesh: Mesh

    def __init__(
        self,
        mesh: Mesh,
        degree: int = 4,
        levels: int = 2,
        output: Output = "primal",
        memory_budget: int | None = None,
        rules: Rules = "averaging",
        creasing: Creasing = "uniform",
    ) -> None:
        if not isinstance(mesh, Mesh):
            raise InvalidInputError(f"mesh must be a bidegree.Mesh, not {type(mesh).__name__}")
        native = _native.Plan(
            mesh._cage,
            _int_arg(degree, "degree"),
            _int_arg(levels, "levels"),
            _choice(output, _OUTPUTS, "output"),
            mesh.boundary,
            _budget(memory_budget),
            _choice(rules, _RULES, "rules"),
            _choice(creasing, _CREASING, "creasing"),
        )
        self._init(mesh, native)
        _warn_isolated(self.isolated_vertices, stacklevel=2)

    @classmethod
    def _wrap(cls, mesh: Mesh, native: Any) -> Plan:
        plan = cls.__new__(cls)
        plan._init(mesh, native)
        return plan

    def _init(self, mesh: Mesh, native: Any) -> None:
        self._mesh = mesh
        self._native_plan = native

    def evaluate(self, points: ArrayLike) -> FloatArray:
        """Subdivides per-vertex values: (V, C) -> (N, C) for any C >= 1 (positions, colours,
        weights, ...); a (V,) array is one channel and gives (N,). float32 stays float32, float64
        stays float64. No validation of the values (NaN in, NaN out): see :func:`subdivide`.
        """
        values, flat = _values_2d(points, self._mesh.num_vertices, "points", "vertices")
        out = self._native_plan.evaluate(values)
        return out.reshape(-1) if flat else out

    def limit_positions(self, points: ArrayLike | None = None) -> FloatArray:
        """Exact limit positions at the output vertices: (V, C) -> (N, C) for any per-vertex
        attribute; the first V' rows (V' cage vertices in faces) are the limits of the cage
        vertices. Default: the cage's own points.

        Every degree of the averaging rules (eigenvector masks of the paper's §4 at interior
        vertices, the B-spline of the curve on boundaries and creases; vertices near irregular
        points or creases are refined a few levels further first, see
        :attr:`limit_extra_levels`), and classic degree 3 (OpenSubdiv's limit masks). Needs the
        primal output.

        Raises:
            InvalidInputError: dual output, classic rules at degree 2, wrong shapes.
            MemoryBudgetError: the extra levels would not fit the memory budget.
        """
        if points is None:
            values: FloatArray = self._mesh.points
            flat = False
        else:
            values, flat = _values_2d(points, self._mesh.num_vertices, "points", "vertices")
        out = self._native_plan.limit_positions(values)
        return out.reshape(-1) if flat else out

    def limit_surface(self, points: ArrayLike | None = None) -> tuple[FloatArray, FloatArray]:
        """Limit positions (N, 3) and unit limit normals (output corners, 3), in the order of
        :attr:`face_indices` (face-varying, like Blender's custom split normals and USD's
        ``faceVarying`` normals): smooth vertices have one normal at all their corners; at
        boundaries, creases and corners each side has its own. Averaging rules only.

        Interior normals are exact (subdominant eigenvectors); normals at curve vertices are
        one-sided estimates from the finer level the limit is computed on (first-order in its
        spacing). Degree 1 gives each face's bilinear normal. Degenerate geometry gives zeros.
        """
        positions, normals = self._native_plan.limit_surface(self._points(points))
        return positions, normals

    @property
    def limit_extra_levels(self) -> int:
        """Levels the limit evaluation refines beyond :attr:`levels` so that every output
        vertex has a clean neighbourhood (0 on regular meshes); built on first use."""
        return int(self._native_plan.limit_extra_levels)

    def evaluate_face_varying(self, values: ArrayLike) -> FloatArray:
        """Interpolates per-face-corner values (e.g. UVs) linearly: (corners, C) -> (output
        corners, C), in the order of :attr:`face_indices`."""
        array, flat = _values_2d(values, self._mesh.num_corners, "values", "face corners")
        out = self._native_plan.evaluate_face_varying(array)
        return out.reshape(-1) if flat else out

    def result(
        self, points: ArrayLike | None = None, *, limit: bool = False, normals: bool = False
    ) -> Result:
        """A :class:`Result` for ``points`` (default: the cage's own points), with uvs when the
        cage has them. ``limit``: the points are pushed to the limit surface
        (:meth:`limit_positions`); ``normals``: the result carries the limit normals
        (:meth:`limit_surface`)."""
        return _result(self, self._points(points), None, limit, normals)

    def _points(self, points: ArrayLike | None) -> FloatArray:
        """``points`` checked as (V, 3), or the cage's own points."""
        if points is None:
            return self._mesh.points
        values, _ = _values_2d(points, self._mesh.num_vertices, "points", "vertices")
        if values.shape[1] != 3:
            raise InvalidInputError(f"points must have shape (V, 3), not {values.shape}")
        return values

    @property
    def mesh(self) -> Mesh:
        """The cage this plan was made for."""
        return self._mesh

    @property
    def degree(self) -> int:
        """Degree of the scheme."""
        return int(self._native_plan.degree)

    @property
    def levels(self) -> int:
        """Number of levels."""
        return int(self._native_plan.levels)

    @property
    def output(self) -> Output:
        """``"primal"`` or ``"dual"``."""
        return self._native_plan.output  # type: ignore[no-any-return]

    @property
    def boundary(self) -> Boundary:
        """``"edge-only"`` or ``"edge-and-corner"`` (from the mesh)."""
        return self._native_plan.boundary  # type: ignore[no-any-return]

    @property
    def rules(self) -> Rules:
        """``"averaging"`` or ``"classic"``."""
        return self._native_plan.rules  # type: ignore[no-any-return]

    @property
    def num_output_vertices(self) -> int:
        """Vertices of the output mesh."""
        return int(self._native_plan.num_output_vertices)

    @property
    def num_output_faces(self) -> int:
        """Faces of the output mesh."""
        return int(self._native_plan.num_output_faces)

    @cached_property
    def isolated_vertices(self) -> NDArray[np.int32]:
        """Cage vertices in no face (dropped), int32, read-only."""
        return _readonly(self._native_plan.isolated_vertices())

    @cached_property
    def face_sizes(self) -> NDArray[np.int32]:
        """(F,) corners of each output face, int32, read-only."""
        return _readonly(self._native_plan.face_sizes())

    @cached_property
    def face_indices(self) -> NDArray[np.int32]:
        """Output vertex of each output face corner, int32, read-only."""
        return _readonly(self._native_plan.face_indices())

    @cached_property
    def face_origin(self) -> NDArray[np.int32]:
        """(F,) cage face each output face comes from, int32, read-only."""
        return _readonly(self._native_plan.face_origin())

    @cached_property
    def edges(self) -> NDArray[np.int32]:
        """(E, 2) edges of the output mesh, int32, read-only (built on first use)."""
        return _readonly(self._native_plan.edges())

    @cached_property
    def corner_edges(self) -> NDArray[np.int32]:
        """Edge (row of :attr:`edges`) from each output face corner to the next, int32."""
        return _readonly(self._native_plan.corner_edges())

    def __repr__(self) -> str:
        return (
            f"Plan(degree={self.degree}, levels={self.levels}, output={self.output!r}, "
            f"boundary={self.boundary!r}, input_vertices={self._mesh.num_vertices}, "
            f"output_vertices={self.num_output_vertices}, output_faces={self.num_output_faces})"
        )


class Result:
    """A subdivided mesh: ``points`` (N, 3) in the dtype of the input (refined points, or limit
    positions with ``limit=True``), the polygons (``face_sizes``, ``face_indices``, int32),
    ``face_origin`` (cage face of each face), ``edges`` (E, 2), ``corner_edges``, ``uvs``
    (output corners, 2) when the cage has uvs and ``normals`` (output corners, 3) with
    ``normals=True``.
    Topology arrays are shared with the :class:`Plan` and read-only; ``points`` is yours.
    """

    def __init__(self, plan: Plan, points: FloatArray, normals: FloatArray | None = None) -> None:
        self._plan = plan
        self.points: FloatArray = points
        #: (output corners, 3) unit limit normals, one per face corner, when asked for.
        self.normals: FloatArray | None = normals
        mesh_uvs = plan.mesh.uvs
        self.uvs: FloatArray | None = (
            plan.evaluate_face_varying(mesh_uvs) if mesh_uvs is not None else None
        )

    @property
    def plan(self) -> Plan:
        """The plan that made this result (to evaluate further point sets)."""
        return self._plan

    @property
    def face_sizes(self) -> NDArray[np.int32]:
        """(F,) corners of each face, int32."""
        return self._plan.face_sizes

    @property
    def face_indices(self) -> NDArray[np.int32]:
        """Vertex of each face corner, int32."""
        return self._plan.face_indices

    @property
    def face_origin(self) -> NDArray[np.int32]:
        """(F,) cage face of each face, int32."""
        return self._plan.face_origin

    @property
    def edges(self) -> NDArray[np.int32]:
        """(E, 2) edges, int32."""
        return self._plan.edges

    @property
    def corner_edges(self) -> NDArray[np.int32]:
        """Edge from each face corner to the next (row of ``edges``), int32."""
        return self._plan.corner_edges

    @property
    def degree(self) -> int:
        """Degree of the scheme."""
        return self._plan.degree

    @property
    def levels(self) -> int:
        """Number of levels."""
        return self._plan.levels

    @property
    def output(self) -> Output:
        """``"primal"`` or ``"dual"``."""
        return self._plan.output

    @property
    def boundary(self) -> Boundary:
        """``"edge-only"`` or ``"edge-and-corner"``."""
        return self._plan.boundary

    @property
    def num_vertices(self) -> int:
        """Number of output vertices."""
        return len(self.points)

    @property
    def num_faces(self) -> int:
        """Number of output faces."""
        return self._plan.num_output_faces

    def write_obj(self, path: str | os.PathLike[str]) -> None:
        """Writes the result as OBJ (``v``, ``vt`` when there are uvs, ``vn`` per face corner
        when there are normals, ``f``), fast.

        Raises:
            BidegreeIOError: the file cannot be written.
            InvalidInputError: ``points`` was replaced by an array of another shape.
        """
        points = np.ascontiguousarray(self.points)
        if points.dtype not in (np.float32, np.float64):
            points = points.astype(np.float64)
        uvs = normals = None
        if self.uvs is not None:
            uvs = np.ascontiguousarray(self.uvs, dtype=points.dtype)
        if self.normals is not None:
            normals = np.ascontiguousarray(self.normals, dtype=points.dtype)
        self._plan._native_plan.write_obj(os.fspath(path), points, uvs, normals)

    def __repr__(self) -> str:
        return (
            f"Result(vertices={self.num_vertices}, faces={self.num_faces}, degree={self.degree}, "
            f"levels={self.levels}, output={self.output!r}, dtype={self.points.dtype})"
        )


def subdivide(
    mesh: Mesh,
    degree: int = 4,
    levels: int = 2,
    output: Output = "primal",
    memory_budget: int | None = None,
    rules: Rules = "averaging",
    creasing: Creasing = "uniform",
    *,
    limit: bool = False,
    normals: bool = False,
) -> Result:
    """Subdivides ``mesh``: validates its geometry (finite points, no zero-area face), builds
    the plan and evaluates it, in one call into the core. Options as in :class:`Plan`; the
    result's :attr:`Result.plan` can evaluate further point sets.

    ``limit=True`` puts the output vertices on the limit surface (:meth:`Plan.limit_positions`);
    ``normals=True`` adds the unit limit normals per face corner as :attr:`Result.normals`
    (:meth:`Plan.limit_surface`). Both need the primal output and the averaging rules (classic
    degree 3 has limit positions, not normals).

    Raises:
        NonFiniteError, DegenerateFaceError: bad geometry.
        NonManifoldEdgeError, InconsistentOrientationError, CreaseNotAnEdgeError: bad topology.
        DegreeOutOfRangeError, LevelOutOfRangeError, MemoryBudgetError, InvalidInputError.

    Warns:
        IsolatedVerticesWarning: the cage has vertices in no face (they are dropped).
    """
    if not isinstance(mesh, Mesh):
        raise InvalidInputError(f"mesh must be a bidegree.Mesh, not {type(mesh).__name__}")
    native, points = _native.subdivide(
        mesh._cage,
        mesh.points,
        _int_arg(degree, "degree"),
        _int_arg(levels, "levels"),
        _choice(output, _OUTPUTS, "output"),
        mesh.boundary,
        _budget(memory_budget),
        _choice(rules, _RULES, "rules"),
        _choice(creasing, _CREASING, "creasing"),
        evaluate=not limit,
    )
    plan = Plan._wrap(mesh, native)
    _warn_isolated(plan.isolated_vertices, stacklevel=2)
    return _result(plan, mesh.points, points, limit, normals)


def _result(
    plan: Plan, values: FloatArray, refined: FloatArray | None, limit: bool, normals: bool
) -> Result:
    """The :class:`Result` of ``values`` through ``plan`` (``refined``: already evaluated)."""
    native = plan._native_plan
    if normals:
        positions, corner_normals = native.limit_surface(values)
        if limit:
            return Result(plan, positions, corner_normals)
        points = refined if refined is not None else native.evaluate(values)
        return Result(plan, points, corner_normals)
    if limit:
        return Result(plan, native.limit_positions(values))
    return Result(plan, refined if refined is not None else native.evaluate(values))


def estimate(mesh: Mesh, degree: int, levels: int, output: Output = "primal") -> dict[str, int]:
    """Output size and peak memory of a request, without doing it (and without a budget):
    ``{"vertices": ..., "faces": ..., "bytes": ...}``."""
    if not isinstance(mesh, Mesh):
        raise InvalidInputError(f"mesh must be a bidegree.Mesh, not {type(mesh).__name__}")
    vertices, faces, nbytes = _native.estimate(
        mesh._cage,
        _int_arg(degree, "degree"),
        _int_arg(levels, "levels"),
        _choice(output, _OUTPUTS, "output"),
        mesh.boundary,
    )
    return {"vertices": int(vertices), "faces": int(faces), "bytes": int(nbytes)}


# ---------------------------------------------------------------------------------------------
# Adaptive subdivision


def _tolerance(value: Any) -> float:
    if isinstance(value, bool):
        raise InvalidInputError("tolerance must be a number, not a bool")
    try:
        tolerance = float(value)
    except (TypeError, ValueError):
        raise InvalidInputError(f"tolerance must be a number, not {type(value).__name__}") from None
    if not np.isfinite(tolerance) or tolerance < 0:
        raise InvalidInputError(f"tolerance must be finite and >= 0, not {value!r}")
    return tolerance


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
        leaves_per_level: int64 (max_level + 1,), quadtree leaves at each level.
        max_error: with ``measure_leaves=True``, the largest flatness error of any leaf
            (relative to the cage's bounding-box diagonal), else None.
    """

    def __init__(self, data: dict[str, Any], degree: int, max_level: int, tolerance: float) -> None:
        self.points: FloatArray = data["points"]
        self.triangles: NDArray[np.int32] = _readonly(data["triangles"])
        self.face_origin: NDArray[np.int32] = _readonly(data["face_origin"])
        self.triangle_level: NDArray[np.int32] = _readonly(data["triangle_level"])
        self.vertex_level: NDArray[np.int32] = _readonly(data["vertex_level"])
        self.vertex_id: NDArray[np.int64] = _readonly(data["vertex_id"])
        self.leaves_per_level: NDArray[np.int64] = _readonly(data["leaves_per_level"])
        self.max_error: float | None = data["max_error"]
        self.degree = degree
        self.max_level = max_level
        self.tolerance = tolerance

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

    def write_obj(self, path: str | os.PathLike[str]) -> None:
        """Writes the triangles as OBJ (``v``, ``f``).

        Raises:
            BidegreeIOError: the file cannot be written.
        """
        points = np.ascontiguousarray(self.points)
        if points.dtype not in (np.float32, np.float64):
            points = points.astype(np.float64)
        sizes = np.full(len(self.triangles), 3, dtype=np.int64)
        _write_obj(path, points, sizes, self.triangles.reshape(-1), None)

    def __repr__(self) -> str:
        return (
            f"AdaptiveResult(vertices={self.num_vertices}, triangles={self.num_triangles}, "
            f"leaves={self.num_leaves}, degree={self.degree}, max_level={self.max_level}, "
            f"tolerance={self.tolerance}, dtype={self.points.dtype})"
        )


def subdivide_adaptive(
    mesh: Mesh,
    degree: int = 4,
    max_level: int = 4,
    tolerance: float = 1e-3,
    memory_budget: int | None = None,
    measure_leaves: bool = False,
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

    Every vertex is bit for bit the vertex of the uniform result at its level.

    Raises:
        NonFiniteError, DegenerateFaceError: bad geometry.
        NonManifoldEdgeError, InconsistentOrientationError, CreaseNotAnEdgeError: bad topology.
        DegreeOutOfRangeError, LevelOutOfRangeError, MemoryBudgetError, InvalidInputError.

    Warns:
        IsolatedVerticesWarning: the cage has vertices in no face (they are dropped).
    """
    if not isinstance(mesh, Mesh):
        raise InvalidInputError(f"mesh must be a bidegree.Mesh, not {type(mesh).__name__}")
    degree = _int_arg(degree, "degree")
    max_level = _int_arg(max_level, "max_level")
    tol = _tolerance(tolerance)
    data = _native.subdivide_adaptive(
        mesh._cage,
        mesh.points,
        degree,
        max_level,
        tol,
        mesh.boundary,
        _budget(memory_budget),
        bool(measure_leaves),
    )
    used = np.zeros(mesh.num_vertices, dtype=bool)
    used[mesh.face_indices] = True
    _warn_isolated(np.flatnonzero(~used).astype(np.int32), stacklevel=2)
    return AdaptiveResult(data, degree, max_level, tol)
