"""Exceptions and warnings of bidegree: one class per error kind of the Rust core.

The Rust extension raises these classes (it looks them up here by name), with the message of the
core's error and its details as attributes (for example ``RepeatedVertexError.face`` and
``.vertex``). All errors derive from :class:`BidegreeError`; input errors are also
:class:`ValueError`, index errors :class:`IndexError`, file errors :class:`OSError`, so ordinary
``except`` clauses work too.

Errors about a mesh read from an OBJ file are told in the file's terms: the message starts with
``path:LINE:`` and uses the file's 1-based vertex indices (tags keep their 0-based ones), the
attribute ``line`` holds the line, and the other attributes keep the mesh's 0-based indices.
"""

from __future__ import annotations

__all__ = [
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
    "NonFiniteError",
    "NonManifoldEdgeError",
    "ObjWarning",
    "RepeatedVertexError",
]


class BidegreeError(Exception):
    """Base class of every error raised by bidegree."""


class EmptyMeshError(BidegreeError, ValueError):
    """The mesh has no faces (or no vertices)."""


class FaceTooSmallError(BidegreeError, ValueError):
    """A face has fewer than three vertices (attributes ``face``, ``size``)."""


class RepeatedVertexError(BidegreeError, ValueError):
    """A face uses the same vertex twice (attributes ``face``, ``vertex``)."""


class IndexOutOfRangeError(BidegreeError, IndexError):
    """A face, crease or corner refers to a vertex that does not exist, or a negative index
    (attributes ``what``, ``index``, ``num_vertices``)."""


class NonFiniteError(BidegreeError, ValueError):
    """A coordinate is NaN or infinite (attribute ``vertex``; ``corner`` for face-varying
    values such as UVs), or a result overflowed its floating-point type although its input was
    finite (float32 beyond about 3.4e38; ``vertex`` is then the output vertex)."""


class DegenerateFaceError(BidegreeError, ValueError):
    """A face has (numerically) zero area (attribute ``face``)."""


class NonManifoldEdgeError(BidegreeError, ValueError):
    """More than two faces share an edge (attributes ``a``, ``b``, ``faces``)."""


class InconsistentOrientationError(BidegreeError, ValueError):
    """Two faces traverse a shared edge in the same direction (attributes ``a``, ``b``,
    ``face_a``, ``face_b``)."""


class CreaseNotAnEdgeError(BidegreeError, ValueError):
    """A crease names a vertex pair that is not an edge of the mesh (attributes ``crease``,
    ``a``, ``b``)."""


class DegreeOutOfRangeError(BidegreeError, ValueError):
    """The degree is outside ``1..=MAX_DEGREE`` (attributes ``degree``, ``max``)."""


class LevelOutOfRangeError(BidegreeError, ValueError):
    """The number of levels is outside ``0..=MAX_LEVELS`` (attributes ``levels``, ``max``)."""


class MemoryBudgetError(BidegreeError):
    """The request would need more memory than its budget (attributes ``required``, ``budget``,
    ``faces``), or more than this process can have (the machine's memory, a cgroup or
    address-space limit: ``required`` and ``budget``, the memory available, when the core knows
    it), or an allocation was refused while working; nothing is kept of the request. Adaptive
    subdivision says in the message when it refused (before any work, before making a level,
    before the output) and sets ``level`` when it stopped before making that level."""


class InvalidInputError(BidegreeError, ValueError):
    """Arrays of the wrong shape, type or length, or a bad option value."""


class BidegreeIOError(BidegreeError, OSError):
    """A file could not be read or written, or is malformed (``path:LINE: message``)."""


class InternalError(BidegreeError, RuntimeError):
    """A bug in bidegree (a caught panic of the Rust core). Please report it. The message
    says no more than that; the attribute ``detail`` holds the panic's text and location in the
    source, for the report."""


class IsolatedVerticesWarning(UserWarning):
    """Cage vertices that belong to no face were dropped from the output."""


class ObjWarning(UserWarning):
    """An OBJ file has statements or tags bidegree does not use (unknown statements, free-form
    geometry, OpenSubdiv tags other than crease, corner, interpolateboundary and creasemethod):
    they were skipped. One warning per kind, ``path:LINE:`` of the first one."""
