"""The plan cache of live surfaces: do only the work a change needs.

A :class:`LiveCache` keeps, per key (an object's modifier and variant, see
:func:`bidegree_blender.modifier.cache_key`), the :class:`bidegree.Plan` built for the cage's
current topology and fingerprints of what the last update consumed:

* topology (face sizes, corner vertices, crease data) with the options -> a change rebuilds the
  plan and rewrites the mesh;
* positions -> a change re-evaluates through the cached plan and rewrites positions only;
* face and corner data (UV maps, material indices, flat/smooth, materials, vertex group
  weights, every other attribute) -> a change keeps the plan and rewrites the mesh;
* nothing changed -> no work at all.

The work itself is :mod:`bidegree_blender.pipeline`'s; the counters in :class:`LiveStats` let
tests assert which path ran.
"""

from __future__ import annotations

import hashlib
import time
from collections.abc import Callable, Hashable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import bidegree
import numpy as np
from bidegree.options import Options

from . import mesh_io, pipeline

if TYPE_CHECKING:  # pragma: no cover - typing only
    import bpy

#: What an update did.
BUILT = "built"  # a new plan was built (or an adaptive surface computed) and the mesh written
REUSED = "reused"  # the cached plan evaluated new positions (positions only written)
REWRITTEN = "rewritten"  # cached plan, but face data (UVs, materials, ...) changed: full write
UNCHANGED = "unchanged"  # nothing changed, no work done


@dataclass
class LiveStats:
    """Counters of what :meth:`LiveCache.update` did (for tests and the status line)."""

    plan_builds: int = 0
    plan_reuses: int = 0
    rewrites: int = 0
    skips: int = 0
    errors: int = 0


@dataclass
class UpdateReport:
    """Outcome of one :meth:`LiveCache.update` call."""

    action: str
    seconds: float
    cage_faces: int
    result_faces: int
    result_vertices: int
    warnings: list[str] = field(default_factory=list)


@dataclass
class _Entry:
    plan: bidegree.Plan | None  # None for an adaptive surface (it depends on the positions)
    check: pipeline.GeometryCheck
    topology: tuple[str, Options]
    positions: str
    face_data: str
    mesh_name: str
    mesh_vertices: int
    result_faces: int


def face_data_fingerprint(cage: mesh_io.CageArrays, materials: list[Any] | None) -> str:
    """Hash of the per-face / per-corner / weight data carried to the result (not positions)."""
    h = hashlib.blake2b(digest_size=16)
    for group in (cage.uv_maps, cage.vertex_groups):
        for name, values in group.items():
            h.update(name.encode())
            h.update(np.ascontiguousarray(values).tobytes())
    cage.attributes.fingerprint(h.update)
    h.update(repr(cage.active_uv).encode())
    for arr in (cage.material_index, cage.sharp_face):
        h.update(b"-" if arr is None else np.ascontiguousarray(arr).tobytes())
    h.update(repr([getattr(m, "name", None) for m in (materials or [])]).encode())
    return h.hexdigest()


class LiveCache:
    """Per-key cache of subdivision plans for live updates."""

    def __init__(self) -> None:
        self._entries: dict[Hashable, _Entry] = {}
        self.stats = LiveStats()

    def __contains__(self, key: Hashable) -> bool:
        return key in self._entries

    def __len__(self) -> int:
        return len(self._entries)

    def plan(self, key: Hashable) -> bidegree.Plan | None:
        """The cached plan for ``key`` (or ``None``)."""
        entry = self._entries.get(key)
        return entry.plan if entry is not None else None

    def discard(self, key: Hashable) -> None:
        """Forget ``key`` (modifier removed, or its surface cleared)."""
        self._entries.pop(key, None)

    def clear(self) -> None:
        """Forget every cached plan."""
        self._entries.clear()

    def keys(self) -> list[Hashable]:
        """The keys with a cached plan."""
        return list(self._entries)

    def retain(self, keep: Callable[[Hashable], bool]) -> int:
        """Forget the plans whose key ``keep`` rejects (e.g. deleted objects); returns how many."""
        gone = [key for key in self._entries if not keep(key)]
        for key in gone:
            del self._entries[key]
        return len(gone)

    def update(
        self,
        key: Hashable,
        cage: mesh_io.CageArrays,
        options: Options,
        mesh: bpy.types.Mesh,
        *,
        materials: list[Any] | None = None,
        holder: bpy.types.Object | None = None,
    ) -> UpdateReport:
        """Bring ``mesh`` (the mesh of ``holder``, if given: it gets the vertex groups) up to
        date with ``cage`` doing as little work as possible.

        On any error nothing is written: ``mesh`` keeps its previous contents, the entry is
        forgotten and the exception (a :class:`bidegree.BidegreeError`) propagates.
        """
        t0 = time.perf_counter()
        topology = (cage.topology_fingerprint(use_creases=options.use_creases), options)
        positions = cage.positions_hash()
        face_data = face_data_fingerprint(cage, materials)
        entry = self._entries.get(key)
        same_mesh = (
            entry is not None
            and entry.mesh_name == mesh.name_full
            and entry.mesh_vertices == len(mesh.vertices)
        )
        notes: list[str] = []
        try:
            if entry is not None and entry.topology == topology and same_mesh:
                if entry.positions == positions and entry.face_data == face_data:
                    self.stats.skips += 1
                    return self._report(UNCHANGED, t0, cage, entry)
            if entry is not None and entry.topology == topology and entry.plan is not None:
                entry.check(cage.points)
                full = not same_mesh or entry.face_data != face_data
                surface = pipeline.plan_surface(entry.plan, cage, options, with_attributes=full)
                self.stats.plan_reuses += 1
                if full:
                    pipeline.write_surface(mesh, surface, cage, materials, holder=holder)
                    self.stats.rewrites += 1
                    action = REWRITTEN
                else:
                    pipeline.write_positions(mesh, surface)
                    action = REUSED
            else:
                # New topology or options, or an adaptive surface (where it refines depends on
                # the positions: there is no plan to keep).
                self._entries.pop(key, None)
                check = pipeline.GeometryCheck(cage.face_sizes, cage.corner_verts)
                check(cage.points)
                plan = None
                if options.adaptive:
                    surface, notes = pipeline.adaptive_surface(cage, options)
                else:
                    plan, notes = pipeline.build_plan(cage, options)
                    surface = pipeline.plan_surface(plan, cage, options)
                pipeline.write_surface(mesh, surface, cage, materials, holder=holder)
                self.stats.plan_builds += 1
                entry = _Entry(
                    plan=plan,
                    check=check,
                    topology=topology,
                    positions="",
                    face_data="",
                    mesh_name="",
                    mesh_vertices=0,
                    result_faces=surface.num_faces,
                )
                self._entries[key] = entry
                action = BUILT
        except Exception:
            self.stats.errors += 1
            self._entries.pop(key, None)
            raise
        entry.positions = positions
        entry.face_data = face_data
        entry.mesh_name = mesh.name_full
        entry.mesh_vertices = len(mesh.vertices)
        report = self._report(action, t0, cage, entry)
        report.warnings = notes
        return report

    @staticmethod
    def _report(action: str, t0: float, cage: mesh_io.CageArrays, entry: _Entry) -> UpdateReport:
        return UpdateReport(
            action=action,
            seconds=time.perf_counter() - t0,
            cage_faces=cage.num_faces,
            result_faces=entry.result_faces,
            result_vertices=entry.mesh_vertices,
        )
