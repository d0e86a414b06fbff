"""The pure pipeline of the Blender layer: a cage read from Blender in, a surface written out.

``read`` (an evaluated object into :class:`mesh_io.CageArrays`) -> ``check`` (geometry) ->
``plan`` -> ``evaluate`` (a :class:`Surface`: every array the result mesh needs) -> ``write``
(into a ``bpy.types.Mesh``). Nothing here caches, registers or keeps state: the live modifier
(:mod:`bidegree_blender.modifier`, through :mod:`bidegree_blender.cache`), the batch, the USD
export and :func:`subdivide_object` all run these same steps with one
:class:`bidegree.options.Options`.
"""

from __future__ import annotations

import warnings
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import bidegree
import numpy as np
from bidegree.options import Options

from . import attributes, mesh_io

if TYPE_CHECKING:  # pragma: no cover - typing only
    import bpy

__all__ = [
    "GeometryCheck",
    "Surface",
    "adaptive_surface",
    "build_plan",
    "cage_mesh",
    "check_geometry",
    "evaluated_cage",
    "object_materials",
    "plan_surface",
    "subdivide_cage",
    "subdivide_object",
    "write_positions",
    "write_surface",
]


def object_materials(obj: bpy.types.Object) -> list[Any]:
    """Materials of ``obj``'s slots in order (object-linked slots included)."""
    return [slot.material for slot in obj.material_slots]


def evaluated_cage(
    obj: bpy.types.Object,
    *,
    depsgraph: bpy.types.Depsgraph | None = None,
    use_creases: bool = True,
) -> mesh_io.CageArrays:
    """Read ``obj``'s evaluated mesh (as ``depsgraph`` evaluated it) into numpy arrays, with
    the weights of its vertex groups.

    The temporary evaluated mesh is freed before returning.

    Raises:
        bidegree.InvalidInputError: ``obj`` is not a mesh object.
        bidegree.EmptyMeshError: the evaluated mesh has no vertices or no faces.
    """
    import bpy

    if not isinstance(obj, bpy.types.Object) or obj.type != "MESH":
        kind = getattr(obj, "type", type(obj).__name__)
        raise bidegree.InvalidInputError(
            f"{getattr(obj, 'name', obj)!r} is not a mesh object (type {kind})"
        )
    if depsgraph is None:
        depsgraph = bpy.context.evaluated_depsgraph_get()
    eval_obj = obj.evaluated_get(depsgraph)
    tmp = eval_obj.to_mesh()
    try:
        cage = mesh_io.read_mesh(tmp, use_creases=use_creases)
        cage.attributes = attributes.read_attributes(tmp, set(cage.uv_maps))
        names = [group.name for group in eval_obj.vertex_groups]
        if names:
            cage.vertex_groups = mesh_io.read_vertex_groups(tmp, names)
    finally:
        eval_obj.to_mesh_clear()
    mesh_io.check_cage(cage)
    return cage


class GeometryCheck:
    """Rejects non-finite positions before they reach the core (zero-area faces are fine: they
    are subdivided, as Blender's modifier does). Cheap enough for every frame of an animation.
    """

    def __init__(self, face_sizes: np.ndarray, corner_verts: np.ndarray) -> None:
        self.num_faces = len(face_sizes)

    def __call__(self, points: np.ndarray) -> None:
        """Raise on bad ``points``.

        Raises:
            bidegree.NonFiniteError: a position is NaN or infinite.
        """
        finite = np.isfinite(points).all(axis=1)
        if not finite.all():
            bad = int(np.flatnonzero(~finite)[0])
            raise bidegree.NonFiniteError(f"vertex {bad} has a non-finite position")


def check_geometry(cage: mesh_io.CageArrays) -> None:
    """One-off :class:`GeometryCheck` of ``cage`` (see there for the errors raised)."""
    GeometryCheck(cage.face_sizes, cage.corner_verts)(cage.points)


def cage_mesh(cage: mesh_io.CageArrays, options: Options) -> bidegree.Mesh:
    """``cage`` as a :class:`bidegree.Mesh` with the boundary rule and creases of ``options``."""
    return mesh_io.to_bidegree_mesh(
        cage, boundary=options.boundary, use_creases=options.use_creases
    )


def _with_warnings(make: Callable[[], Any]) -> tuple[Any, list[str]]:
    """``make()`` with its warnings (isolated vertices, ...) collected as text."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        made = make()
    return made, [str(w.message) for w in caught]


def build_plan(cage: mesh_io.CageArrays, options: Options) -> tuple[bidegree.Plan, list[str]]:
    """The :class:`bidegree.Plan` of ``cage`` and the warnings building it gave."""
    return _with_warnings(lambda: options.plan(cage_mesh(cage, options)))


@dataclass
class Surface:
    """Every array of a subdivided surface that is written into a Blender mesh.

    Point data is per output vertex, corner data per output face corner (in the order of
    ``corner_verts``), face data is carried from the cage through ``face_origin``.
    """

    points: np.ndarray
    face_sizes: np.ndarray
    corner_verts: np.ndarray
    edges: np.ndarray
    corner_edges: np.ndarray
    face_origin: np.ndarray
    #: Custom normals (the limit normals, or the cage's carried over), or ``None``.
    normals: np.ndarray | None = None
    #: Where ``normals`` are: ``"CORNER"`` (per face corner) or ``"POINT"`` (per vertex).
    normals_domain: str = "CORNER"
    #: UV map name -> (corners, 2).
    uv_maps: dict[str, np.ndarray] = field(default_factory=dict)
    #: Vertex group name -> (points,) weights (every group of the cage, in its order).
    vertex_groups: dict[str, np.ndarray] = field(default_factory=dict)
    #: Every other attribute of the cage on the surface (:mod:`.attributes`).
    attributes: attributes.SurfaceAttributes = field(
        default_factory=lambda: attributes.SurfaceAttributes([])
    )

    @property
    def num_faces(self) -> int:
        """Faces of the surface."""
        return len(self.face_sizes)


def _plan_uv_maps(
    plan: bidegree.Plan, cage: mesh_io.CageArrays, options: Options
) -> dict[str, np.ndarray]:
    """Every UV map of ``cage`` through ``plan`` (face-varying in the options' mode, on
    Blender's UV topology: :meth:`.mesh_io.CageArrays.uv_indices`), in one pass."""
    if not cage.uv_maps:
        return {}
    return attributes.face_varying(plan, cage.uv_sets(), options.uv_mode)


def plan_vertex_groups(plan: bidegree.Plan, cage: mesh_io.CageArrays) -> dict[str, np.ndarray]:
    """Every vertex group of ``cage`` through ``plan`` (the scheme applied to the weights, like
    positions), clamped to Blender's ``[0, 1]``."""
    if not cage.vertex_groups:
        return {}
    names = list(cage.vertex_groups)
    stacked = np.stack([cage.vertex_groups[n] for n in names], axis=1)
    out = np.clip(np.asarray(plan.evaluate(stacked)), 0.0, 1.0)
    return {n: out[:, i] for i, n in enumerate(names)}


def plan_surface(
    plan: bidegree.Plan,
    cage: mesh_io.CageArrays,
    options: Options,
    *,
    with_attributes: bool = True,
) -> Surface:
    """The :class:`Surface` of ``cage`` through ``plan`` (``with_attributes=False``: points and
    normals only, for a positions-only update of a mesh that has the rest). Normals: the limit
    normals with ``options.normals``, else the cage's custom normals carried over (they follow
    the positions), else none. The limit normals are per vertex where that is exact (no split
    vertex, :attr:`bidegree.Plan.limit_normals_split`) and Blender stores them so (5.0 on):
    a quarter of the corners' bytes, and Blender draws them without corner normals."""
    per_vertex = options.normals and mesh_io.point_normals() and not plan.limit_normals_split
    points, normals = options.evaluate(plan, cage.points, "vertex" if per_vertex else "corner")
    if normals is None and cage.attributes.custom_normals is not None:
        normals = attributes.custom_normals(plan, cage.attributes.custom_normals)
    surface = Surface(
        points=points,
        face_sizes=plan.face_sizes,
        corner_verts=plan.face_indices,
        edges=plan.edges,
        corner_edges=plan.corner_edges,
        face_origin=plan.face_origin,
        normals=normals,
        normals_domain="POINT" if per_vertex else "CORNER",
    )
    if with_attributes:
        surface.uv_maps = _plan_uv_maps(plan, cage, options)
        surface.vertex_groups = plan_vertex_groups(plan, cage)
        surface.attributes = attributes.transfer(
            plan,
            cage,
            cage.attributes,
            uv_mode=options.uv_mode,
            use_creases=options.use_creases,
        )
    return surface


def triangle_edges(triangles: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The edges (E, 2) of a triangle mesh and the edge of each corner (to the next corner)."""
    tris = np.asarray(triangles, dtype=np.int64).reshape(-1, 3)
    a = tris.reshape(-1)
    b = np.roll(tris, -1, axis=1).reshape(-1)
    keys = np.minimum(a, b) << 32 | np.maximum(a, b)
    unique, corner_edges = np.unique(keys, return_inverse=True)
    edges = np.stack([unique >> 32, unique & 0xFFFFFFFF], axis=-1)
    return edges.astype(np.int32), corner_edges.reshape(-1).astype(np.int32)


def adaptive_surface(cage: mesh_io.CageArrays, options: Options) -> tuple[Surface, list[str]]:
    """The adaptive :class:`Surface` of ``cage`` (triangles): UV maps and corner floats in the
    options' UV mode, vertex group weights and point floats through the same levels as the
    points, custom normals (linear, renormalized; the limit normals of ``options.normals``
    are not available on adaptive output), face data through ``face_origin``, edge data on
    the triangle edges along their cage edge, integers and booleans from the quadrant's cage
    corner, vertex creases on the cage vertices' own output vertices
    (:func:`attributes.adaptive_attributes`)."""
    bmesh = cage_mesh(cage, options)
    points, sets = attributes.adaptive_request(cage, options.uv_mode)
    for name, (uv, indices) in cage.uv_sets().items():
        sets[f"uv:{name}"] = (uv, options.uv_mode, indices)
    groups = list(cage.vertex_groups)
    columns = [cage.vertex_groups[n].reshape(-1, 1) for n in groups]
    columns += [a.values.reshape(len(a.values), -1) for a in points]
    stacked = np.concatenate(columns, axis=1) if columns else None
    result, notes = _with_warnings(
        lambda: options.subdivide_adaptive(bmesh, vertex_values=stacked, face_varying=sets)
    )
    edges, corner_edges = triangle_edges(result.triangles)
    values = result.vertex_values
    point_values = values[:, len(groups) :] if values is not None else None
    surface_attributes, normals = attributes.adaptive_attributes(
        result, cage, points, point_values, corner_edges, use_creases=options.use_creases
    )
    surface = Surface(
        points=result.points,
        face_sizes=np.full(result.num_triangles, 3, dtype=np.int32),
        corner_verts=np.asarray(result.triangles, dtype=np.int32).reshape(-1),
        edges=edges,
        corner_edges=corner_edges,
        face_origin=result.face_origin,
        normals=normals,
        uv_maps={
            name: result.face_varying[f"uv:{name}"].astype(np.float32) for name in cage.uv_maps
        },
        attributes=surface_attributes,
    )
    if groups and values is not None:
        weights = np.clip(values[:, : len(groups)], 0.0, 1.0).astype(np.float32)
        surface.vertex_groups = {n: weights[:, i] for i, n in enumerate(groups)}
    return surface, notes


def subdivide_cage(cage: mesh_io.CageArrays, options: Options) -> tuple[Surface, list[str]]:
    """Check ``cage`` and subdivide it with ``options`` (uniform or adaptive), no cache."""
    check_geometry(cage)
    if options.adaptive:
        return adaptive_surface(cage, options)
    plan, notes = build_plan(cage, options)
    return plan_surface(plan, cage, options), notes


def write_surface(
    mesh: bpy.types.Mesh,
    surface: Surface,
    cage: mesh_io.CageArrays,
    materials: list[Any] | None,
    *,
    holder: bpy.types.Object | None = None,
) -> None:
    """Replace ``mesh``'s geometry with ``surface`` (topology, positions, UV maps, face data
    of the cage through ``face_origin``, custom normals; vertex groups need the object that
    holds ``mesh``, ``holder``)."""
    mesh_io.write_mesh(
        mesh,
        points=surface.points,
        face_sizes=surface.face_sizes,
        corner_verts=surface.corner_verts,
        edges=surface.edges,
        corner_edges=surface.corner_edges,
        face_origin=surface.face_origin,
        cage=cage,
        uv_maps=surface.uv_maps,
        active_uv=cage.active_uv,
        materials=materials,
        normals=surface.normals,
        normals_domain=surface.normals_domain,
    )
    attributes.write_attributes(mesh, surface.attributes)
    if holder is not None:
        mesh_io.write_vertex_groups(holder, surface.vertex_groups)


def write_positions(mesh: bpy.types.Mesh, surface: Surface) -> None:
    """Overwrite the positions (and custom normals) of ``mesh``, which has ``surface``'s
    topology already."""
    mesh_io.write_positions(mesh, surface.points, surface.normals, surface.normals_domain)


def subdivide_object(
    obj: bpy.types.Object,
    degree: int = 4,
    levels: int = 2,
    output: str = "primal",
    boundary: str = "edge-only",
    use_creases: bool = True,
    depsgraph: bpy.types.Depsgraph | None = None,
    *,
    name: str | None = None,
    memory_budget: int | None = None,
    rules: str = "averaging",
    limit: bool = False,
    normals: bool = False,
    uv_mode: str = "boundaries",
    options: Options | None = None,
) -> bpy.types.Mesh:
    """Subdivide ``obj``'s evaluated mesh and return a new mesh datablock.

    Modifiers of ``obj`` are honoured (the evaluated mesh is used). Materials, per-face
    material indices, flat/smooth shading (through ``face_origin``), every UV map
    (face-varying in ``uv_mode``, default Blender's *Keep Boundaries*) and every other attribute
    (:mod:`bidegree_blender.attributes`) carry over; edge and vertex creases shape the surface
    (sharpness ``10 * c**2``). ``limit`` puts the vertices on the limit surface, ``normals``
    writes its limit normals as custom normals. ``options`` (a
    :class:`bidegree.options.Options`) replaces every keyword setting at once.

    Raises:
        bidegree.BidegreeError: a subclass describing bad input (not a mesh object, no
            vertices or faces, non-manifold edge, loose edges, zero-area face, a setting of
            the wrong type, degree/level out of range, memory budget, ...). Nothing is
            created and ``obj`` is untouched.
    """
    import bpy

    if options is None:
        options = Options(
            degree=degree,
            levels=levels,
            output=output,
            boundary=boundary,
            use_creases=use_creases,
            memory_budget=memory_budget,
            rules=rules,
            limit=limit,
            normals=normals,
            uv_mode=uv_mode,
        )
    cage = evaluated_cage(obj, depsgraph=depsgraph, use_creases=options.use_creases)
    surface, _notes = subdivide_cage(cage, options)
    mesh = bpy.data.meshes.new(name or f"{obj.name}_bidegree")
    try:
        write_surface(mesh, surface, cage, object_materials(obj))
    except BaseException:
        bpy.data.meshes.remove(mesh)
        raise
    return mesh
