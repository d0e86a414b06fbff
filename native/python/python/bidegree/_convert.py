"""Argument checking and conversion for the ``bidegree`` API: Python values and numpy arrays
into the C-contiguous arrays and plain values the extension ``bidegree._native`` accepts (no
per-element Python work except for inputs that are Python lists), with the API's error messages.
"""

from __future__ import annotations

import contextlib
import operator
import os
import sys
import warnings
from collections.abc import Iterator
from typing import Any, Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ._errors import (
    IndexOutOfRangeError,
    InvalidInputError,
    IsolatedVerticesWarning,
    MemoryBudgetError,
)

Output = Literal["primal", "dual"]
Boundary = Literal["edge-only", "edge-and-corner", "none"]
Rules = Literal["averaging", "classic"]
Creasing = Literal["uniform", "chaikin"]
UvMode = Literal["none", "corners-only", "corners-plus1", "corners-plus2", "boundaries", "all"]
NormalDomain = Literal["corner", "vertex"]
FloatArray = NDArray[np.float32] | NDArray[np.float64]

OUTPUTS = ("primal", "dual")
BOUNDARIES = ("edge-only", "edge-and-corner", "none")
RULES = ("averaging", "classic")
CREASING = ("uniform", "chaikin")
#: OpenSubdiv's face-varying modes (``FVarLinearInterpolation``), smoothest first.
UV_MODES = ("none", "corners-only", "corners-plus1", "corners-plus2", "boundaries", "all")
NORMAL_DOMAINS = ("corner", "vertex")
_INT64_MIN, _INT64_MAX = -(2**63), 2**63 - 1


@contextlib.contextmanager
def memory_errors() -> Iterator[None]:
    """numpy's (or Python's) ``MemoryError`` inside an API call, an array that could not be
    allocated, raised as ``MemoryBudgetError`` like the core's own refusals. Used as a decorator
    on the public entry points."""
    try:
        yield
    except MemoryError as exc:
        what = str(exc) or "an array could not be allocated"
        raise MemoryBudgetError(f"out of memory: {what}") from exc


def float_array(values: ArrayLike, what: str) -> FloatArray:
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


def int_array(values: ArrayLike, what: str) -> NDArray[np.int64]:
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


def readonly(array: np.ndarray) -> np.ndarray:
    """``array``, made read-only (arrays bidegree hands out and shares)."""
    array.setflags(write=False)
    return array


def owned(array: np.ndarray, source: Any) -> np.ndarray:
    """``array`` as an array that shares no memory with the caller's ``source``."""
    if isinstance(source, np.ndarray) and np.shares_memory(array, source):
        return array.copy()
    return array


def int_arg(value: Any, what: str) -> int:
    """An integer option (numpy integers accepted), clamped to int64 for the core."""
    if isinstance(value, bool):
        raise InvalidInputError(f"{what} must be an integer, not a bool")
    try:
        number = operator.index(value)
    except TypeError:
        raise InvalidInputError(f"{what} must be an integer, not {type(value).__name__}") from None
    return min(max(number, _INT64_MIN), _INT64_MAX)


def choice(value: Any, choices: tuple[str, ...], what: str) -> str:
    """``value`` if it is one of the strings ``choices``."""
    if not isinstance(value, str) or value not in choices:
        allowed = " or ".join(repr(c) for c in choices)
        raise InvalidInputError(f"{what} must be {allowed}, not {value!r}")
    return value


def budget(value: int | None, what: str = "memory_budget") -> int | None:
    """A byte count (a memory budget, an input limit; None: the core's default), clamped to
    u64."""
    if value is None:
        return None
    number = int_arg(value, what)
    if number < 0:
        raise InvalidInputError(f"{what} must be >= 0, not {number}")
    return min(number, 2**64 - 1)


def sharpness(values: ArrayLike, count: int, what: str) -> NDArray[np.float32]:
    """``count`` sharpness values of creases or corners (one value is repeated), float32."""
    try:
        array = np.asarray(values, dtype=np.float32)
    except (TypeError, ValueError) as exc:
        raise InvalidInputError(f"{what} sharpness must be numbers: {exc}") from None
    if array.ndim == 0:
        array = np.full(count, array, dtype=np.float32)
    if array.shape != (count,):
        raise InvalidInputError(
            f"{what} sharpness must have shape ({count},) (one per {what}), not {array.shape}"
        )
    return np.array(array, dtype=np.float32, order="C")


def pair(value: Any, what: str) -> tuple[Any, Any]:
    """The two parts of a ``(indices, sharpness)`` argument."""
    try:
        first, second = value
    except (TypeError, ValueError):
        raise InvalidInputError(
            f"{what} must be a pair (indices, sharpness), not {type(value).__name__}"
        ) from None
    return first, second


def values_2d(values: ArrayLike, rows: int, what: str, expected: str) -> tuple[FloatArray, bool]:
    """``values`` as a (rows, C) float array; a 1-D input counts as C = 1 (flag returned)."""
    array = float_array(values, what)
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


def face_varying_indices(
    indices: ArrayLike, corners: int, num_values: int, what: str
) -> NDArray[np.uint32]:
    """One index per face corner into ``num_values`` face-varying values (OpenSubdiv's index
    buffer, OBJ's ``vt`` indices), as the uint32 array the core reads."""
    array = int_array(indices, what)
    if array.ndim != 1 or len(array) != corners:
        raise InvalidInputError(
            f"{what} must have one index per face corner ({corners}), not shape {array.shape}"
        )
    bad = np.flatnonzero((array < 0) | (array >= num_values))
    if len(bad):
        error = IndexOutOfRangeError(
            f"{what}: face corner {bad[0]} has index {array[bad[0]]}, out of range "
            f"[0, {num_values})"
        )
        error.what, error.index, error.num_vertices = what, int(array[bad[0]]), num_values
        raise error
    return np.ascontiguousarray(array, dtype=np.uint32)


def tolerance(value: Any) -> float:
    """An adaptive flatness tolerance: a finite number >= 0."""
    if isinstance(value, bool):
        raise InvalidInputError("tolerance must be a number, not a bool")
    try:
        number = float(value)
    except (TypeError, ValueError):
        raise InvalidInputError(f"tolerance must be a number, not {type(value).__name__}") from None
    if not np.isfinite(number) or number < 0:
        raise InvalidInputError(f"tolerance must be finite and >= 0, not {value!r}")
    return number


def warn_at_caller(message: str, category: type[Warning]) -> None:
    """``warnings.warn`` pointing at the first frame outside this package (and outside
    ``contextlib``, whose decorator wraps the entry points), so the warning names the user's line
    however deep inside the API it was raised."""
    package = os.path.dirname(os.path.abspath(__file__))
    skipped = (package + os.sep, os.path.abspath(contextlib.__file__))
    frame = sys._getframe(1)
    level = 2  # stacklevel 1 is this function, 2 its caller
    while frame is not None and os.path.abspath(frame.f_code.co_filename).startswith(skipped):
        frame = frame.f_back
        level += 1
    warnings.warn(message, category, stacklevel=level)


def warn_isolated(isolated: NDArray[np.int32]) -> None:
    """Warns that the cage vertices ``isolated`` (in no face) are dropped from the output."""
    if len(isolated):
        shown = ", ".join(str(v) for v in isolated[:10])
        more = ", ..." if len(isolated) > 10 else ""
        warn_at_caller(
            f"{len(isolated)} isolated vertices (in no face) are dropped from the output: "
            f"[{shown}{more}]",
            IsolatedVerticesWarning,
        )
