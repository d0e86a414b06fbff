"""The subdivision options of one request, checked once, and the one place they become arguments.

:class:`Options` is what the command line, the Blender add-on, the batch converter and the USD
export all build (from their flags, modifier inputs or keyword arguments) and hand on; its methods
call :class:`bidegree.Plan`, :func:`bidegree.subdivide` and :func:`bidegree.subdivide_adaptive`
with every field, so no caller spreads settings into keyword arguments by hand (and none can drop
one)::

    options = Options(degree=3, levels=2, rules="classic", limit=True)
    result = options.subdivide(cage)            # or options.plan(cage) + options.evaluate(plan, P)

Bad values raise :class:`bidegree.InvalidInputError` (or the core's typed range errors when the
request is made), never a plain ``ValueError`` or ``TypeError``. Pure Python: no bpy.
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import operator
from dataclasses import dataclass
from typing import Any

import numpy as np

import bidegree

__all__ = ["Options"]

_CHOICES = {
    "output": ("primal", "dual"),
    "boundary": ("edge-only", "edge-and-corner", "none"),
    "rules": ("averaging", "classic"),
    "creasing": ("uniform", "chaikin"),
    "uv_mode": ("none", "corners-only", "corners-plus1", "corners-plus2", "boundaries", "all"),
}


def _integer(value: Any, name: str) -> int:
    if isinstance(value, bool):
        raise bidegree.InvalidInputError(f"{name} must be an integer, not a bool")
    try:
        return operator.index(value)
    except TypeError:
        raise bidegree.InvalidInputError(
            f"{name} must be an integer, not {type(value).__name__} {value!r}"
        ) from None


def _flag(value: Any, name: str) -> bool:
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    raise bidegree.InvalidInputError(f"{name} must be True or False, not {value!r}")


@dataclass(frozen=True)
class Options:
    """Everything a subdivision depends on besides the cage.

    Attributes:
        degree: averaging steps per level, ``1..=MAX_DEGREE`` (checked by the core).
        levels: refinement levels (the deepest level when ``adaptive``), ``0..=MAX_LEVELS``.
        output: ``"primal"`` (drawing mesh) or ``"dual"``.
        boundary: ``"edge-only"`` or ``"edge-and-corner"``; applied to cages built by a caller
            from its own data (Blender); an OBJ cage keeps its ``t interpolateboundary`` tag
            unless the caller overrides it.
        rules: ``"averaging"`` or ``"classic"``.
        creasing: ``"uniform"`` or ``"chaikin"`` (classic semi-sharp creases); ``None``: the
            mesh's own (an OBJ cage's ``t creasemethod`` tag, else uniform).
        use_creases: honour the cage's creases and corners (off: everything smooth).
        limit: output vertices on the limit surface.
        normals: limit normals per face corner.
        adaptive: adaptive triangles up to ``levels`` (``tolerance``) instead of uniform levels.
        tolerance: adaptive flatness tolerance relative to the cage's bounding-box diagonal.
        memory_budget: bytes a request may need (``None``: the core's default).
        uv_mode: how face-varying values (UVs) are subdivided: OpenSubdiv's six modes
            (``"none"``, ``"corners-only"``, ``"corners-plus1"``, ``"corners-plus2"``,
            ``"boundaries"``: Blender's default *Keep Boundaries*, ``"all"``: linear), see
            :meth:`bidegree.Plan.evaluate_face_varying`.
    """

    degree: int = 4
    levels: int = 2
    output: str = "primal"
    boundary: str = "edge-only"
    rules: str = "averaging"
    creasing: str | None = None
    use_creases: bool = True
    limit: bool = False
    normals: bool = False
    adaptive: bool = False
    tolerance: float = 1e-3
    memory_budget: int | None = None
    uv_mode: str = "boundaries"

    def __post_init__(self) -> None:
        set_field = object.__setattr__  # frozen: normalise once, here
        set_field(self, "degree", _integer(self.degree, "degree"))
        set_field(self, "levels", _integer(self.levels, "levels"))
        for name, allowed in _CHOICES.items():
            value = getattr(self, name)
            if value is None and name == "creasing":
                continue
            if not isinstance(value, str) or value not in allowed:
                choices = " or ".join(repr(c) for c in allowed)
                raise bidegree.InvalidInputError(f"{name} must be {choices}, not {value!r}")
        for name in ("use_creases", "limit", "normals", "adaptive"):
            set_field(self, name, _flag(getattr(self, name), name))
        if isinstance(self.tolerance, bool):
            raise bidegree.InvalidInputError("tolerance must be a number, not a bool")
        try:
            tolerance = float(self.tolerance)
        except (TypeError, ValueError):
            raise bidegree.InvalidInputError(
                f"tolerance must be a number, not {self.tolerance!r}"
            ) from None
        if not math.isfinite(tolerance) or tolerance < 0:
            raise bidegree.InvalidInputError(f"tolerance must be finite and >= 0, not {tolerance}")
        set_field(self, "tolerance", tolerance)
        if self.memory_budget is not None:
            budget = _integer(self.memory_budget, "memory_budget")
            if budget < 0:
                raise bidegree.InvalidInputError(f"memory_budget must be >= 0, not {budget}")
            set_field(self, "memory_budget", budget)

    def replace(self, **changes: Any) -> Options:
        """A copy with ``changes`` (checked again)."""
        return dataclasses.replace(self, **changes)

    @classmethod
    def from_namespace(cls, args: argparse.Namespace) -> Options:
        """The options of a parsed command line: every field that ``args`` has as an attribute
        (``max_level`` standing in for ``levels`` with ``--adaptive``)."""
        values = {
            field.name: getattr(args, field.name)
            for field in dataclasses.fields(cls)
            if getattr(args, field.name, None) is not None
        }
        if getattr(args, "adaptive", False) and getattr(args, "max_level", None) is not None:
            values["levels"] = args.max_level
        return cls(**values)

    # ----------------------------------------------------------------------------- requests

    def has_limit_positions(self) -> bool:
        """Whether the uniform surface of these options has limit positions (the core refuses
        ``limit`` otherwise): the primal output, and with classic rules degree 3 (OpenSubdiv's
        masks) from level 1 on."""
        if self.output != "primal":
            return False
        return self.rules == "averaging" or (self.degree == 3 and self.levels > 0)

    def unsupported_by_adaptive(self) -> list[str]:
        """The settings adaptive subdivision cannot honour (empty when it can)."""
        return [
            name
            for name, asked in (
                ("classic rules", self.rules != "averaging"),
                ("the dual output", self.output != "primal"),
                ("limit positions", self.limit),
                ("limit normals", self.normals),
            )
            if asked
        ]

    def _request(self) -> dict[str, Any]:
        """The keyword arguments :class:`bidegree.Plan` and :func:`bidegree.subdivide` share."""
        return {
            "degree": self.degree,
            "levels": self.levels,
            "output": self.output,
            "memory_budget": self.memory_budget,
            "rules": self.rules,
            "creasing": self.creasing,
        }

    def plan(self, mesh: bidegree.Mesh) -> bidegree.Plan:
        """The :class:`bidegree.Plan` of ``mesh`` with these options (uniform levels)."""
        return bidegree.Plan(mesh, **self._request())

    def evaluate(
        self,
        plan: bidegree.Plan,
        points: np.ndarray,
        normals_domain: bidegree.NormalDomain = "corner",
    ) -> tuple[np.ndarray, np.ndarray | None]:
        """The output points of ``points`` through ``plan`` (refined, or limit positions with
        ``limit``) and, with ``normals``, the limit normals per output face corner (per output
        vertex with ``normals_domain="vertex"``, see :meth:`bidegree.Plan.limit_surface`)."""
        if self.normals:
            positions, normals = plan.limit_surface(points, normals=normals_domain)
            return (positions if self.limit else plan.evaluate(points)), normals
        if self.limit:
            return plan.limit_positions(points), None
        return plan.evaluate(points), None

    def evaluate_face_varying(self, plan: bidegree.Plan, values: Any) -> Any:
        """Face-varying ``values`` (one array per corner, or a mapping of them) through ``plan``
        in ``uv_mode``, on the limit surface with ``limit``."""
        return plan.evaluate_face_varying(values, self.uv_mode, limit=self.limit)  # type: ignore[arg-type]

    def subdivide(self, mesh: bidegree.Mesh) -> bidegree.Result:
        """:func:`bidegree.subdivide` of ``mesh`` (uniform levels) with these options."""
        return bidegree.subdivide(
            mesh,
            **self._request(),
            limit=self.limit,
            normals=self.normals,
            uv_mode=self.uv_mode,  # type: ignore[arg-type]
        )

    def subdivide_adaptive(
        self,
        mesh: bidegree.Mesh,
        *,
        vertex_values: Any = None,
        face_varying: Any = None,
    ) -> bidegree.AdaptiveResult:
        """:func:`bidegree.subdivide_adaptive` of ``mesh`` up to ``levels``, the mesh's uvs and
        ``face_varying`` in ``uv_mode``, with ``vertex_values`` (see there).

        Raises:
            bidegree.InvalidInputError: a setting adaptive subdivision does not support.
        """
        unsupported = self.unsupported_by_adaptive()
        if unsupported:
            raise bidegree.InvalidInputError(
                f"adaptive subdivision does not support {' or '.join(unsupported)}"
            )
        return bidegree.subdivide_adaptive(
            mesh,
            degree=self.degree,
            max_level=self.levels,
            tolerance=self.tolerance,
            memory_budget=self.memory_budget,
            uv_mode=self.uv_mode,  # type: ignore[arg-type]
            vertex_values=vertex_values,
            face_varying=face_varying,
        )

    def estimate(self, mesh: bidegree.Mesh) -> dict[str, int]:
        """:func:`bidegree.estimate` of the uniform request (adaptive stays below it)."""
        return bidegree.estimate(
            mesh,
            self.degree,
            self.levels,
            self.output,  # type: ignore[arg-type]
        )
