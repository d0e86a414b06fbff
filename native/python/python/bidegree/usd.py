"""USD export of a bidegree cage and its subdivided result (usd-core, ``pxr``).

The stage written by :func:`export` looks like this::

    /Bidegree              Xform, the default prim (kind = component)
    /Bidegree/Cage         Mesh: the input cage, subdivisionScheme = catmullClark, with the cage's
                           creases, corners and boundary rule, so that any USD renderer draws the
                           Catmull-Clark surface of the same cage (for comparison)
    /Bidegree/Result       Mesh: the bidegree surface, subdivisionScheme = none, normals,
                           primvars:st (when the cage has UVs), primvars:distance (optional,
                           with a matching primvars:displayColor ramp for viewing),
                           extent and the custom attributes bidegree:degree, bidegree:levels,
                           bidegree:output, bidegree:boundary, bidegree:version
    /Bidegree/<Name>       optional extra meshes (``extra_meshes``; ``bidegree.compare`` writes the
                           OpenSubdiv surface as /Bidegree/OpenSubdiv)

Conventions:

- Points are written as ``point3f[]`` (float32), whatever the input precision.
- Point order: the points of the result (and of the extra meshes) are written in the order of
  their first use in ``faceVertexIndices`` (points no face uses last), so point ``p`` of the
  file is in general *not* ``result.points[p]``; the faces keep the result's order, so every
  face-varying value and per-face datum (UVs, limit normals, ``GeomSubset`` face indices) is
  unchanged, and the per-vertex ones (``vertex`` normals, ``primvars:distance``,
  ``primvars:displayColor``) follow the points.  The file describes the same surface; the order
  only makes ``faceVertexIndices`` local, which the crate's integer compression needs (in the
  subdivision's level order a 1M-face ``.usdc`` write takes 2.4 to 5 times as long and its
  ``faceVertexIndices`` take 10 MB instead of 0.15 MB).  ``point_order="result"`` keeps the
  result's numbering, for callers that index the file's points by it (e.g. to add time samples
  of ``Plan.evaluate`` to the points later).  The cage is always written in its own order (its
  creases and corners refer to it).
- Winding is counter-clockwise (``orientation = rightHanded``), as in OBJ and in bidegree.
- Normals of the result are its limit normals when it has them (``Result.normals``, from
  ``normals=True``): ``vertex`` interpolation, one per point, when every point's corners have the
  same normal as written (float32, bit for bit: a smooth surface, boundaries included; a quarter
  of the data), else ``faceVarying``, one per face corner, split at creases. Otherwise
  *area-weighted vertex normals* (``vertex`` interpolation): each face contributes its vector
  area (Newell's formula, exact for planar faces) to each of its vertices and the sums are
  normalised.  A vertex whose sum vanishes gets a zero normal.
- UVs are face-varying ``primvars:st`` (``texCoord2f[]``), on both the cage and the result;
  further UV sets (``uv_sets``) are primvars of their own names.  The cage's are indexed
  primvars whose indices are the face-varying topology bidegree used (``Mesh.uv_indices``, or
  one index per distinct value at each vertex), which OpenSubdiv takes as the topology; the
  result's ``st`` is indexed too when the result has the indexed form (``Result.uv_values`` and
  ``uv_indices``: one value per vertex of the subdivided face-varying mesh), else it has one
  value per face corner, as the further sets do.  The cage's
  ``faceVaryingLinearInterpolation`` is the result's ``uv_mode`` (OpenSubdiv's names:
  :data:`UV_MODE_TO_USD`; ``all``, linear, for a result without one), so a renderer subdividing
  the cage gets the same UV layout.
- Crease and corner sharpness use the OpenSubdiv convention, shared with bidegree: a sharpness of
  10 or more is infinitely sharp.  Infinite values (``inf``) are written as 10.0, finite values as
  given.  Each crease is one ``creaseLengths`` entry of length 2.
- Boundary mode ``edge-only`` is written as ``interpolateBoundary = edgeOnly``,
  ``edge-and-corner`` as ``edgeAndCorner`` and ``none`` as ``none``; the cage's hole faces
  (``Mesh.holes``) as ``holeIndices``.

Writing is atomic: the stage is built in memory, exported to a temporary file in the target
directory (same extension, so the same file format) and moved over the target with
:func:`os.replace`; a failure removes the temporary file and leaves any existing target untouched.
The format follows the extension: ``.usda`` (text), ``.usdc`` (crate) or ``.usd`` (crate).
All array data goes through ``Vt.*Array.FromNumpy``; there is no Python loop over points or faces.
"""

from __future__ import annotations

import os
import tempfile
from collections.abc import Mapping
from typing import Any

import numpy as np

from ._errors import BidegreeIOError, InvalidInputError

__all__ = [
    "BOUNDARY_TO_USD",
    "POINT_ORDERS",
    "SUPPORTED_EXTENSIONS",
    "UV_MODE_TO_USD",
    "distance_colors",
    "export",
    "validate",
    "vertex_normals",
]

#: bidegree boundary mode -> UsdGeom ``interpolateBoundary`` token
BOUNDARY_TO_USD: dict[str, str] = {
    "edge-only": "edgeOnly",
    "edge-and-corner": "edgeAndCorner",
    "none": "none",
}

#: bidegree face-varying mode (``uv_mode``) -> UsdGeom ``faceVaryingLinearInterpolation`` token
UV_MODE_TO_USD: dict[str, str] = {
    "none": "none",
    "corners-only": "cornersOnly",
    "corners-plus1": "cornersPlus1",
    "corners-plus2": "cornersPlus2",
    "boundaries": "boundaries",
    "all": "all",
}

#: File extensions :func:`export` accepts.
SUPPORTED_EXTENSIONS: tuple[str, ...] = (".usda", ".usdc", ".usd")

#: Point orders of :func:`export` (``point_order``): first use in the faces, or the result's.
POINT_ORDERS: tuple[str, ...] = ("first-use", "result")

#: Sharpness at or above which OpenSubdiv and bidegree treat a crease or corner as infinitely sharp.
INFINITELY_SHARP = 10.0

_UP_AXES = ("Y", "Z")


def _pxr() -> Any:
    """Import usd-core lazily so that ``import bidegree`` does not require it."""
    try:
        from pxr import Gf, Kind, Sdf, Usd, UsdGeom, Vt  # noqa: F401
    except ImportError as exc:  # pragma: no cover - depends on the environment
        raise BidegreeIOError("USD export needs usd-core: pip install usd-core") from exc
    import pxr

    return pxr


class _Topology:
    """Validated polygon-mesh arrays (points, face sizes, face indices) of a cage or result."""

    def __init__(self, what: str, points: Any, face_sizes: Any, face_indices: Any) -> None:
        pts = np.asarray(points)
        if pts.ndim != 2 or pts.shape[1] != 3:
            raise InvalidInputError(f"{what}: points must have shape (N, 3), got {pts.shape}")
        if not np.issubdtype(pts.dtype, np.number):
            raise InvalidInputError(f"{what}: points must be numeric, got dtype {pts.dtype}")
        if pts.shape[0] == 0:
            raise InvalidInputError(f"{what}: no points")
        if not np.all(np.isfinite(pts)):
            raise InvalidInputError(f"{what}: points contain NaN or infinite values")
        largest = float(np.abs(pts).max())
        if largest > np.finfo(np.float32).max:
            raise InvalidInputError(
                f"{what}: points reach {largest:.3g}, beyond float32 (USD writes point3f)"
            )
        sizes = np.asarray(face_sizes)
        indices = np.asarray(face_indices)
        if sizes.ndim != 1 or indices.ndim != 1:
            raise InvalidInputError(f"{what}: face_sizes and face_indices must be 1-D arrays")
        if sizes.size == 0:
            raise InvalidInputError(f"{what}: no faces")
        if not (
            np.issubdtype(sizes.dtype, np.integer) and np.issubdtype(indices.dtype, np.integer)
        ):
            raise InvalidInputError(f"{what}: face_sizes and face_indices must be integer arrays")
        if sizes.min() < 3:
            raise InvalidInputError(f"{what}: every face needs at least 3 vertices")
        total = int(sizes.sum(dtype=np.int64))
        if total != indices.size:
            raise InvalidInputError(
                f"{what}: face_sizes sum to {total} but face_indices has {indices.size} entries"
            )
        if indices.min() < 0 or indices.max() >= pts.shape[0]:
            raise InvalidInputError(
                f"{what}: face_indices out of range [0, {pts.shape[0]}): "
                f"min {int(indices.min())}, max {int(indices.max())}"
            )
        if pts.shape[0] > np.iinfo(np.int32).max or total > np.iinfo(np.int32).max:
            raise InvalidInputError(f"{what}: too large for 32-bit USD index arrays")
        self.what = what
        self.points = pts
        self.face_sizes = sizes.astype(np.int32, copy=False)
        self.face_indices = indices.astype(np.int32, copy=False)

    @property
    def num_points(self) -> int:
        return int(self.points.shape[0])

    @property
    def num_corners(self) -> int:
        return int(self.face_indices.size)


class _PointOrder:
    """The order in which a polygon mesh's points are written: point ``p`` of the file is input
    point ``order[p]`` (``None``: the input's order).  Per-vertex arrays go through
    :meth:`vertex`; :attr:`face_indices` are the faces in the file's point numbers."""

    def __init__(self, topo: _Topology, first_use: bool) -> None:
        """``first_use``: points in the order of their first use in the faces (local indices
        for the crate's delta-coded integers), the unused ones last in their own order;
        O(corners) with numpy.  Else the input's order."""
        self.order: np.ndarray | None = None
        self.face_indices = topo.face_indices
        if not first_use:
            return
        corners = topo.num_corners
        first = np.full(topo.num_points, corners, dtype=np.int64)
        np.minimum.at(first, topo.face_indices, np.arange(corners, dtype=np.int64))
        used = first < corners
        is_first = np.zeros(corners, dtype=bool)
        is_first[first[used]] = True
        order = np.concatenate([topo.face_indices[is_first], np.flatnonzero(~used)])
        new_number = np.empty(topo.num_points, dtype=np.int32)
        new_number[order] = np.arange(topo.num_points, dtype=np.int32)
        self.order = order
        self.face_indices = new_number.take(topo.face_indices)

    def vertex(self, values: np.ndarray) -> np.ndarray:
        """Per-vertex ``values`` (one row per input point) in the file's point order."""
        return values if self.order is None else values.take(self.order, axis=0)


def vertex_normals(
    points: np.ndarray, face_sizes: np.ndarray, face_indices: np.ndarray
) -> np.ndarray:
    """Area-weighted vertex normals (float32, unit length or zero) of a polygon mesh.

    Each face's vector area (Newell's formula around the face's first vertex) is added to each of
    its vertices; the sums are normalised.  Vectorised with numpy; O(corners).
    """
    pts = np.asarray(points, dtype=np.float64)
    sizes = np.asarray(face_sizes, dtype=np.int64)
    idx = np.asarray(face_indices, dtype=np.int64)
    n = pts.shape[0]
    starts = np.zeros(sizes.size, dtype=np.int64)
    np.cumsum(sizes[:-1], out=starts[1:])
    nxt = np.arange(1, idx.size + 1, dtype=np.int64)
    nxt[starts + sizes - 1] = starts  # last corner of a face -> its first corner
    next_idx = idx.take(nxt)
    first = idx.take(starts)
    # Column-wise (structure of arrays): 1-D takes are much faster than (N, 3) row gathers.
    a, b = [], []
    for k in range(3):
        col = np.ascontiguousarray(pts[:, k])
        origin = np.repeat(col.take(first), sizes)
        a.append(col.take(idx) - origin)
        b.append(col.take(next_idx) - origin)
    cross = (
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    )
    acc = np.empty((n, 3), dtype=np.float64)
    for k in range(3):
        face_area2 = np.add.reduceat(cross[k], starts)  # 2 * vector area of each face
        acc[:, k] = np.bincount(idx, weights=np.repeat(face_area2, sizes), minlength=n)
    length = np.linalg.norm(acc, axis=1)
    ok = length > 0
    acc[ok] /= length[ok, None]
    acc[~ok] = 0.0
    return acc.astype(np.float32)


#: Colour ramp of :func:`distance_colors` (dark blue -> purple -> orange -> light yellow).
_RAMP = np.array(
    [
        [0.05, 0.03, 0.25],
        [0.45, 0.10, 0.50],
        [0.85, 0.30, 0.25],
        [0.99, 0.65, 0.05],
        [1.0, 1.0, 0.6],
    ]
)


def distance_colors(distances: np.ndarray) -> np.ndarray:
    """(N, 3) float32 display colours for per-vertex distances: 0 -> dark blue, the largest
    distance -> light yellow (piecewise-linear ramp; all dark blue when every distance is 0)."""
    d = np.asarray(distances, dtype=np.float64)
    top = float(d.max()) if d.size else 0.0
    t = d / top if top > 0 else np.zeros_like(d)
    x = np.clip(t, 0.0, 1.0) * (len(_RAMP) - 1)
    i = np.minimum(x.astype(np.int64), len(_RAMP) - 2)
    f = (x - i)[:, None]
    return ((1.0 - f) * _RAMP[i] + f * _RAMP[i + 1]).astype(np.float32)


def _sharpness(values: np.ndarray) -> np.ndarray:
    """Sharpness values for USD: finite values unchanged, +inf -> 10 (infinitely sharp)."""
    out = np.asarray(values, dtype=np.float32).copy()
    out[np.isposinf(out)] = INFINITELY_SHARP
    return out


def _pair(value: Any, what: str) -> tuple[np.ndarray, np.ndarray] | None:
    """Normalise an optional ``(indices, sharpness)`` pair; None or empty -> None."""
    if value is None:
        return None
    try:
        first, second = value
    except (TypeError, ValueError) as exc:
        raise InvalidInputError(f"cage {what} must be a pair (indices, sharpness)") from exc
    a = np.asarray(first)
    s = np.asarray(second)
    if a.size == 0 and s.size == 0:
        return None
    return a, s


def _face_varying(
    value: Any, num_corners: int, what: str, name: str = "uvs", width: int = 2
) -> np.ndarray | None:
    if value is None:
        return None
    uv = np.asarray(value)
    if uv.ndim != 2 or uv.shape[1] != width:
        raise InvalidInputError(
            f"{what}: {name} must have shape (corners, {width}), got {uv.shape}"
        )
    if uv.shape[0] != num_corners:
        raise InvalidInputError(
            f"{what}: {uv.shape[0]} {name} but the mesh has {num_corners} face corners "
            f"({name} are face-varying: one per face corner)"
        )
    if not np.all(np.isfinite(uv)):
        raise InvalidInputError(f"{what}: {name} contain NaN or infinite values")
    return uv


def _result_uvs(result: Any, num_corners: int) -> tuple[np.ndarray, np.ndarray | None] | None:
    """A result's uvs as ``(values, indices)``: its indexed form (``Result.uv_values``,
    ``Result.uv_indices``: one value per face-varying vertex) when it has one, checked, else
    its per-corner ``uvs`` (indices ``None``)."""
    values = getattr(result, "uv_values", None)
    indices = getattr(result, "uv_indices", None)
    if values is None or indices is None:
        per_corner = _face_varying(getattr(result, "uvs", None), num_corners, "result")
        return None if per_corner is None else (per_corner, None)
    values, indices = np.asarray(values), np.asarray(indices)
    if values.ndim != 2 or values.shape[1] != 2:
        raise InvalidInputError(f"result: uv_values must have shape (N, 2), got {values.shape}")
    if indices.shape != (num_corners,) or not np.issubdtype(indices.dtype, np.integer):
        raise InvalidInputError(
            f"result: uv_indices must be {num_corners} integers (one per face corner), "
            f"got {indices.dtype} {indices.shape}"
        )
    if indices.size and (indices.min() < 0 or indices.max() >= len(values)):
        raise InvalidInputError("result: a uv index is out of range")
    if not np.all(np.isfinite(values)):
        raise InvalidInputError("result: uv_values contain NaN or infinite values")
    return values, indices


def _indexed(
    per_corner: np.ndarray, indices: np.ndarray | None, topo: _Topology
) -> tuple[np.ndarray, np.ndarray]:
    """A cage's face-varying values as an indexed primvar whose indices are the face-varying
    topology bidegree subdivided: the given ``indices`` (``Mesh.uv_indices``) with the values
    they index, or else one index per distinct value at each vertex (the weld by value), so
    that a reader refining the cage (OpenSubdiv takes the indices as the topology) gets the
    same seams."""
    if indices is not None:
        indices = np.asarray(indices, dtype=np.int64)
        values = np.zeros((int(indices.max()) + 1 if len(indices) else 0, per_corner.shape[1]))
        values[indices] = per_corner
        return values, indices
    keys = np.column_stack([topo.face_indices.astype(np.float64), per_corner])
    first, inverse = np.unique(keys, axis=0, return_index=True, return_inverse=True)[1:]
    return per_corner[first], inverse.reshape(-1)


def _vec3f(pxr: Any, a: np.ndarray) -> Any:
    return pxr.Vt.Vec3fArray.FromNumpy(np.ascontiguousarray(a, dtype=np.float32))


def _vec2f(pxr: Any, a: np.ndarray) -> Any:
    return pxr.Vt.Vec2fArray.FromNumpy(np.ascontiguousarray(a, dtype=np.float32))


def _ints(pxr: Any, a: np.ndarray) -> Any:
    return pxr.Vt.IntArray.FromNumpy(np.ascontiguousarray(a, dtype=np.int32))


def _floats(pxr: Any, a: np.ndarray) -> Any:
    return pxr.Vt.FloatArray.FromNumpy(np.ascontiguousarray(a, dtype=np.float32))


def _extent(pxr: Any, points: np.ndarray) -> Any:
    return _vec3f(pxr, np.stack([points.min(axis=0), points.max(axis=0)]))


def _per_point(
    per_corner: np.ndarray, face_indices: np.ndarray, num_points: int
) -> np.ndarray | None:
    """``per_corner`` values as float32, one per point, when every point's corners have the
    same ones bit for bit (points no face uses get zeros), else ``None``."""
    values = np.asarray(per_corner, dtype=np.float32)
    out = np.zeros((num_points, values.shape[1]), dtype=np.float32)
    out[face_indices] = values
    return out if np.array_equal(out[face_indices], values) else None


def _define_polymesh(
    pxr: Any,
    stage: Any,
    path: str,
    topo: _Topology,
    *,
    normals: bool | np.ndarray,
    uvs: tuple[np.ndarray, np.ndarray | None] | None = None,
    distances: np.ndarray | None = None,
    point_order: str = "first-use",
) -> Any:
    """Define a plain polygon mesh (subdivisionScheme = none) at ``path``, its points in
    ``point_order`` (:data:`POINT_ORDERS`). ``normals``: an array (corners, 3) is written per
    point where every point's corners agree, else face-varying (limit normals); ``True``
    computes vertex normals. ``uvs``: ``(values, indices)``, an indexed ``primvars:st``, or
    ``(per-corner values, None)``."""
    UsdGeom, Sdf = pxr.UsdGeom, pxr.Sdf
    order = _PointOrder(topo, point_order == "first-use")
    points = order.vertex(topo.points)
    mesh = UsdGeom.Mesh.Define(stage, path)
    mesh.CreateSubdivisionSchemeAttr(UsdGeom.Tokens.none)
    mesh.CreateOrientationAttr(UsdGeom.Tokens.rightHanded)
    mesh.CreatePointsAttr(_vec3f(pxr, points))
    mesh.CreateFaceVertexCountsAttr(_ints(pxr, topo.face_sizes))
    mesh.CreateFaceVertexIndicesAttr(_ints(pxr, order.face_indices))
    mesh.CreateExtentAttr(_extent(pxr, points))
    if isinstance(normals, np.ndarray):
        at_points = _per_point(normals, order.face_indices, len(points))
        if at_points is None:
            mesh.CreateNormalsAttr(_vec3f(pxr, normals))
            mesh.SetNormalsInterpolation(UsdGeom.Tokens.faceVarying)
        else:
            mesh.CreateNormalsAttr(_vec3f(pxr, at_points))
            mesh.SetNormalsInterpolation(UsdGeom.Tokens.vertex)
    elif normals:
        mesh.CreateNormalsAttr(
            _vec3f(pxr, vertex_normals(points, topo.face_sizes, order.face_indices))
        )
        mesh.SetNormalsInterpolation(UsdGeom.Tokens.vertex)
    primvars = UsdGeom.PrimvarsAPI(mesh.GetPrim())
    if uvs is not None:
        st = primvars.CreatePrimvar(
            "st", Sdf.ValueTypeNames.TexCoord2fArray, UsdGeom.Tokens.faceVarying
        )
        values, indices = uvs
        st.Set(_vec2f(pxr, values))
        if indices is not None:
            st.SetIndices(_ints(pxr, indices))
    if distances is not None:
        per_point = order.vertex(distances)
        dist = primvars.CreatePrimvar(
            "distance", Sdf.ValueTypeNames.FloatArray, UsdGeom.Tokens.vertex
        )
        dist.Set(_floats(pxr, per_point))
        color = primvars.CreatePrimvar(
            "displayColor", Sdf.ValueTypeNames.Color3fArray, UsdGeom.Tokens.vertex
        )
        color.Set(_vec3f(pxr, distance_colors(per_point)))
    return mesh


def _check_distances(distances: Any, num_points: int, what: str) -> np.ndarray | None:
    if distances is None:
        return None
    d = np.asarray(distances)
    if d.ndim != 1 or d.shape[0] != num_points:
        raise InvalidInputError(
            f"{what}: distances must have shape ({num_points},) (one per vertex), got {d.shape}"
        )
    if not np.issubdtype(d.dtype, np.number) or not np.all(np.isfinite(d)):
        raise InvalidInputError(f"{what}: distances must be finite numbers")
    return d


def _version() -> str:
    import bidegree

    version = getattr(bidegree, "__version__", None)
    if version:
        return str(version)
    try:
        from importlib.metadata import version as dist_version

        return dist_version("bidegree")
    except Exception:  # metadata missing in a source checkout
        return "unknown"


def _build_stage(
    cage: Any,
    result: Any,
    *,
    up_axis: str,
    meters_per_unit: float,
    distances: Any,
    extra_meshes: Mapping[str, tuple[Any, Any]] | None,
    uv_sets: Mapping[str, tuple[Any, Any]] | None = None,
    point_order: str = "first-use",
) -> Any:
    pxr = _pxr()
    Usd, UsdGeom, Sdf, Kind = pxr.Usd, pxr.UsdGeom, pxr.Sdf, pxr.Kind

    # ---- validate everything before building anything
    if up_axis not in _UP_AXES:
        raise InvalidInputError(f"up_axis must be 'Y' or 'Z', got {up_axis!r}")
    mpu = float(meters_per_unit)
    if not (np.isfinite(mpu) and mpu > 0):
        raise InvalidInputError(
            f"meters_per_unit must be a positive number, got {meters_per_unit!r}"
        )
    if point_order not in POINT_ORDERS:
        raise InvalidInputError(
            f"unknown point_order {point_order!r}; expected one of {list(POINT_ORDERS)}"
        )

    cage_topo = _Topology("cage", cage.points, cage.face_sizes, cage.face_indices)
    res_topo = _Topology("result", result.points, result.face_sizes, result.face_indices)
    cage_uvs = _face_varying(getattr(cage, "uvs", None), cage_topo.num_corners, "cage")
    res_uvs = _result_uvs(result, res_topo.num_corners)
    res_normals = _face_varying(
        getattr(result, "normals", None), res_topo.num_corners, "result", "normals", 3
    )
    dist = _check_distances(distances, res_topo.num_points, "result")
    uv_mode = str(getattr(result, "uv_mode", None) or "all")
    if uv_mode not in UV_MODE_TO_USD:
        raise InvalidInputError(
            f"unknown uv_mode {uv_mode!r}; expected one of {sorted(UV_MODE_TO_USD)}"
        )
    more_uvs: list[tuple[str, np.ndarray, np.ndarray]] = []
    for name, (cage_set, result_set) in (uv_sets or {}).items():
        if not Sdf.Path.IsValidIdentifier(name) or name in ("st", "normals", "displayColor"):
            raise InvalidInputError(f"invalid UV set name {name!r}")
        cage_values = _face_varying(cage_set, cage_topo.num_corners, "cage", name)
        result_values = _face_varying(result_set, res_topo.num_corners, "result", name)
        more_uvs.append((name, cage_values, result_values))

    boundary = str(getattr(cage, "boundary", None) or getattr(result, "boundary", "edge-only"))
    result_boundary = getattr(result, "boundary", None)
    if result_boundary is not None and str(result_boundary) != boundary:
        raise InvalidInputError(
            f"the cage's boundary mode {boundary!r} differs from the result's "
            f"{result_boundary!r}: is the result from another cage?"
        )
    if boundary not in BOUNDARY_TO_USD:
        raise InvalidInputError(
            f"unknown boundary mode {boundary!r}; expected one of {sorted(BOUNDARY_TO_USD)}"
        )

    creases = _pair(getattr(cage, "creases", None), "creases")
    if creases is not None:
        edges, sharp = creases
        edges = edges.reshape(-1, 2) if edges.ndim == 1 and edges.size % 2 == 0 else edges
        if edges.ndim != 2 or edges.shape[1] != 2 or sharp.shape != (edges.shape[0],):
            raise InvalidInputError(
                "cage creases must be ((K, 2) vertex pairs, (K,) sharpness), "
                f"got {edges.shape} and {sharp.shape}"
            )
        if edges.size and (edges.min() < 0 or edges.max() >= cage_topo.num_points):
            raise InvalidInputError("cage crease vertex index out of range")
        creases = (edges, sharp)
    corners = _pair(getattr(cage, "corners", None), "corners")
    if corners is not None:
        cverts, csharp = corners
        if cverts.ndim != 1 or csharp.shape != cverts.shape:
            raise InvalidInputError(
                "cage corners must be ((K,) vertices, (K,) sharpness), "
                f"got {cverts.shape} and {csharp.shape}"
            )
        if cverts.size and (cverts.min() < 0 or cverts.max() >= cage_topo.num_points):
            raise InvalidInputError("cage corner vertex index out of range")

    extras: list[tuple[str, _Topology, np.ndarray | None]] = []
    for name, (mesh_like, extra_dist) in (extra_meshes or {}).items():
        if not Sdf.Path.IsValidIdentifier(name) or name in ("Cage", "Result"):
            raise InvalidInputError(f"invalid extra mesh name {name!r}")
        topo = _Topology(name, mesh_like.points, mesh_like.face_sizes, mesh_like.face_indices)
        extras.append((name, topo, _check_distances(extra_dist, topo.num_points, name)))

    # ---- build the stage in memory
    stage = Usd.Stage.CreateInMemory("bidegree.usda")
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.y if up_axis == "Y" else UsdGeom.Tokens.z)
    UsdGeom.SetStageMetersPerUnit(stage, mpu)
    root = UsdGeom.Xform.Define(stage, "/Bidegree")
    stage.SetDefaultPrim(root.GetPrim())
    Usd.ModelAPI(root.GetPrim()).SetKind(Kind.Tokens.component)

    # cage: Catmull-Clark subdivision surface of the same control mesh
    cmesh = UsdGeom.Mesh.Define(stage, "/Bidegree/Cage")
    cmesh.CreateSubdivisionSchemeAttr(UsdGeom.Tokens.catmullClark)
    cmesh.CreateOrientationAttr(UsdGeom.Tokens.rightHanded)
    cmesh.CreateInterpolateBoundaryAttr(BOUNDARY_TO_USD[boundary])
    cmesh.CreateFaceVaryingLinearInterpolationAttr(UV_MODE_TO_USD[uv_mode])
    cmesh.CreatePointsAttr(_vec3f(pxr, cage_topo.points))
    cmesh.CreateFaceVertexCountsAttr(_ints(pxr, cage_topo.face_sizes))
    cmesh.CreateFaceVertexIndicesAttr(_ints(pxr, cage_topo.face_indices))
    # The Catmull-Clark limit surface lies in the convex hull of the control points.
    cmesh.CreateExtentAttr(_extent(pxr, cage_topo.points))
    holes = np.asarray(getattr(cage, "holes", ()), dtype=np.int64)
    if holes.size:
        cmesh.CreateHoleIndicesAttr(_ints(pxr, holes))
    if creases is not None:
        edges, sharp = creases
        cmesh.CreateCreaseIndicesAttr(_ints(pxr, edges.reshape(-1)))
        cmesh.CreateCreaseLengthsAttr(_ints(pxr, np.full(edges.shape[0], 2, dtype=np.int32)))
        cmesh.CreateCreaseSharpnessesAttr(_floats(pxr, _sharpness(sharp)))
    if corners is not None:
        cverts, csharp = corners
        cmesh.CreateCornerIndicesAttr(_ints(pxr, cverts))
        cmesh.CreateCornerSharpnessesAttr(_floats(pxr, _sharpness(csharp)))
    if cage_uvs is not None:
        st = UsdGeom.PrimvarsAPI(cmesh.GetPrim()).CreatePrimvar(
            "st", Sdf.ValueTypeNames.TexCoord2fArray, UsdGeom.Tokens.faceVarying
        )
        values, indices = _indexed(cage_uvs, getattr(cage, "uv_indices", None), cage_topo)
        st.Set(_vec2f(pxr, values))
        st.SetIndices(_ints(pxr, indices))

    # result: the bidegree surface as a plain polygon mesh
    rmesh = _define_polymesh(
        pxr,
        stage,
        "/Bidegree/Result",
        res_topo,
        normals=res_normals if res_normals is not None else True,
        uvs=res_uvs,
        distances=dist,
        point_order=point_order,
    )
    prim = rmesh.GetPrim()
    for name, type_name, value in (
        ("bidegree:degree", Sdf.ValueTypeNames.Int, int(result.degree)),
        ("bidegree:levels", Sdf.ValueTypeNames.Int, int(result.levels)),
        ("bidegree:output", Sdf.ValueTypeNames.Token, str(result.output)),
        ("bidegree:boundary", Sdf.ValueTypeNames.Token, boundary),
        ("bidegree:version", Sdf.ValueTypeNames.String, _version()),
    ):
        prim.CreateAttribute(name, type_name, custom=True).Set(value)

    for name, cage_values, result_values in more_uvs:
        for mesh, values in ((cmesh, cage_values), (rmesh, result_values)):
            primvar = UsdGeom.PrimvarsAPI(mesh.GetPrim()).CreatePrimvar(
                name, Sdf.ValueTypeNames.TexCoord2fArray, UsdGeom.Tokens.faceVarying
            )
            if mesh is cmesh:
                values, indices = _indexed(values, None, cage_topo)
                primvar.SetIndices(_ints(pxr, indices))
            primvar.Set(_vec2f(pxr, values))

    for name, topo, extra_dist in extras:
        _define_polymesh(
            pxr,
            stage,
            f"/Bidegree/{name}",
            topo,
            normals=True,
            distances=extra_dist,
            point_order=point_order,
        )
    return stage


def _file_mode(target: str) -> int:
    """Mode for the new file: the existing target's mode, else 0o666 minus the umask."""
    try:
        return os.stat(target).st_mode & 0o7777
    except OSError:
        umask = os.umask(0)
        os.umask(umask)
        return 0o666 & ~umask


def export(
    path: str | os.PathLike[str],
    cage: Any,
    result: Any,
    *,
    up_axis: str = "Y",
    meters_per_unit: float = 1.0,
    distances: Any = None,
    extra_meshes: Mapping[str, tuple[Any, Any]] | None = None,
    uv_sets: Mapping[str, tuple[Any, Any]] | None = None,
    point_order: str = "first-use",
) -> None:
    """Write ``cage`` and its subdivided ``result`` to a USD file (see the module docstring).

    Args:
        path: target file; ``.usda`` writes text, ``.usdc`` or ``.usd`` writes crate.  The
            directory must exist.
        cage: a :class:`bidegree.Mesh` (points, face_sizes, face_indices, creases, corners, uvs,
            boundary).
        result: a :class:`bidegree.Result` (points, face_sizes, face_indices, uvs, degree,
            levels, output, boundary).
        up_axis: ``"Y"`` or ``"Z"`` (stage ``upAxis``).
        meters_per_unit: stage ``metersPerUnit`` (> 0).
        distances: optional per-result-vertex values, written as ``primvars:distance``
            (``vertex`` interpolation) on ``/Bidegree/Result``, together with a
            ``primvars:displayColor`` ramp of them (:func:`distance_colors`) for viewers.
        extra_meshes: optional ``{name: (mesh, distances_or_None)}``; each mesh (anything with
            points, face_sizes, face_indices) is written as a plain polygon mesh
            ``/Bidegree/<name>``.
        uv_sets: optional further UV sets ``{name: (cage (corners, 2), result (output
            corners, 2))}`` (e.g. ``Plan.evaluate_face_varying`` of a dict), each written as a
            face-varying ``texCoord2f[]`` primvar ``name`` on the cage and the result (``st`` is
            the cage's own ``uvs``). They share the cage's ``faceVaryingLinearInterpolation``
            (USD has one per mesh): subdivide them in the result's ``uv_mode``.
        point_order: order of the points of the result and the extra meshes in the file:
            ``"first-use"`` (default), the order of their first use in the faces, so that point
            ``p`` of the file is in general not ``result.points[p]`` (the faces, and so every
            face-varying or per-face value, keep the result's order); ``"result"``, the
            result's own numbering (point ``p`` is ``result.points[p]``), for a caller that
            indexes the file's points by it, at the cost of a larger ``.usdc`` that takes 2.4
            to 5 times as long to write at 1M faces (see the module docstring).

    Raises:
        bidegree.InvalidInputError: mismatched or malformed arrays, bad options, unsupported
            extension.
        bidegree.BidegreeIOError: missing directory, unwritable path, USD write failure.  No
            partial file is left behind in either case.
    """
    target = os.path.abspath(os.fspath(path))
    directory, filename = os.path.split(target)
    stem, ext = os.path.splitext(filename)
    if ext.lower() not in SUPPORTED_EXTENSIONS:
        raise InvalidInputError(
            f"{path}: unsupported USD extension {ext!r}; "
            f"use one of {', '.join(SUPPORTED_EXTENSIONS)}"
        )
    if not os.path.isdir(directory):
        raise BidegreeIOError(f"{path}: directory {directory} does not exist")
    if os.path.isdir(target):
        raise BidegreeIOError(f"{path}: is a directory")

    stage = _build_stage(
        cage,
        result,
        up_axis=up_axis,
        meters_per_unit=meters_per_unit,
        distances=distances,
        extra_meshes=extra_meshes,
        uv_sets=uv_sets,
        point_order=point_order,
    )

    try:
        fd, tmp = tempfile.mkstemp(prefix=f".{stem}.", suffix=f".tmp{ext}", dir=directory)
    except OSError as exc:
        raise BidegreeIOError(
            f"{path}: cannot write to {directory}: {exc.strerror or exc}"
        ) from exc
    os.close(fd)
    try:
        try:
            ok = stage.GetRootLayer().Export(tmp)
        except Exception as exc:  # pxr raises Tf.ErrorException
            raise BidegreeIOError(f"{path}: USD export failed: {exc}") from exc
        if not ok:
            raise BidegreeIOError(f"{path}: USD export failed")
        try:
            os.chmod(tmp, _file_mode(target))
            os.replace(tmp, target)
        except OSError as exc:
            raise BidegreeIOError(f"{path}: cannot write: {exc.strerror or exc}") from exc
    except BaseException:
        try:
            os.unlink(tmp)
        except FileNotFoundError:
            pass
        raise

    # A layer for this path that is already open in this process would otherwise keep serving
    # the old content to Usd.Stage.Open / Sdf.Layer.FindOrOpen.
    pxr = _pxr()
    layer = pxr.Sdf.Layer.Find(target)
    if layer is not None:
        layer.Reload(force=True)


def validate(path: str | os.PathLike[str]) -> list[str]:
    """Validate a USD file with usd-core's validators; return the error messages (empty = valid).

    Uses ``UsdValidation`` with every registered validator (what ``usdchecker`` runs in recent
    usd-core) and, on usd-core releases that still ship it, ``UsdUtils.ComplianceChecker``.
    Warnings are not returned.
    """
    import importlib

    pxr = _pxr()
    file = os.fspath(path)
    errors: list[str] = []
    try:
        validation = importlib.import_module("pxr.UsdValidation")
    except ImportError:  # pragma: no cover - usd-core before 25.x
        validation = None
    if validation is not None:
        stage = pxr.Usd.Stage.Open(file)
        registry = validation.ValidationRegistry()
        context = validation.ValidationContext(registry.GetOrLoadAllValidators())
        for err in context.Validate(stage):
            if err.GetType() == validation.ValidationErrorType.Error:
                errors.append(f"{err.GetName()}: {err.GetMessage()}")
    usd_utils = importlib.import_module("pxr.UsdUtils")
    checker_cls = getattr(usd_utils, "ComplianceChecker", None)
    if checker_cls is not None:  # pragma: no cover - removed from recent usd-core
        checker = checker_cls()
        checker.CheckCompliance(file)
        errors.extend(checker.GetErrors())
        errors.extend(checker.GetFailedChecks())
    return errors
