"""Type stubs of the Rust extension ``bidegree._native`` (use the ``bidegree`` API instead).

Arrays must be C-contiguous and of exactly the dtypes named; the ``bidegree`` package converts.
Every function releases the GIL while the core works; core errors arrive as the classes of
``bidegree._errors`` and a panic as ``bidegree.InternalError``.
"""

import os
from typing import Any, Literal, TypeAlias, TypedDict

import numpy as np
from numpy.typing import NDArray

__version__: str
MAX_DEGREE: int
MAX_LEVELS: int
DEFAULT_MEMORY_BUDGET: int
MACHINE_MEMORY: int | None
ADDRESS_SPACE_HEADROOM: int
INFINITELY_SHARP: float
DEFAULT_MAX_INPUT_BYTES: int

_Float: TypeAlias = NDArray[np.float32] | NDArray[np.float64]
_Output: TypeAlias = Literal["primal", "dual"]
_Boundary: TypeAlias = Literal["edge-only", "edge-and-corner"]

class Cage:
    def __init__(
        self,
        num_vertices: int,
        face_sizes: NDArray[np.int64],
        face_indices: NDArray[np.int64],
        crease_edges: NDArray[np.int64],
        crease_sharpness: NDArray[np.float32],
        corner_vertices: NDArray[np.int64],
        corner_sharpness: NDArray[np.float32],
        source: ObjSource | None = None,
        holes: NDArray[np.int64] | None = None,
    ) -> None: ...
    @property
    def num_vertices(self) -> int: ...
    @property
    def num_faces(self) -> int: ...
    def validate_geometry(self, points: _Float) -> None: ...

class Plan:
    def __init__(
        self,
        cage: Cage,
        degree: int,
        levels: int,
        output: str,
        boundary: str,
        memory_budget: int | None = None,
        rules: str = "averaging",
        creasing: str = "uniform",
    ) -> None: ...
    def evaluate(self, values: _Float) -> Any: ...
    def limit_positions(self, values: _Float) -> Any: ...
    def limit_surface(self, points: _Float, normals: str = "corner") -> tuple[Any, Any]: ...
    def release_buffers(self) -> None: ...
    @property
    def limit_extra_levels(self) -> int: ...
    @property
    def limit_normals_split(self) -> bool: ...
    def evaluate_face_varying(
        self,
        values: _Float,
        mode: str = ...,
        limit: bool = ...,
        indices: NDArray[np.uint32] | None = ...,
    ) -> Any: ...
    def evaluate_face_varying_shared(
        self,
        values: _Float,
        mode: str = ...,
        limit: bool = ...,
        indices: NDArray[np.uint32] | None = ...,
    ) -> tuple[Any, NDArray[np.int32]]: ...
    @property
    def degree(self) -> int: ...
    @property
    def levels(self) -> int: ...
    @property
    def output(self) -> _Output: ...
    @property
    def boundary(self) -> _Boundary: ...
    @property
    def rules(self) -> str: ...
    @property
    def memory_budget(self) -> int: ...
    @property
    def num_input_vertices(self) -> int: ...
    @property
    def num_output_vertices(self) -> int: ...
    @property
    def num_output_faces(self) -> int: ...
    def isolated_vertices(self) -> NDArray[np.int32]: ...
    def face_sizes(self) -> NDArray[np.int32]: ...
    def face_indices(self) -> NDArray[np.int32]: ...
    def face_origin(self) -> NDArray[np.int32]: ...
    def corner_edges(self) -> NDArray[np.int32]: ...
    def edges(self) -> NDArray[np.int32]: ...
    def edge_origin(self) -> NDArray[np.int32]: ...
    def edge_sharpness(self) -> NDArray[np.float32]: ...
    def cage_edges(self) -> NDArray[np.int32]: ...
    def write_obj(
        self,
        path: str | os.PathLike[str],
        points: _Float,
        uvs: _Float | None = None,
        normals: _Float | None = None,
        uv_indices: NDArray[np.uint32] | None = None,
    ) -> None: ...

class _ObjData(TypedDict):
    points: NDArray[np.float64]
    face_sizes: NDArray[np.int64]
    face_indices: NDArray[np.int64]
    uvs: NDArray[np.float64]
    face_uvs: NDArray[np.int64] | None
    crease_edges: NDArray[np.int64]
    crease_sharpness: NDArray[np.float32]
    corner_vertices: NDArray[np.int64]
    corner_sharpness: NDArray[np.float32]
    boundary: _Boundary | None
    creasing: Literal["uniform", "chaikin"] | None
    warnings: list[str]
    source: ObjSource

class ObjSource:
    """Lines of the faces, creases and corners of a file read by :func:`read_obj`."""
    @property
    def name(self) -> str: ...
    def face_lines(self) -> NDArray[np.uint64]: ...

def subdivide(
    cage: Cage,
    points: _Float,
    degree: int,
    levels: int,
    output: str,
    boundary: str,
    memory_budget: int | None = None,
    rules: str = "averaging",
    creasing: str = "uniform",
    evaluate: bool = True,
) -> tuple[Plan, Any | None]: ...
def estimate(
    cage: Cage, degree: int, levels: int, output: str = "primal", boundary: str = "edge-only"
) -> tuple[int, int, int]: ...
def read_obj(
    path: str | os.PathLike[str], max_bytes: int | None = None, memory_budget: int | None = None
) -> _ObjData: ...
def write_obj(
    path: str | os.PathLike[str],
    points: _Float,
    face_offsets: NDArray[np.uint32],
    face_indices: NDArray[np.uint32],
    uvs: _Float | None = None,
    normals: _Float | None = None,
    uv_indices: NDArray[np.uint32] | None = None,
) -> None: ...
def _panic_for_tests(in_worker: bool = False) -> None: ...

# Analysis (the paper's §4): subdivision matrix, Fourier blocks, C1 report.
def analyze(degree: int, valence: int, steps: int = 4) -> dict[str, Any]:
    """Subdivision matrix (``matrix``, ``labels``), spectrum (``eigenvalues`` complex, ``modes``),
    Fourier ``blocks`` and ``block_eigenvalues``; with ``steps > 0`` also the report (``text``,
    ``c1``, ``dominant``, ``subdominant``, ``third``, ``jacobian_min``/``max``, ``winding``, ...)
    and the characteristic map (``map_points`` (k, rows, columns, 2), ``map_params``,
    ``map_cell_jacobian``, ``map_in_ring``, ``map_spacing``, ``map_steps``)."""

def basis_function(
    degree: int, valence: int, steps: int = 3, label: tuple[int, int, int] = (0, 0, 0)
) -> dict[str, Any]:
    """A level-1 unit impulse refined by ``steps`` engine steps: ``params`` (rows, columns, 2),
    ``values`` (k, rows, columns), ``spacing``, ``primal``."""

class _AdaptiveData(TypedDict):
    points: _Float
    triangles: NDArray[np.int32]
    face_origin: NDArray[np.int32]
    triangle_level: NDArray[np.int32]
    vertex_level: NDArray[np.int32]
    vertex_id: NDArray[np.int64]
    cage_vertex: NDArray[np.int32]
    vertex_sharpness: NDArray[np.float32]
    leaves_per_level: NDArray[np.int64]
    max_error: float | None
    vertex_values: _Float | None
    face_varying: list[_Float]
    edge_origin: NDArray[np.int32]
    edge_level: NDArray[np.int32]
    edge_sharpness: NDArray[np.float32]
    cage_edges: NDArray[np.int32]

def subdivide_adaptive(
    cage: Cage,
    points: _Float,
    degree: int,
    max_level: int,
    tolerance: float,
    boundary: str,
    memory_budget: int | None = None,
    measure_leaves: bool = False,
    vertex_values: _Float | None = None,
    face_varying: list[tuple[_Float, str, NDArray[np.uint32] | None]] | None = None,
) -> _AdaptiveData: ...
