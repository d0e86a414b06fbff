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

from . import _native
from ._adaptive import AdaptiveResult, subdivide_adaptive
from ._convert import Boundary as Boundary  # the option types, for annotations
from ._convert import Creasing as Creasing
from ._convert import FloatArray as FloatArray
from ._convert import NormalDomain as NormalDomain
from ._convert import Output as Output
from ._convert import Rules as Rules
from ._convert import UvMode as UvMode
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
    ObjWarning,
    RepeatedVertexError,
)
from ._mesh import DEFAULT_MAX_INPUT_BYTES, Mesh
from ._plan import Plan, Result, estimate, subdivide
from ._uv_weld import BLENDER_UV_LIMIT, blender_uv_indices

__all__ = [
    "BLENDER_UV_LIMIT",
    "DEFAULT_MAX_INPUT_BYTES",
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
    "ObjWarning",
    "Plan",
    "RepeatedVertexError",
    "Result",
    "__version__",
    "blender_uv_indices",
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

# The public classes and functions live in private modules; they present themselves as
# ``bidegree.X`` (help(), reprs of the classes, documentation tools).
for _public in (AdaptiveResult, Mesh, Plan, Result, estimate, subdivide, subdivide_adaptive):
    _public.__module__ = __name__
del _public
