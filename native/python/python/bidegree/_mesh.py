"""The cage, :class:`Mesh` (points, faces, creases, corners, UVs, boundary rule, creasing
method), its OBJ reading and writing.
"""

from __future__ import annotations

import itertools
import os
from collections.abc import Sequence
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from . import _convert as convert
from . import _native
from ._convert import Boundary, Creasing, FloatArray
from ._errors import FaceTooSmallError, InvalidInputError, NonFiniteError, ObjWarning

#: Largest OBJ file :meth:`Mesh.from_obj` reads unless told otherwise (2 GiB).
DEFAULT_MAX_INPUT_BYTES: int = _native.DEFAULT_MAX_INPUT_BYTES


class Mesh:
    """A subdivision cage: points, polygonal faces, and optional creases, corners, face-varying
    UVs, holes, boundary rule and creasing method. Construction checks shapes, face sizes,
    indices, faces of fewer than 3 distinct vertices and finite UVs; that creases are edges is
    checked when a :class:`Plan` is built, finite points by :func:`subdivide`. Any polygon soup
    is a cage, as in OpenSubdiv: non-manifold edges (any number of faces), faces whose
    orientations disagree, non-manifold (bowtie) vertices, faces repeating a vertex and
    zero-area faces are subdivided; non-manifold edges and vertices become infinitely sharp
    curves and corners, every face keeping its own side.

    Args:
        points: (V, 3) coordinates, float32 or float64 (other numbers become float64).
        faces: the faces as sequences of vertex indices (counter-clockwise), or an (F, k) integer
            array of faces of equal size. Alternatively give ``face_sizes`` and ``face_indices``.
        face_sizes: (F,) number of corners of each face.
        face_indices: (sum of face_sizes,) vertex of each face corner, faces one after the other.
        creases: ``(edges, sharpness)``: (K, 2) vertex pairs that are mesh edges and (K,)
            sharpness values (or one for all); ``>= 10`` or ``inf`` is infinitely sharp.
        corners: ``(vertices, sharpness)``: (K,) vertices and (K,) sharpness values (or one).
        uvs: (corners, 2) face-varying texture coordinates, one per face corner; the corners
            of one vertex with equal uvs share one face-varying value (a seam is where they
            differ). With ``uv_indices``: the (N, 2) texture coordinates they index.
        uv_indices: (corners,) one index into ``uvs`` per face corner (OpenSubdiv's
            face-varying index buffer, OBJ's ``vt`` indices, USD's ``primvars:st:indices``):
            the face-varying topology. Corners of one vertex with the same index share a value;
            different indices stay apart even where their coordinates are equal.
        holes: (H,) faces that are holes: refined (they shape their neighbours) but left out
            of the output, as OpenSubdiv's ``holeIndices``.
        boundary: ``"edge-only"`` (boundary edges are sharp), ``"edge-and-corner"`` (also
            boundary vertices of a single face are corners) or ``"none"`` (OpenSubdiv's
            ``VTX_BOUNDARY_NONE``: the faces at a boundary not creased infinitely are holes).
        creasing: ``"uniform"`` or ``"chaikin"``: how semi-sharp creases decrease from level to
            level with the classic rules (OpenSubdiv's creasing method, the ``t creasemethod``
            tag of its files); a :class:`Plan` uses it unless told otherwise.

    Raises:
        InvalidInputError: wrong shapes or types, bad sharpness, boundary or creasing values.
        EmptyMeshError, FaceTooSmallError, RepeatedVertexError, IndexOutOfRangeError: bad faces,
            creases or corners.
        NonFiniteError: a UV is NaN or infinite.
    """

    @convert.memory_errors()
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
        uv_indices: ArrayLike | None = None,
        holes: ArrayLike | None = None,
        boundary: Boundary = "edge-only",
        creasing: Creasing = "uniform",
    ) -> None:
        pts = convert.owned(convert.float_array(points, "points"), points)
        if pts.ndim != 2 or pts.shape[1] != 3:
            raise InvalidInputError(f"points must have shape (V, 3), not {pts.shape}")

        if faces is not None:
            if face_sizes is not None or face_indices is not None:
                raise InvalidInputError("give either faces or face_sizes + face_indices, not both")
            sizes, indices = self._faces_to_arrays(faces)
        else:
            if face_sizes is None or face_indices is None:
                raise InvalidInputError("give faces, or both face_sizes and face_indices")
            sizes = convert.owned(convert.int_array(face_sizes, "face_sizes"), face_sizes)
            indices = convert.owned(convert.int_array(face_indices, "face_indices"), face_indices)
            if sizes.ndim != 1 or indices.ndim != 1:
                raise InvalidInputError(
                    f"face_sizes and face_indices must be 1-D, not {sizes.shape} and "
                    f"{indices.shape}"
                )

        crease_pair: tuple[NDArray[np.int64], NDArray[np.float32]] | None = None
        if creases is not None:
            edges_in, sharp_in = convert.pair(creases, "creases")
            edges = convert.int_array(edges_in, "crease edges")
            if edges.size == 0:
                edges = edges.reshape(0, 2)
            if edges.ndim != 2 or edges.shape[1] != 2:
                raise InvalidInputError(f"crease edges must have shape (K, 2), not {edges.shape}")
            crease_pair = (
                convert.owned(edges, edges_in),
                convert.sharpness(sharp_in, len(edges), "crease"),
            )

        corner_pair: tuple[NDArray[np.int64], NDArray[np.float32]] | None = None
        if corners is not None:
            vertices_in, sharp_in = convert.pair(corners, "corners")
            vertices = convert.int_array(vertices_in, "corner vertices").reshape(-1)
            corner_pair = (
                convert.owned(vertices, vertices_in),
                convert.sharpness(sharp_in, len(vertices), "corner"),
            )

        uv_array: FloatArray | None = None
        if uvs is not None:
            uv_array = convert.owned(convert.float_array(uvs, "uvs"), uvs)
            if uv_array.ndim != 2 or uv_array.shape[1] != 2:
                raise InvalidInputError(
                    f"uvs must have shape (corners, 2) (face-varying), not {uv_array.shape}"
                )
        elif uv_indices is not None:
            raise InvalidInputError("uv_indices index uvs: give the uvs too")
        hole_array = None
        if holes is not None:
            hole_array = convert.owned(convert.int_array(holes, "holes"), holes).reshape(-1)
        self._finish(
            pts,
            sizes,
            indices,
            crease_pair,
            corner_pair,
            uv_array,
            boundary,
            creasing,
            holes=hole_array,
            uv_indices=uv_indices,
        )

    def _finish(
        self,
        pts: FloatArray,
        sizes: NDArray[np.int64],
        indices: NDArray[np.int64],
        crease_pair: tuple[NDArray[np.int64], NDArray[np.float32]] | None,
        corner_pair: tuple[NDArray[np.int64], NDArray[np.float32]] | None,
        uv_array: FloatArray | None,
        boundary: Boundary,
        creasing: Creasing,
        source: Any = None,
        holes: NDArray[np.int64] | None = None,
        uv_indices: ArrayLike | None = None,
    ) -> None:
        """Checks and builds the cage from converted arrays that are the mesh's own (the
        constructor's copies, or what :meth:`from_obj` read, with the file's ``source``
        lines for its errors)."""
        _check_face_sizes(sizes)
        uv_table: FloatArray | None = None
        uv_index: NDArray[np.uint32] | None = None
        if uv_array is not None and uv_indices is not None:
            uv_index = convert.face_varying_indices(
                uv_indices, len(indices), len(uv_array), "uv_indices"
            )
            uv_table, uv_array = uv_array, uv_array[uv_index]
        if uv_array is not None:
            if len(uv_array) != len(indices):
                raise InvalidInputError(
                    f"{len(uv_array)} uvs but the mesh has {len(indices)} face corners "
                    "(uvs are face-varying: one per face corner)"
                )
            bad = np.flatnonzero(~np.isfinite(uv_array).all(axis=1))
            if len(bad):
                error = NonFiniteError(
                    f"uvs: face corner {bad[0]} has a non-finite texture coordinate "
                    f"({len(bad)} such corners)"
                )
                error.corner = int(bad[0])
                raise error

        self._boundary: Boundary = convert.choice(boundary, convert.BOUNDARIES, "boundary")  # type: ignore[assignment]
        self._creasing: Creasing = convert.choice(creasing, convert.CREASING, "creasing")  # type: ignore[assignment]
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
            source,
            holes,
        )
        self._holes = convert.readonly(holes if holes is not None else empty_i)
        self._points = convert.readonly(pts)
        self._face_sizes = convert.readonly(sizes)
        self._face_indices = convert.readonly(indices)
        self._creases = (
            (convert.readonly(crease_pair[0]), convert.readonly(crease_pair[1]))
            if crease_pair
            else None
        )
        self._corners = (
            (convert.readonly(corner_pair[0]), convert.readonly(corner_pair[1]))
            if corner_pair
            else None
        )
        self._uvs = convert.readonly(uv_array) if uv_array is not None else None
        self._uv_table = convert.readonly(uv_table) if uv_table is not None else None
        self._uv_indices = convert.readonly(uv_index) if uv_index is not None else None

    @staticmethod
    def _faces_to_arrays(faces: Any) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
        if isinstance(faces, np.ndarray):
            array = convert.int_array(faces, "faces")
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
        indices = convert.int_array(flat, "faces") if flat else np.zeros(0, dtype=np.int64)
        return sizes, indices.reshape(-1)

    @classmethod
    @convert.memory_errors()
    def from_obj(
        cls,
        path: str | os.PathLike[str],
        *,
        boundary: Boundary | None = None,
        creasing: Creasing | None = None,
        max_bytes: int | None = None,
        memory_budget: int | None = None,
    ) -> Mesh:
        """Reads an OBJ file: ``v``, ``vt`` (as face-varying uvs when every face corner has
        one), ``f`` (any index form, negative indices), and OpenSubdiv's ``t crease``,
        ``t corner``, ``t hole``, ``t interpolateboundary`` (0 is ``"none"``) and
        ``t creasemethod`` tags; the ``vt`` indices are the uvs' face-varying topology
        (:attr:`uv_indices`: two indices with equal coordinates at one vertex stay apart, as in
        OpenSubdiv). The file is
        streamed; LF, CRLF and CR line ends and a UTF-8 byte order mark are accepted.

        Errors found later in the mesh (by this constructor, :class:`Plan` or
        :func:`subdivide`: repeated vertices, non-manifold edges, orientation, creases that are
        no edges) name the file's line and its 1-based vertex indices.

        Args:
            path: the file.
            boundary: overrides the file's ``t interpolateboundary`` tag; without either the
                boundary is ``"edge-only"``.
            creasing: overrides the file's ``t creasemethod`` tag (``normal`` is
                ``"uniform"``); without either the creasing is ``"uniform"``.
            max_bytes: refuse files larger than this (default :data:`DEFAULT_MAX_INPUT_BYTES`,
                2 GiB).
            memory_budget: refuse files whose mesh would take more bytes than this while
                reading (default 4 GiB).

        Raises:
            BidegreeIOError: the file cannot be read, is malformed or too large
                (``path:LINE: message``).
            MemoryBudgetError: the mesh would not fit ``memory_budget``.
            BidegreeError: the topology is invalid (see :class:`Mesh`).

        Warns:
            ObjWarning: the file has statements or tags that were skipped (one per kind).
        """
        data = _native.read_obj(
            os.fspath(path),
            convert.budget(max_bytes, "max_bytes"),
            convert.budget(memory_budget),
        )
        for message in data["warnings"]:
            convert.warn_at_caller(message, ObjWarning)
        uvs = uv_indices = None
        if data["face_uvs"] is not None:
            # The vt indices are the face-varying topology (OpenSubdiv's rule).
            uvs, uv_indices = data["uvs"], data["face_uvs"]
        creases = None
        if len(data["crease_sharpness"]):
            creases = (data["crease_edges"], data["crease_sharpness"])
        corners = None
        if len(data["corner_sharpness"]):
            corners = (data["corner_vertices"], data["corner_sharpness"])
        mesh = cls.__new__(cls)
        mesh._finish(
            data["points"],
            data["face_sizes"],
            data["face_indices"],
            creases,
            corners,
            uvs,
            boundary if boundary is not None else (data["boundary"] or "edge-only"),
            creasing if creasing is not None else (data["creasing"] or "uniform"),
            data["source"],
            holes=data["holes"] if len(data["holes"]) else None,
            uv_indices=uv_indices,
        )
        return mesh

    @convert.memory_errors()
    def write_obj(self, path: str | os.PathLike[str]) -> None:
        """Writes the cage's points, faces and uvs as OBJ (creases and corners are not kept;
        the ``vt`` indices are :attr:`uv_indices`, or one per distinct value)."""
        write_obj_arrays(
            path,
            self._points,
            self._face_sizes,
            self._face_indices,
            self._uv_table if self._uv_indices is not None else self._uvs,
            self._uv_indices,
        )

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
    def uv_indices(self) -> NDArray[np.uint32] | None:
        """(corners,) the uvs' face-varying topology (indices into :attr:`uv_values`), or None
        when the uvs are welded by value."""
        return self._uv_indices

    @property
    def uv_values(self) -> FloatArray | None:
        """The (N, 2) texture coordinates :attr:`uv_indices` index; without indices the
        per-corner :attr:`uvs`."""
        return self._uv_table if self._uv_table is not None else self._uvs

    @property
    def holes(self) -> NDArray[np.int64]:
        """(H,) the faces tagged as holes (without those boundary ``"none"`` adds)."""
        return self._holes

    @property
    def boundary(self) -> Boundary:
        """``"edge-only"``, ``"edge-and-corner"`` or ``"none"``."""
        return self._boundary

    @property
    def creasing(self) -> Creasing:
        """``"uniform"`` or ``"chaikin"``: the creasing method plans use unless told otherwise."""
        return self._creasing

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
        if self._creasing != "uniform":
            extras.append(f"creasing={self._creasing!r}")
        extra = (", " + ", ".join(extras)) if extras else ""
        return (
            f"Mesh(vertices={self.num_vertices}, faces={self.num_faces}, "
            f"boundary={self._boundary!r}, dtype={self._points.dtype}{extra})"
        )


def _check_face_sizes(sizes: NDArray[np.int64]) -> None:
    """Faces have at least 3 vertices (the core says so too; this names negative sizes)."""
    small = np.flatnonzero(sizes < 3)
    if len(small):
        face, size = int(small[0]), int(sizes[small[0]])
        if size < 0:
            text = f"face {face} has size {size} in face_sizes; a size counts the face's vertices"
        else:
            text = f"face {face} has {size} vertices"
        error = FaceTooSmallError(f"{text}; faces need at least 3")
        error.face, error.size = face, size
        raise error


def shared_uvs(per_corner: FloatArray) -> tuple[FloatArray, NDArray[np.uint32]]:
    """Per-corner uvs as OBJ's shared ``vt`` lines: one per distinct value and each corner's
    index, so that reading the indices back as the face-varying topology
    (:attr:`Mesh.uv_indices`) gives the seams the values had (the weld by value)."""
    values, inverse = np.unique(per_corner, axis=0, return_inverse=True)
    return np.ascontiguousarray(values), inverse.reshape(-1).astype(np.uint32)


def write_obj_arrays(
    path: str | os.PathLike[str],
    points: FloatArray,
    face_sizes: NDArray[np.integer[Any]],
    face_indices: NDArray[np.integer[Any]],
    uvs: FloatArray | None,
    uv_indices: NDArray[np.uint32] | None = None,
) -> None:
    """Writes a polygon mesh given as numpy arrays as OBJ (through the core's writer): ``uvs``
    per corner (written as :func:`shared_uvs`), or the ``vt`` values ``uv_indices`` index."""
    offsets = np.zeros(len(face_sizes) + 1, dtype=np.uint32)
    np.cumsum(face_sizes, out=offsets[1:], dtype=np.uint32)
    indices = np.ascontiguousarray(face_indices, dtype=np.uint32)
    if uvs is not None:
        uvs = np.ascontiguousarray(uvs, dtype=points.dtype)
        if uv_indices is None:
            uvs, uv_indices = shared_uvs(uvs)
    _native.write_obj(os.fspath(path), points, offsets, indices, uvs, None, uv_indices)
