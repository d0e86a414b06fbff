"""The import path ``bidegree_blender.live`` of the batch before issue 15 (kept while the batch
is rebuilt; new code imports :mod:`.pipeline` and :class:`bidegree.options.Options`)."""

from __future__ import annotations

from typing import Any

import numpy as np
from bidegree.options import Options as Settings

from . import mesh_io, pipeline
from .pipeline import build_plan, check_geometry

__all__ = ["Settings", "build_plan", "check_geometry", "evaluate_surface", "write_full"]


def evaluate_surface(
    plan: Any, points: np.ndarray, settings: Settings
) -> tuple[np.ndarray, np.ndarray | None]:
    """:meth:`bidegree.options.Options.evaluate`."""
    return settings.evaluate(plan, points)


def write_full(
    mesh: Any,
    plan: Any,
    points: np.ndarray,
    cage: mesh_io.CageArrays,
    materials: list[Any] | None,
    normals: np.ndarray | None = None,
) -> None:
    """Write the surface of ``cage`` through ``plan`` with ``points`` (and ``normals``)."""
    surface = pipeline.plan_surface(plan, cage, Settings())
    surface.points, surface.normals = points, normals
    pipeline.write_surface(mesh, surface, cage, materials)
