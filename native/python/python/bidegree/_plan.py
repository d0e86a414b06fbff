"""Subdivision: :class:`Plan` (the topology work, done once), :class:`Result` (a subdivided
mesh), :func:`subdivide` (both in one call) and :func:`estimate`.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Mapping
from typing import Any, TypeVar, overload

import numpy as np
from numpy.typing import ArrayLike, NDArray

from . import _convert as convert
from . import _native
from ._convert import Boundary, Creasing, FloatArray, NormalDomain, Output, Rules, UvMode
from ._errors import InvalidInputError
from ._mesh import Mesh, shared_uvs

_T = TypeVar("_T")


class _Output:
    """What a :class:`Plan` and its :class:`Result` objects share, read from the native plan in
    one place: the options and the output topology (each array fetched once per plan and shared
    read-only)."""

    _native_plan: Any
    _arrays: dict[str, NDArray[np.int32]]

    @convert.memory_errors()
    def _array(self, name: str) -> NDArray[np.int32]:
        """The native plan's array ``name``, fetched on first use and kept (read-only)."""
        array = self._arrays.get(name)
        if array is None:
            array = self._arrays[name] = convert.readonly(getattr(self._native_plan, name)())
        return array

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
    def face_sizes(self) -> NDArray[np.int32]:
        """(F,) corners of each output face, int32, read-only."""
        return self._array("face_sizes")

    @property
    def face_indices(self) -> NDArray[np.int32]:
        """Output vertex of each output face corner, int32, read-only."""
        return self._array("face_indices")

    @property
    def face_origin(self) -> NDArray[np.int32]:
        """(F,) cage face each output face comes from, int32, read-only."""
        return self._array("face_origin")

    @property
    def edges(self) -> NDArray[np.int32]:
        """(E, 2) edges of the output mesh, int32, read-only (built on first use)."""
        return self._array("edges")

    @property
    def corner_edges(self) -> NDArray[np.int32]:
        """Edge (row of :attr:`edges`) from each output face corner to the next, int32."""
        return self._array("corner_edges")

    @property
    def edge_origin(self) -> NDArray[np.int32]:
        """(E,) cage edge (row of :attr:`cage_edges`) each output edge lies on, -1 for an edge
        inside a cage face, int32, read-only. Primal output: the child edges of each cage
        edge; dual output: only the boundary edges between two boundary points of one cage
        edge (every other dual edge crosses the surface's edges)."""
        return self._array("edge_origin")

    @property
    def edge_sharpness(self) -> NDArray[np.float32]:
        """(E,) sharpness each output edge keeps at the last level (10 infinitely sharp, 0
        inside cage faces), float32, read-only: what one more level would use, so that the
        output, subdivided again with these creases, continues this surface. Classic
        Catmull-Clark: OpenSubdiv's per-level rule (uniform or Chaikin); otherwise the cage
        edge's sharpness minus one per level."""
        return self._array("edge_sharpness")

    @property
    def cage_edges(self) -> NDArray[np.int32]:
        """(E0, 2) edges of the cage as vertex pairs (smaller first, the cage's numbering),
        ordered by pair, int32, read-only."""
        return self._array("cage_edges")


class Plan(_Output):
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
            Default: the mesh's (:attr:`Mesh.creasing`, from an OBJ file's ``t creasemethod``
            tag), else uniform.

    Raises:
        NonManifoldEdgeError, InconsistentOrientationError, CreaseNotAnEdgeError: bad topology.
        DegreeOutOfRangeError, LevelOutOfRangeError, MemoryBudgetError, InvalidInputError.

    Warns:
        IsolatedVerticesWarning: the cage has vertices in no face (they are dropped).
    """

    _mesh: Mesh

    @convert.memory_errors()
    def __init__(
        self,
        mesh: Mesh,
        degree: int = 4,
        levels: int = 2,
        output: Output = "primal",
        memory_budget: int | None = None,
        rules: Rules = "averaging",
        creasing: Creasing | None = None,
    ) -> None:
        if not isinstance(mesh, Mesh):
            raise InvalidInputError(f"mesh must be a bidegree.Mesh, not {type(mesh).__name__}")
        native = _native.Plan(
            mesh._cage,
            convert.int_arg(degree, "degree"),
            convert.int_arg(levels, "levels"),
            convert.choice(output, convert.OUTPUTS, "output"),
            mesh.boundary,
            convert.budget(memory_budget),
            convert.choice(rules, convert.RULES, "rules"),
            _creasing(mesh, creasing),
        )
        self._init(mesh, native)
        convert.warn_isolated(self.isolated_vertices)

    @classmethod
    def _wrap(cls, mesh: Mesh, native: Any) -> Plan:
        plan = cls.__new__(cls)
        plan._init(mesh, native)
        return plan

    def _init(self, mesh: Mesh, native: Any) -> None:
        self._mesh = mesh
        self._native_plan = native
        self._arrays = {}

    @convert.memory_errors()
    def evaluate(self, points: ArrayLike) -> FloatArray:
        """Subdivides per-vertex values: (V, C) -> (N, C) for any C >= 1 (positions, colours,
        weights, ...); a (V,) array is one channel and gives (N,). float32 stays float32, float64
        stays float64. Values must be finite (:class:`NonFiniteError` names the vertex); a result
        that overflows its dtype (float32 beyond about 3.4e38) raises :class:`NonFiniteError`
        too.
        """
        values, flat = convert.values_2d(points, self._mesh.num_vertices, "points", "vertices")
        out = self._native_plan.evaluate(values)
        return out.reshape(-1) if flat else out

    @convert.memory_errors()
    def limit_positions(self, points: ArrayLike | None = None) -> FloatArray:
        """Exact limit positions at the output vertices: (V, C) -> (N, C) for any per-vertex
        attribute; the first V' rows (V' cage vertices in faces drawn) are the limits of the
        cage vertices. Default: the cage's own points. Holes change no rule: the limit is the
        whole surface's, at the vertices drawn.

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
            values, flat = convert.values_2d(points, self._mesh.num_vertices, "points", "vertices")
        out = self._native_plan.limit_positions(values)
        return out.reshape(-1) if flat else out

    @convert.memory_errors()
    def limit_surface(
        self, points: ArrayLike | None = None, normals: NormalDomain = "corner"
    ) -> tuple[FloatArray, FloatArray]:
        """Limit positions (N, 3) and unit limit normals (output corners, 3), in the order of
        :attr:`face_indices` (face-varying, like Blender's custom split normals and USD's
        ``faceVarying`` normals): smooth vertices have one normal at all their corners; at
        creases and corners each side has its own. Averaging rules only.

        With ``normals="vertex"`` the normals are one per output vertex (N, 3), as the
        positions (OpenSubdiv's form, USD's ``vertex`` normals): a vertex whose corners agree
        has their normal, bit for bit; where they differ (creases, corners, degree 1's faces)
        the unit vector along their sum, which shades smoothly across the split. A quarter of
        the bytes of the corners' normals on a quad mesh, and a faster call.

        Interior normals are exact (subdominant eigenvectors); normals at curve vertices are
        one-sided estimates from the finer level the limit is computed on (first-order in its
        spacing). Degree 1 gives each face's bilinear normal. Degenerate geometry gives zeros.

        Raises:
            InvalidInputError: ``normals`` not ``"corner"`` or ``"vertex"``, dual output,
                classic rules, wrong shapes.
            MemoryBudgetError: the extra levels would not fit the memory budget.
        """
        domain = convert.choice(normals, convert.NORMAL_DOMAINS, "normals")
        return self._native_plan.limit_surface(self._points(points), domain)

    def release_buffers(self) -> None:
        """Free the working arrays the plan keeps between calls.

        A plan keeps a few arrays the size of its last level after :meth:`evaluate`,
        :meth:`limit_surface` and the face-varying calls, so that the next call (the next frame)
        does not allocate them again. A batch job that keeps many plans alive, or one plan
        between rare calls, can give that memory back here; results do not change, and the next
        call allocates the arrays again. The topology and the limit's stencils stay.
        """
        self._native_plan.release_buffers()

    @property
    def limit_extra_levels(self) -> int:
        """Levels the limit evaluation refines beyond :attr:`levels` so that every output
        vertex has a clean neighbourhood (0 on regular meshes, and where every irregular vertex
        is isolated: its neighbours' limits are then composed stencils); built on first use."""
        return int(self._native_plan.limit_extra_levels)

    @property
    def limit_normals_split(self) -> bool:
        """Whether some output vertex has different limit normals at its corners: the two
        sides of an infinitely sharp crease, the sectors of a corner (degree 1: every face its
        own; semi-sharp creases are smooth in the limit). ``False`` means
        ``limit_surface(normals="vertex")`` gives every corner's normal, bit for bit, in a
        quarter of the bytes (Blender's point custom normals, USD's ``vertex`` normals); built
        on first use, with the limit's stencils.

        Raises:
            InvalidInputError: dual output, classic rules (no limit normals).
            MemoryBudgetError: the extra levels would not fit the memory budget.
        """
        return bool(self._native_plan.limit_normals_split)

    @overload
    def evaluate_face_varying(
        self,
        values: Mapping[str, ArrayLike | tuple[ArrayLike, ArrayLike]],
        mode: UvMode = ...,
        *,
        limit: bool = ...,
    ) -> dict[str, FloatArray]: ...

    @overload
    def evaluate_face_varying(
        self,
        values: ArrayLike,
        mode: UvMode = ...,
        *,
        limit: bool = ...,
        indices: ArrayLike | None = ...,
    ) -> FloatArray: ...

    @convert.memory_errors()
    def evaluate_face_varying(
        self,
        values: ArrayLike | Mapping[str, ArrayLike | tuple[ArrayLike, ArrayLike]],
        mode: UvMode = "boundaries",
        *,
        limit: bool = False,
        indices: ArrayLike | None = None,
    ) -> FloatArray | dict[str, FloatArray]:
        """Subdivides per-face-corner values (UVs, any channel count): (corners, C) ->
        (output corners, C) in the order of :attr:`face_indices`; a (corners,) array gives
        (output corners,). A mapping of name -> array (several UV sets, each its own seams)
        gives a dict of the results; a set given as ``(values, indices)`` is indexed.

        The corners of one cage vertex with equal values (every channel) share one
        face-varying value; where they differ is a seam, a boundary of the face-varying mesh.
        With ``indices`` (one int per face corner, OpenSubdiv's face-varying index buffer,
        OBJ's ``vt`` indices, USD's primvar indices) the values are given OpenSubdiv's way,
        ``values`` (N, C) indexed by them, and the indices are the topology: corners of one
        cage vertex with the same index share a value, different indices stay apart even where
        their values are equal (a seam OpenSubdiv keeps). Blender's Subdivision Surface welds
        by a tolerance and the UV winding instead: ``indices=blender_uv_indices(...)`` gives
        its seams (:func:`bidegree.blender_uv_indices`).
        ``mode`` is OpenSubdiv's ``FVarLinearInterpolation`` (USD's
        ``faceVaryingLinearInterpolation``): ``"none"`` (smooth everywhere: Blender's *All*),
        ``"corners-only"``, ``"corners-plus1"``, ``"corners-plus2"``, ``"boundaries"`` (seams and
        boundary linear, smooth inside: Blender's default *Keep Boundaries*) or ``"all"``
        (bilinear per face: Blender's *None*). Every mode but ``"all"`` subdivides the values
        with this plan's scheme and degree (the face-varying mesh is refined on first use per
        UV layout and mode, and kept). ``limit``: the values on their limit surface (the masks
        of :meth:`limit_positions`; ``"all"`` is its own limit).

        Raises:
            InvalidInputError: wrong shape, unknown mode. NonFiniteError: a non-finite value.
            IndexOutOfRangeError: an index outside ``values``.
        """
        if isinstance(values, Mapping):
            return _each_set(values, indices, self.evaluate_face_varying, mode, limit)
        array, flat, mode, index = self._face_varying_input(values, mode, limit, indices)
        out = self._native_plan.evaluate_face_varying(array, mode, limit, index)
        return out.reshape(-1) if flat else out

    @overload
    def evaluate_face_varying_shared(
        self,
        values: Mapping[str, ArrayLike | tuple[ArrayLike, ArrayLike]],
        mode: UvMode = ...,
        *,
        limit: bool = ...,
    ) -> dict[str, tuple[FloatArray, NDArray[np.int32]]]: ...

    @overload
    def evaluate_face_varying_shared(
        self,
        values: ArrayLike,
        mode: UvMode = ...,
        *,
        limit: bool = ...,
        indices: ArrayLike | None = ...,
    ) -> tuple[FloatArray, NDArray[np.int32]]: ...

    @convert.memory_errors()
    def evaluate_face_varying_shared(
        self,
        values: ArrayLike | Mapping[str, ArrayLike | tuple[ArrayLike, ArrayLike]],
        mode: UvMode = "boundaries",
        *,
        limit: bool = False,
        indices: ArrayLike | None = None,
    ) -> tuple[FloatArray, NDArray[np.int32]] | dict[str, tuple[FloatArray, NDArray[np.int32]]]:
        """:meth:`evaluate_face_varying` in the indexed form of OpenSubdiv, USD's indexed
        primvars and OBJ's shared ``vt`` lines: ``(values, indices)``, the refined values (one
        per vertex of the subdivided face-varying mesh that the output uses: (N, C), or (N,)
        for a 1-D input) and one int32 index into them per output face corner (in the order of
        :attr:`face_indices`), so ``values[indices]`` is what :meth:`evaluate_face_varying`
        returns, bitwise. The indices are topology: read-only, and the same array for every
        call on one UV layout and mode (the plan keeps them), so re-evaluating writes one value
        per face-varying vertex instead of one per face corner (about a quarter as many on a
        quad mesh). Arguments, modes and errors as :meth:`evaluate_face_varying`.
        """
        if isinstance(values, Mapping):
            return _each_set(values, indices, self.evaluate_face_varying_shared, mode, limit)
        array, flat, mode, index = self._face_varying_input(values, mode, limit, indices)
        out, shared = self._native_plan.evaluate_face_varying_shared(array, mode, limit, index)
        return (out.reshape(-1) if flat else out), convert.readonly(shared)

    def _face_varying_input(
        self, values: ArrayLike, mode: UvMode, limit: bool, indices: ArrayLike | None
    ) -> tuple[FloatArray, bool, UvMode, NDArray[np.uint32] | None]:
        """Checks face-varying input: the values as a 2-D array (and whether they came 1-D), the
        mode, and the indices (None: per corner)."""
        mode = convert.choice(mode, convert.UV_MODES, "uv_mode")  # type: ignore[assignment]
        if not isinstance(limit, bool):
            raise InvalidInputError(f"limit must be True or False, not {limit!r}")
        corners = self._mesh.num_corners
        if indices is None:
            array, flat = convert.values_2d(values, corners, "values", "face corners")
            return array, flat, mode, None
        given = convert.float_array(values, "values")
        rows = len(given) if given.ndim else 0
        array, flat = convert.values_2d(given, rows, "values", "indexed values")
        index = convert.face_varying_indices(indices, corners, rows, "indices")
        return array, flat, mode, index

    def result(
        self,
        points: ArrayLike | None = None,
        *,
        limit: bool = False,
        normals: bool = False,
        uv_mode: UvMode = "boundaries",
    ) -> Result:
        """A :class:`Result` for ``points`` (default: the cage's own points), with uvs when the
        cage has them (in ``uv_mode``, see :meth:`evaluate_face_varying`). ``limit``: the points
        (and uvs) are pushed to the limit surface (:meth:`limit_positions`); ``normals``: the
        result carries the limit normals (:meth:`limit_surface`)."""
        return _result(self, self._points(points), None, limit, normals, uv_mode)

    def _points(self, points: ArrayLike | None) -> FloatArray:
        """``points`` checked as (V, 3), or the cage's own points."""
        if points is None:
            return self._mesh.points
        values, _ = convert.values_2d(points, self._mesh.num_vertices, "points", "vertices")
        if values.shape[1] != 3:
            raise InvalidInputError(f"points must have shape (V, 3), not {values.shape}")
        return values

    @property
    def mesh(self) -> Mesh:
        """The cage this plan was made for."""
        return self._mesh

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

    @property
    def isolated_vertices(self) -> NDArray[np.int32]:
        """Cage vertices in no face (dropped), int32, read-only."""
        return self._array("isolated_vertices")

    def __repr__(self) -> str:
        return (
            f"Plan(degree={self.degree}, levels={self.levels}, output={self.output!r}, "
            f"boundary={self.boundary!r}, input_vertices={self._mesh.num_vertices}, "
            f"output_vertices={self.num_output_vertices}, output_faces={self.num_output_faces})"
        )


def _each_set(
    sets: Mapping[str, ArrayLike | tuple[ArrayLike, ArrayLike]],
    indices: ArrayLike | None,
    evaluate: Callable[..., _T],
    mode: UvMode,
    limit: bool,
) -> dict[str, _T]:
    """``evaluate`` of each face-varying set of a mapping (a set given as ``(values, indices)``
    is indexed)."""
    if indices is not None:
        raise InvalidInputError("indices go with each set of a mapping: (values, indices)")
    out = {}
    for name, given in sets.items():
        array, index = given if isinstance(given, tuple) else (given, None)
        out[name] = evaluate(array, mode, limit=limit, indices=index)
    return out


class Result(_Output):
    """A subdivided mesh: ``points`` (N, 3) in the dtype of the input (refined points, or limit
    positions with ``limit=True``), the polygons (``face_sizes``, ``face_indices``, int32),
    ``face_origin`` (cage face of each face), ``edges`` (E, 2), ``corner_edges``, ``uvs``
    (output corners, 2) when the cage has uvs (subdivided in :attr:`uv_mode`; kept in the
    indexed form, ``uv_values`` indexed by ``uv_indices``, and expanded on first read) and
    ``normals`` (output corners, 3) with ``normals=True``.
    Topology arrays are shared with the :class:`Plan` and read-only; ``points`` is yours.
    """

    def __init__(
        self,
        plan: Plan,
        points: FloatArray,
        normals: FloatArray | None = None,
        uv_mode: UvMode = "boundaries",
        limit: bool = False,
    ) -> None:
        self._plan = plan
        self._native_plan = plan._native_plan
        self._arrays = plan._arrays
        self.points: FloatArray = points
        #: (output corners, 3) unit limit normals, one per face corner, when asked for.
        self.normals: FloatArray | None = normals
        #: The face-varying mode the uvs were subdivided in.
        self.uv_mode: UvMode = uv_mode
        mesh = plan.mesh
        #: The subdivided uvs in the indexed form (as :attr:`Mesh.uv_values`): (N, 2) values,
        #: one per vertex of the subdivided face-varying mesh, ``None`` without uvs (or once
        #: :attr:`uvs` is assigned).
        self.uv_values: FloatArray | None = None
        #: int32 index into :attr:`uv_values` per output face corner (read-only, shared with
        #: the plan's later results of the same UV layout and mode).
        self.uv_indices: NDArray[np.int32] | None = None
        self._uvs: FloatArray | None = None
        if mesh.uv_indices is not None:
            self.uv_values, self.uv_indices = plan.evaluate_face_varying_shared(
                mesh.uv_values, uv_mode, limit=limit, indices=mesh.uv_indices
            )
        elif mesh.uvs is not None:
            self.uv_values, self.uv_indices = plan.evaluate_face_varying_shared(
                mesh.uvs, uv_mode, limit=limit
            )

    @property
    def uvs(self) -> FloatArray | None:
        """(output corners, 2) uvs per face corner (``uv_values[uv_indices]``, made on first
        read), ``None`` when the cage has none. Assigning replaces them (and drops the indexed
        form, which no longer describes them)."""
        if self._uvs is None and self.uv_values is not None and self.uv_indices is not None:
            self._uvs = self.uv_values[self.uv_indices]
        return self._uvs

    @uvs.setter
    def uvs(self, value: FloatArray | None) -> None:
        self._uvs = value
        self.uv_values = self.uv_indices = None

    @property
    def plan(self) -> Plan:
        """The plan that made this result (to evaluate further point sets)."""
        return self._plan

    @property
    def num_vertices(self) -> int:
        """Number of output vertices."""
        return len(self.points)

    @property
    def num_faces(self) -> int:
        """Number of output faces."""
        return int(self._native_plan.num_output_faces)

    @convert.memory_errors()
    def write_obj(self, path: str | os.PathLike[str]) -> None:
        """Writes the result as OBJ (``v``, ``vt`` when there are uvs: one per value of
        :attr:`uv_values`, or per distinct value of assigned :attr:`uvs`, so that the ``vt``
        indices read back as the same seams; ``vn`` per face corner
        when there are normals, ``f``), fast.

        Raises:
            BidegreeIOError: the file cannot be written.
            InvalidInputError: ``points`` was replaced by an array of another shape.
        """
        points = np.ascontiguousarray(self.points)
        if points.dtype not in (np.float32, np.float64):
            points = points.astype(np.float64)
        uvs = normals = uv_indices = None
        if self.uv_values is not None and self.uv_indices is not None:
            uvs = np.ascontiguousarray(self.uv_values, dtype=points.dtype)
            uv_indices = self.uv_indices.astype(np.uint32)
        elif self.uvs is not None:
            uvs, uv_indices = shared_uvs(np.ascontiguousarray(self.uvs, dtype=points.dtype))
        if self.normals is not None:
            normals = np.ascontiguousarray(self.normals, dtype=points.dtype)
        self._native_plan.write_obj(os.fspath(path), points, uvs, normals, uv_indices)

    def __repr__(self) -> str:
        return (
            f"Result(vertices={self.num_vertices}, faces={self.num_faces}, degree={self.degree}, "
            f"levels={self.levels}, output={self.output!r}, dtype={self.points.dtype})"
        )


@convert.memory_errors()
def subdivide(
    mesh: Mesh,
    degree: int = 4,
    levels: int = 2,
    output: Output = "primal",
    memory_budget: int | None = None,
    rules: Rules = "averaging",
    creasing: Creasing | None = None,
    *,
    limit: bool = False,
    normals: bool = False,
    uv_mode: UvMode = "boundaries",
) -> Result:
    """Subdivides ``mesh``: validates its geometry (finite points, no zero-area face), builds
    the plan and evaluates it, in one call into the core. Options as in :class:`Plan`; the
    result's :attr:`Result.plan` can evaluate further point sets.

    ``limit=True`` puts the output vertices on the limit surface (:meth:`Plan.limit_positions`);
    ``normals=True`` adds the unit limit normals per face corner as :attr:`Result.normals`
    (:meth:`Plan.limit_surface`). Both need the primal output and the averaging rules (classic
    degree 3 has limit positions, not normals). The mesh's uvs are subdivided in ``uv_mode``
    (OpenSubdiv's face-varying modes, default ``"boundaries"`` as Blender's *Keep Boundaries*;
    see :meth:`Plan.evaluate_face_varying`), on the limit surface with ``limit``.

    Raises:
        NonFiniteError, DegenerateFaceError: bad geometry.
        NonManifoldEdgeError, InconsistentOrientationError, CreaseNotAnEdgeError: bad topology.
        DegreeOutOfRangeError, LevelOutOfRangeError, MemoryBudgetError, InvalidInputError.

    Warns:
        IsolatedVerticesWarning: the cage has vertices in no face (they are dropped).
    """
    if not isinstance(mesh, Mesh):
        raise InvalidInputError(f"mesh must be a bidegree.Mesh, not {type(mesh).__name__}")
    uv_mode = convert.choice(uv_mode, convert.UV_MODES, "uv_mode")  # type: ignore[assignment]
    native, points = _native.subdivide(
        mesh._cage,
        mesh.points,
        convert.int_arg(degree, "degree"),
        convert.int_arg(levels, "levels"),
        convert.choice(output, convert.OUTPUTS, "output"),
        mesh.boundary,
        convert.budget(memory_budget),
        convert.choice(rules, convert.RULES, "rules"),
        _creasing(mesh, creasing),
        evaluate=not limit,
    )
    plan = Plan._wrap(mesh, native)
    convert.warn_isolated(plan.isolated_vertices)
    return _result(plan, mesh.points, points, limit, normals, uv_mode)


def _creasing(mesh: Mesh, creasing: Creasing | None) -> str:
    """The creasing method of a request: the one asked for, else the mesh's."""
    if creasing is None:
        return mesh.creasing
    return convert.choice(creasing, convert.CREASING, "creasing")


def _result(
    plan: Plan,
    values: FloatArray,
    refined: FloatArray | None,
    limit: bool,
    normals: bool,
    uv_mode: UvMode,
) -> Result:
    """The :class:`Result` of ``values`` through ``plan`` (``refined``: already evaluated)."""
    native = plan._native_plan

    def make(points: FloatArray, corner_normals: FloatArray | None = None) -> Result:
        return Result(plan, points, corner_normals, uv_mode, limit)

    if normals:
        positions, corner_normals = native.limit_surface(values)
        if limit:
            return make(positions, corner_normals)
        return make(refined if refined is not None else native.evaluate(values), corner_normals)
    if limit:
        return make(native.limit_positions(values))
    return make(refined if refined is not None else native.evaluate(values))


@convert.memory_errors()
def estimate(mesh: Mesh, degree: int, levels: int, output: Output = "primal") -> dict[str, int]:
    """Output size and peak memory of a request, without doing it (and without a budget):
    ``{"vertices": ..., "faces": ..., "bytes": ...}``."""
    if not isinstance(mesh, Mesh):
        raise InvalidInputError(f"mesh must be a bidegree.Mesh, not {type(mesh).__name__}")
    vertices, faces, nbytes = _native.estimate(
        mesh._cage,
        convert.int_arg(degree, "degree"),
        convert.int_arg(levels, "levels"),
        convert.choice(output, convert.OUTPUTS, "output"),
        mesh.boundary,
    )
    return {"vertices": int(vertices), "faces": int(faces), "bytes": int(nbytes)}
