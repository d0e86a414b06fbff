"""Live-update logic: plan cache, change detection and result writing.

This module is the GUI-free heart of the add-on's live result.  A
:class:`LiveCache` keeps, per key (normally the source object's
``session_uid``), the :class:`bidegree.Plan` built for the object's current
topology plus fingerprints of what the last update consumed:

* topology fingerprint (face sizes + corner vertices + crease data) and the
  subdivision settings -> a change rebuilds the plan;
* positions hash -> a change re-evaluates through the cached plan
  (``Plan.evaluate``) and only rewrites vertex positions;
* face data hash (UVs, material indices, flat/smooth, material list) -> a
  change rewrites the result mesh but keeps the plan;
* nothing changed -> no work at all.

The counters in :class:`LiveStats` let tests assert which path ran.
"""

from __future__ import annotations

import hashlib
import time
import warnings
from collections.abc import Callable, Hashable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, NamedTuple

import bidegree
import numpy as np

from . import mesh_io

if TYPE_CHECKING:  # pragma: no cover - typing only
    import bpy

#: What an update did.
BUILT = "built"  # a new plan was built and the result mesh fully written
REUSED = "reused"  # the cached plan evaluated new positions (positions only written)
REWRITTEN = "rewritten"  # cached plan, but face data (UVs, materials, ...) changed: full write
UNCHANGED = "unchanged"  # nothing changed, no work done


@dataclass(frozen=True)
class Settings:
    """Subdivision settings of one object (everything a plan depends on besides the cage)."""

    degree: int = 4
    levels: int = 2
    output: str = "primal"
    boundary: str = "edge-only"
    use_creases: bool = True
    memory_budget: int | None = None
    rules: str = "averaging"
    #: Output vertices on the limit surface (exact limit positions).
    limit: bool = False
    #: Limit normals as the result's custom normals (split at creases).
    normals: bool = False
    #: Adaptive subdivision (``levels`` is then the deepest level) drawn as triangles.
    adaptive: bool = False
    #: Flatness tolerance of the adaptive subdivision, relative to the cage's diagonal.
    tolerance: float = 1e-3


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


class _Fingerprints(NamedTuple):
    """What an update consumes, hashed: topology with the settings, positions, face data."""

    topology: tuple[str, Settings]
    positions: str
    face_data: str


@dataclass
class _Entry:
    plan: Any
    check: GeometryCheck
    topology: tuple[str, Settings]
    positions: str
    face_data: str
    mesh_name: str
    mesh_vertices: int
    result_faces: int


def face_data_fingerprint(cage: mesh_io.CageArrays, materials: list[Any] | None) -> str:
    """Hash of the per-face / per-corner data carried over to the result (not positions)."""
    h = hashlib.blake2b(digest_size=16)
    for name in sorted(cage.uv_maps):
        h.update(name.encode())
        h.update(np.ascontiguousarray(cage.uv_maps[name]).tobytes())
    h.update(repr(cage.active_uv).encode())
    for arr in (cage.material_index, cage.sharp_face):
        h.update(b"-" if arr is None else np.ascontiguousarray(arr).tobytes())
    h.update(repr([getattr(m, "name", None) for m in (materials or [])]).encode())
    return h.hexdigest()


class GeometryCheck:
    """Rejects non-finite positions and zero-area faces before they reach the core.

    The fan triangulation of the faces is precomputed once per topology, so a
    check of new positions is a handful of vectorised numpy operations.
    """

    def __init__(self, face_sizes: np.ndarray, corner_verts: np.ndarray) -> None:
        sizes = np.asarray(face_sizes, dtype=np.int64)
        starts = np.zeros(len(sizes), dtype=np.int64)
        if len(sizes):
            np.cumsum(sizes[:-1], out=starts[1:])
        ntri = np.maximum(sizes - 2, 0)
        self.num_faces = len(sizes)
        self.face_of_tri = np.repeat(np.arange(len(sizes)), ntri)
        local = np.arange(int(ntri.sum())) - np.repeat(np.cumsum(ntri) - ntri, ntri)
        first = starts[self.face_of_tri]
        self.v0 = corner_verts[first]
        self.v1 = corner_verts[first + local + 1]
        self.v2 = corner_verts[first + local + 2]

    def __call__(self, points: np.ndarray) -> None:
        """Raise on bad ``points``.

        Raises:
            bidegree.NonFiniteError: a position is NaN or infinite.
            bidegree.DegenerateFaceError: a face has (numerically) zero area.
        """
        finite = np.isfinite(points).all(axis=1)
        if not finite.all():
            bad = int(np.flatnonzero(~finite)[0])
            raise bidegree.NonFiniteError(f"vertex {bad} has a non-finite position")
        if self.num_faces == 0:
            return
        p0 = points[self.v0]
        cross = np.cross(points[self.v1] - p0, points[self.v2] - p0)
        tri_area = np.sqrt(np.einsum("ij,ij->i", cross, cross))
        area = np.bincount(self.face_of_tri, weights=tri_area, minlength=self.num_faces)
        extent = float((points.max(axis=0) - points.min(axis=0)).max()) if len(points) else 0.0
        degenerate = np.flatnonzero(area <= max(extent, 1e-30) ** 2 * 1e-12)
        if len(degenerate):
            raise bidegree.DegenerateFaceError(
                f"face {int(degenerate[0])} has zero area ({len(degenerate)} degenerate "
                "face(s)); merge or dissolve them (Mesh > Clean Up > Degenerate Dissolve)"
            )


def check_geometry(cage: mesh_io.CageArrays) -> None:
    """One-off :class:`GeometryCheck` of ``cage`` (see there for the errors raised)."""
    GeometryCheck(cage.face_sizes, cage.corner_verts)(cage.points)


def with_warnings(
    cage: mesh_io.CageArrays, settings: Settings, make: Callable[[bidegree.Mesh], Any]
) -> tuple[Any, list[str]]:
    """``make`` applied to ``cage`` as a :class:`bidegree.Mesh`, its warnings collected as text."""
    bmesh = mesh_io.to_bidegree_mesh(
        cage, boundary=settings.boundary, use_creases=settings.use_creases
    )
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        made = make(bmesh)
    return made, [str(w.message) for w in caught]


def build_plan(cage: mesh_io.CageArrays, settings: Settings) -> tuple[Any, list[str]]:
    """Build the :class:`bidegree.Plan` for ``cage`` and collect its warnings as text."""
    return with_warnings(
        cage,
        settings,
        lambda bmesh: bidegree.Plan(
            bmesh,
            degree=settings.degree,
            levels=settings.levels,
            output=settings.output,
            memory_budget=settings.memory_budget,
            rules=settings.rules,
        ),
    )


def evaluate_surface(
    plan: Any, points: np.ndarray, settings: Settings
) -> tuple[np.ndarray, np.ndarray | None]:
    """The result's points (refined, or limit positions with ``settings.limit``) and, with
    ``settings.normals``, its limit normals per face corner."""
    if settings.normals:
        positions, normals = plan.limit_surface(points)
        return (positions if settings.limit else plan.evaluate(points)), normals
    if settings.limit:
        return plan.limit_positions(points), None
    return plan.evaluate(points), None


def evaluate_uvs(plan: Any, cage: mesh_io.CageArrays) -> dict[str, np.ndarray]:
    """Linearly interpolate every UV map of ``cage`` through ``plan`` in a single pass."""
    if not cage.uv_maps:
        return {}
    names = list(cage.uv_maps)
    stacked = np.concatenate([cage.uv_maps[n] for n in names], axis=1)
    out = np.asarray(plan.evaluate_face_varying(stacked))
    return {n: out[:, 2 * i : 2 * i + 2] for i, n in enumerate(names)}


def write_full(
    mesh: bpy.types.Mesh,
    plan: Any,
    points: np.ndarray,
    cage: mesh_io.CageArrays,
    materials: list[Any] | None,
    normals: np.ndarray | None = None,
) -> None:
    """Write the full result (topology, positions, UVs, per-face data, custom normals) into
    ``mesh``."""
    mesh_io.write_mesh(
        mesh,
        points=points,
        face_sizes=plan.face_sizes,
        corner_verts=plan.face_indices,
        edges=plan.edges,
        corner_edges=plan.corner_edges,
        face_origin=plan.face_origin,
        cage=cage,
        uv_maps=evaluate_uvs(plan, cage),
        active_uv=cage.active_uv,
        materials=materials,
        normals=normals,
    )


def triangle_edges(triangles: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The edges (E, 2) of a triangle mesh and the edge of each corner (to the next corner)."""
    tris = np.asarray(triangles, dtype=np.int64).reshape(-1, 3)
    a = tris.reshape(-1)
    b = np.roll(tris, -1, axis=1).reshape(-1)
    keys = np.minimum(a, b) << 32 | np.maximum(a, b)
    unique, corner_edges = np.unique(keys, return_inverse=True)
    edges = np.stack([unique >> 32, unique & 0xFFFFFFFF], axis=-1)
    return edges.astype(np.int32), corner_edges.reshape(-1).astype(np.int32)


def write_adaptive(
    mesh: bpy.types.Mesh,
    result: Any,
    cage: mesh_io.CageArrays,
    materials: list[Any] | None,
) -> None:
    """Write an adaptive result (triangles; per-face data through ``face_origin``, no UVs)."""
    edges, corner_edges = triangle_edges(result.triangles)
    mesh_io.write_mesh(
        mesh,
        points=result.points,
        face_sizes=np.full(result.num_triangles, 3, dtype=np.int32),
        corner_verts=np.asarray(result.triangles, dtype=np.int32).reshape(-1),
        edges=edges,
        corner_edges=corner_edges,
        face_origin=result.face_origin,
        cage=cage,
        materials=materials,
    )


class LiveCache:
    """Per-object cache of subdivision plans for live updates."""

    def __init__(self) -> None:
        self._entries: dict[Hashable, _Entry] = {}
        self.stats = LiveStats()

    def __contains__(self, key: Hashable) -> bool:
        return key in self._entries

    def __len__(self) -> int:
        return len(self._entries)

    def plan(self, key: Hashable) -> Any | None:
        """The cached plan for ``key`` (or ``None``)."""
        entry = self._entries.get(key)
        return entry.plan if entry is not None else None

    def discard(self, key: Hashable) -> None:
        """Forget ``key`` (object removed or bidegree disabled)."""
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

    def invalidate(self, key: Hashable) -> None:
        """Force the next update of ``key`` to rewrite the result (keeps the plan)."""
        entry = self._entries.get(key)
        if entry is not None:
            entry.positions = ""
            entry.face_data = ""

    def update(
        self,
        key: Hashable,
        cage: mesh_io.CageArrays,
        settings: Settings,
        mesh: bpy.types.Mesh,
        *,
        materials: list[Any] | None = None,
    ) -> UpdateReport:
        """Bring ``mesh`` up to date with ``cage`` doing as little work as possible.

        On any error nothing is written: ``mesh`` keeps its previous contents and
        the exception (a :class:`bidegree.BidegreeError`) propagates.
        """
        t0 = time.perf_counter()
        try:
            prints = _Fingerprints(
                (cage.topology_fingerprint(use_creases=settings.use_creases), settings),
                cage.positions_hash(),
                face_data_fingerprint(cage, materials),
            )
            update = self._update_adaptive if settings.adaptive else self._update
            return update(key, cage, settings, mesh, materials, t0, prints)
        except Exception:
            self.stats.errors += 1
            raise

    def _update(
        self,
        key: Hashable,
        cage: mesh_io.CageArrays,
        settings: Settings,
        mesh: bpy.types.Mesh,
        materials: list[Any] | None,
        t0: float,
        prints: _Fingerprints,
    ) -> UpdateReport:
        topology, positions, face_data = prints
        entry = self._entries.get(key)
        same_mesh = (
            entry is not None
            and entry.mesh_name == mesh.name_full
            and entry.mesh_vertices == len(mesh.vertices)
        )
        notes: list[str] = []

        if entry is not None and entry.topology == topology and same_mesh:
            if entry.positions == positions and entry.face_data == face_data:
                self.stats.skips += 1
                return self._report(UNCHANGED, t0, cage, entry)
            entry.check(cage.points)
            points, normals = evaluate_surface(entry.plan, cage.points, settings)
            self.stats.plan_reuses += 1
            if entry.face_data == face_data:
                mesh_io.write_positions(mesh, points, normals)
                action = REUSED
            else:
                write_full(mesh, entry.plan, points, cage, materials, normals)
                self.stats.rewrites += 1
                action = REWRITTEN
        elif entry is not None and entry.topology == topology:
            # Same plan, but the result mesh was replaced or emptied behind our back.
            entry.check(cage.points)
            points, normals = evaluate_surface(entry.plan, cage.points, settings)
            self.stats.plan_reuses += 1
            write_full(mesh, entry.plan, points, cage, materials, normals)
            self.stats.rewrites += 1
            action = REWRITTEN
        else:
            check = GeometryCheck(cage.face_sizes, cage.corner_verts)
            check(cage.points)
            plan, notes = build_plan(cage, settings)
            points, normals = evaluate_surface(plan, cage.points, settings)
            write_full(mesh, plan, points, cage, materials, normals)
            self.stats.plan_builds += 1
            entry = _Entry(
                plan=plan,
                check=check,
                topology=topology,
                positions="",
                face_data="",
                mesh_name="",
                mesh_vertices=0,
                result_faces=int(plan.num_output_faces),
            )
            self._entries[key] = entry
            action = BUILT

        entry.positions = positions
        entry.face_data = face_data
        entry.mesh_name = mesh.name_full
        entry.mesh_vertices = len(mesh.vertices)
        report = self._report(action, t0, cage, entry)
        report.warnings = notes
        return report

    def _update_adaptive(
        self,
        key: Hashable,
        cage: mesh_io.CageArrays,
        settings: Settings,
        mesh: bpy.types.Mesh,
        materials: list[Any] | None,
        t0: float,
        prints: _Fingerprints,
    ) -> UpdateReport:
        """The adaptive result: where it refines depends on the positions, so any change of
        topology, settings, positions or face data recomputes it (there is no plan to keep)."""
        topology, positions, face_data = prints
        entry = self._entries.get(key)
        if (
            entry is not None
            and entry.topology == topology
            and entry.positions == positions
            and entry.face_data == face_data
            and entry.mesh_name == mesh.name_full
            and entry.mesh_vertices == len(mesh.vertices)
        ):
            self.stats.skips += 1
            return self._report(UNCHANGED, t0, cage, entry)
        unsupported = [
            name
            for name, asked in (
                ("classic rules", settings.rules != "averaging"),
                ("the dual output", settings.output != "primal"),
                ("limit positions", settings.limit),
                ("limit normals", settings.normals),
            )
            if asked
        ]
        if unsupported:
            raise bidegree.InvalidInputError(
                f"adaptive subdivision does not support {' or '.join(unsupported)}; "
                "turn Adaptive off or those settings off"
            )
        check = GeometryCheck(cage.face_sizes, cage.corner_verts)
        check(cage.points)
        result, notes = with_warnings(
            cage,
            settings,
            lambda bmesh: bidegree.subdivide_adaptive(
                bmesh,
                degree=settings.degree,
                max_level=settings.levels,
                tolerance=settings.tolerance,
                memory_budget=settings.memory_budget,
            ),
        )
        write_adaptive(mesh, result, cage, materials)
        self.stats.plan_builds += 1
        entry = _Entry(
            plan=None,
            check=check,
            topology=topology,
            positions=positions,
            face_data=face_data,
            mesh_name=mesh.name_full,
            mesh_vertices=len(mesh.vertices),
            result_faces=result.num_triangles,
        )
        self._entries[key] = entry
        report = self._report(BUILT, t0, cage, entry)
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
