"""Every Blender attribute of the cage on the surface (issue 14): read, transfer, write.

What each domain does (Blender's Subdivision Surface, ``subdiv_mesh.cc``, is the comparison):

* **Point** (colour attributes, generic float / vector / 2-D vector / colour attributes; vertex
  groups stay in :mod:`.mesh_io`): through the plan like the positions (``Plan.evaluate``, any
  channel count), so a weight is the scheme applied to the weights (Subsurf mixes them
  bilinearly). Byte colours are clamped to ``[0, 1]``. Integers, booleans, quaternions and
  matrices are not averaged: each output vertex takes the value of the *nearest cage vertex in
  its origin face's parameter*: the cage corner whose quadrant of the face (the sub-face of the
  first refinement that holds the corner) it lies in. That quadrant is found without positions
  (so a deforming cage never changes it): a linear face-varying evaluation of the unit vector
  at angle ``2 pi i / n`` on corner ``i`` of each ``n``-gon points, at every output corner,
  into the angular sector of its quadrant's corner.
* **Corner** (UV maps, corner colours, generic corner attributes): face-varying through
  ``Plan.evaluate_face_varying`` with the UV mode (:data:`UV_SMOOTH` maps Blender's six names;
  Subsurf smooths only UV maps and mixes the others bilinearly). UV maps weld as Blender's
  Subsurf welds them (within ``STD_UV_CONNECT_LIMIT`` per axis and by UV winding:
  :meth:`.mesh_io.CageArrays.uv_indices`), the other corner values by exact equality.
  Integers and booleans: the value of the quadrant's cage corner.
* **Face** (generic; material indices and flat/smooth stay in :mod:`.mesh_io`): copied from the
  origin face.
* **Edge** (sharp edges, seams, generic): copied onto the child edges of each cage edge
  (``Plan.edge_origin``); edges inside a cage face get the default (0, false), as Subsurf. The
  edge crease is the sharpness each child edge keeps at the last level (``Plan.edge_sharpness``,
  OpenSubdiv's per-level rule, as crease ``sqrt(s / 10)``), so that the applied surface,
  subdivided again, continues this one; Subsurf copies the cage's crease unchanged.
* **Vertex crease**: on the output vertex of each cage vertex, lowered by one per level (a
  vertex of sharpness ``s`` is a corner while ``s > level``); 0 elsewhere (Subsurf mixes it).
* **Custom normals** (the cage has them: Subsurf's *Use Custom Normals*): the cage's corner
  normals, linear face-varying (Subsurf's bilinear mix) and renormalized. The limit normals of
  *Limit Normals* take precedence.

Dual output: edges lie on cage edges only along the boundary (``Plan.edge_origin``) and no
output vertex is a cage vertex, so interior edge attributes and vertex creases stay at their
defaults.

Adaptive output (:func:`adaptive_request`, :func:`adaptive_attributes`): point floats, vertex
groups, corner floats (UV maps included, in the UV mode), custom normals, face attributes and
edge attributes (on the triangle edges along their cage edge, the crease lowered by each
edge's level), vertex creases (on the cage vertices' own output vertices,
``AdaptiveResult.cage_vertex``, lowered by each vertex's level) and integers and booleans (the
quadrant's cage corner, from the unit vectors carried linearly) come through as on uniform
output (each at its vertex's level).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from types import SimpleNamespace
from typing import TYPE_CHECKING, Any

import bidegree
import numpy as np

if TYPE_CHECKING:  # pragma: no cover - typing only
    import bpy

#: Blender's *UV Smooth* names (the Subdivision Surface modifier's, in its order) ->
#: bidegree's face-varying modes (OpenSubdiv's ``FVarLinearInterpolation``).
UV_SMOOTH: dict[str, str] = {
    "None": "all",
    "Keep Corners": "corners-only",
    "Keep Corners, Junctions": "corners-plus1",
    "Keep Corners, Junctions, Concave": "corners-plus2",
    "Keep Boundaries": "boundaries",
    "All": "none",
}
#: Blender's default (and the modes' default), *Keep Boundaries*.
UV_SMOOTH_DEFAULT = "Keep Boundaries"

#: Attribute data type -> (``foreach_get`` property, numpy dtype, values per element).
_LAYOUT: dict[str, tuple[str, Any, int]] = {
    "FLOAT": ("value", np.float32, 1),
    "FLOAT2": ("vector", np.float32, 2),
    "FLOAT_VECTOR": ("vector", np.float32, 3),
    "FLOAT_COLOR": ("color", np.float32, 4),
    "BYTE_COLOR": ("color", np.float32, 4),
    "QUATERNION": ("value", np.float32, 4),
    "FLOAT4X4": ("value", np.float32, 16),
    "INT": ("value", np.int32, 1),
    "INT8": ("value", np.int32, 1),
    "INT16_2D": ("value", np.int32, 2),
    "INT32_2D": ("value", np.int32, 2),
    "BOOLEAN": ("value", bool, 1),
}
#: Types that are averaged (through the plan or face-varying); the others take a cage value.
_AVERAGED = {"FLOAT", "FLOAT2", "FLOAT_VECTOR", "FLOAT_COLOR", "BYTE_COLOR"}
#: Attributes another part of the add-on carries (or that are topology).
_HANDLED_ELSEWHERE = {
    ("POINT", "position"),
    ("FACE", "material_index"),
    ("FACE", "sharp_face"),
    ("CORNER", "custom_normal"),
}
#: Internal (dot) attributes that are user data: seams (Blender 4.2; ``uv_seam`` from 4.3).
_INTERNAL_KEPT = {".uv_seam"}
CREASE_EDGE, CREASE_VERT = "crease_edge", "crease_vert"
_CREASE_SCALE = 10.0


@dataclass
class Attribute:
    """One attribute of a mesh: ``values`` is ``(n,)`` or ``(n, width)`` per element of
    ``domain`` (``POINT``, ``EDGE``, ``FACE``, ``CORNER``)."""

    name: str
    domain: str
    data_type: str
    values: np.ndarray


@dataclass
class CageAttributes:
    """The cage's attributes that :mod:`.mesh_io` does not carry, and its custom normals."""

    attributes: list[Attribute]
    #: Corner normals ``(corners, 3)`` when the cage has custom normals, else ``None``.
    custom_normals: np.ndarray | None = None
    #: The active and the default (render) colour attribute, by name.
    colors: tuple[str, str] = ("", "")

    def fingerprint(self, update: Any) -> None:
        """Feed the attributes into the hash ``update`` (``hashlib``'s ``update``); not the
        custom normals, which follow the positions and are written with them."""
        for attr in self.attributes:
            update(f"{attr.domain}:{attr.data_type}:{attr.name}".encode())
            update(np.ascontiguousarray(attr.values).tobytes())
        update(b"custom normals" if self.custom_normals is not None else b"-")
        update(repr(self.colors).encode())


def _read(attr: Any, count: int) -> np.ndarray:
    prop, dtype, width = _LAYOUT[attr.data_type]
    out = np.empty(count * width, dtype=dtype)
    if count:
        attr.data.foreach_get(prop, out)
    return out.reshape(count, width) if width > 1 else out


def read_attributes(mesh: bpy.types.Mesh, uv_maps: set[str]) -> CageAttributes:
    """The attributes of ``mesh`` to carry (all of them but topology, positions, ``uv_maps``
    (read by :mod:`.mesh_io`), material indices, flat/smooth and strings), and its corner
    normals if it has custom normals."""
    counts = {
        "POINT": len(mesh.vertices),
        "EDGE": len(mesh.edges),
        "FACE": len(mesh.polygons),
        "CORNER": len(mesh.loops),
    }
    found: list[Attribute] = []
    for attr in mesh.attributes:
        name, domain = attr.name, attr.domain
        if domain not in counts or attr.data_type not in _LAYOUT:
            continue
        if (name.startswith(".") and name not in _INTERNAL_KEPT) or (
            domain,
            name,
        ) in _HANDLED_ELSEWHERE:
            continue
        if domain == "CORNER" and name in uv_maps:
            continue
        found.append(Attribute(name, domain, attr.data_type, _read(attr, counts[domain])))
    normals = None
    if mesh.has_custom_normals and counts["CORNER"]:
        normals = np.empty(counts["CORNER"] * 3, dtype=np.float32)
        mesh.corner_normals.foreach_get("vector", normals)
        normals = normals.reshape(-1, 3)
    colors = mesh.color_attributes
    return CageAttributes(found, normals, (colors.active_color_name, colors.default_color_name))


def face_varying(plan: bidegree.Plan, values: Any, mode: str) -> Any:
    """``values`` per cage corner (an array, or a dict of them: each welded on its own, so
    one attribute's seams do not split another) at the output corners in the face-varying
    ``mode``."""
    if isinstance(values, dict):
        return {k: np.asarray(v) for k, v in plan.evaluate_face_varying(values, mode).items()}
    return np.asarray(plan.evaluate_face_varying(values, mode))


@dataclass
class SurfaceAttributes:
    """Attributes of a surface, ready to write: per output element of their domain."""

    attributes: list[Attribute]
    #: The active and the default (render) colour attribute, by name.
    colors: tuple[str, str] = ("", "")


@dataclass
class _OutputEdges:
    """Where the output edges lie on the cage: ``cage_edges`` (E0, 2) as the core orders them,
    per output edge its cage edge ``origin`` (-1 inside a cage face), the sharpness it keeps
    (``sharpness()``, computed only for a crease) and its level (``levels``: one for all, or
    per edge on adaptive output)."""

    cage_edges: np.ndarray
    origin: np.ndarray
    sharpness: Callable[[], np.ndarray]
    levels: int | np.ndarray


class _Corners:
    """The cage corners as the core sees them, and where each output corner lies in them."""

    def __init__(self, plan: Any, cage: Any, direction: np.ndarray | None = None) -> None:
        """``plan``: a :class:`bidegree.Plan`, or anything with its ``face_origin``,
        ``face_sizes``, ``face_indices``, ``output`` and ``num_output_vertices`` when
        ``direction`` (the linear face-varying :meth:`unit_vectors` at the output corners)
        is given."""
        sizes = np.asarray(cage.face_sizes, dtype=np.int64)
        starts = np.zeros(len(sizes), dtype=np.int64)
        np.cumsum(sizes[:-1], out=starts[1:])
        #: The unit vector of each cage corner, and its linear face-varying values (float64:
        #: exact at the output corners that are cage corners).
        self.unit = self.unit_vectors(cage)
        self.direction = face_varying(plan, self.unit, "all") if direction is None else direction
        origin = np.repeat(np.asarray(plan.face_origin, dtype=np.int64), plan.face_sizes)
        n = sizes[origin]
        angle = np.arctan2(self.direction[:, 1], self.direction[:, 0])
        #: For each output corner, the cage corner whose quadrant of the origin face holds it.
        self.quadrant = starts[origin] + np.rint(angle * n / (2 * np.pi)).astype(np.int64) % n
        #: Output corners at cage vertices (their vector is the corner's, bit for bit); none
        #: on the dual mesh, whose vertices are face points (its corners take a corner's value).
        self.exact = (self.direction == self.unit[self.quadrant]).all(axis=1)
        if plan.output == "dual":
            self.exact[:] = False
        face_indices = np.asarray(plan.face_indices, dtype=np.int64)
        self.face_indices = face_indices
        #: The first output corner of each output vertex (it picks the vertex's quadrant).
        self.first = np.empty(int(plan.num_output_vertices), dtype=np.int64)
        self.first[face_indices[::-1]] = np.arange(len(face_indices) - 1, -1, -1)
        self.corner_verts = np.asarray(cage.corner_verts, dtype=np.int64)

    @staticmethod
    def unit_vectors(cage: Any) -> np.ndarray:
        """Corner ``i`` of each ``n``-gon: the unit vector at angle ``2 pi i / n``."""
        sizes = np.asarray(cage.face_sizes, dtype=np.int64)
        starts = np.zeros(len(sizes), dtype=np.int64)
        np.cumsum(sizes[:-1], out=starts[1:])
        face = np.repeat(np.arange(len(sizes)), sizes)
        theta = 2 * np.pi * (np.arange(int(sizes.sum())) - starts[face]) / sizes[face]
        return np.stack([np.cos(theta), np.sin(theta)], axis=1)

    def point_source(self) -> np.ndarray:
        """The cage vertex each output vertex takes a non-averaged value from."""
        return self.corner_verts[self.quadrant[self.first]]


def transfer(
    plan: bidegree.Plan,
    cage: Any,
    cage_attributes: CageAttributes,
    *,
    uv_mode: str,
    use_creases: bool,
) -> SurfaceAttributes:
    """The attributes of ``cage`` (:class:`.mesh_io.CageArrays`) on ``plan``'s surface (custom
    normals: :func:`custom_normals`, which follow the positions)."""
    attrs = cage_attributes.attributes
    by_value = {
        id(a)
        for a in attrs
        if a.domain in ("POINT", "CORNER")
        and (a.data_type not in _AVERAGED or (a.domain, a.name) == ("POINT", CREASE_VERT))
    }
    corners = _Corners(plan, cage) if by_value else None
    out: list[Attribute] = []
    points = [a for a in attrs if a.domain == "POINT" and id(a) not in by_value]
    if points:
        out += _split(points, np.asarray(plan.evaluate(_stack(points))))
    corner = [a for a in attrs if a.domain == "CORNER" and id(a) not in by_value]
    if corner:
        values = face_varying(plan, {a.name: a.values for a in corner}, uv_mode)
        for a in corner:
            out += _split([a], values[a.name].reshape(len(values[a.name]), -1))
    origin = np.asarray(plan.face_origin, dtype=np.int64)
    for a in attrs:
        if a.domain == "FACE":
            out.append(_like(a, a.values[origin]))
        elif id(a) in by_value:
            assert corners is not None
            if a.name == CREASE_VERT and a.domain == "POINT":
                at = corners.face_indices[corners.exact]
                source = corners.corner_verts[corners.quadrant[corners.exact]]
                count = int(plan.num_output_vertices)
                out.append(_vertex_crease(a, count, at, source, int(plan.levels), use_creases))
            elif a.domain == "POINT":
                out.append(_like(a, a.values[corners.point_source()]))
            else:
                out.append(_like(a, a.values[corners.quadrant]))
    edges = [a for a in attrs if a.domain == "EDGE"]
    if edges:
        on = _OutputEdges(
            plan.cage_edges, plan.edge_origin, lambda: plan.edge_sharpness, int(plan.levels)
        )
        out += _edge_attributes(edges, on, cage, use_creases)
    order = {(a.domain, a.name): i for i, a in enumerate(attrs)}
    out.sort(key=lambda a: order[(a.domain, a.name)])
    return SurfaceAttributes(out, cage_attributes.colors)


#: Names of the face-varying sets that carry the custom normals and the corners' unit vectors
#: (for integer and boolean attributes) through adaptive output.
_NORMALS_SET = "\0custom normals"
_QUADRANT_SET = "\0quadrant"


def adaptive_request(
    cage: Any, uv_mode: str
) -> tuple[list[Attribute], dict[str, tuple[np.ndarray, str]]]:
    """What adaptive output carries of the attributes of ``cage`` (a
    :class:`.mesh_io.CageArrays`), as the arguments of :func:`bidegree.subdivide_adaptive`:
    the averaged point attributes (stacked as its ``vertex_values``) and the averaged corner
    attributes, custom normals and, for integer and boolean attributes, the corners' unit
    vectors (its ``face_varying``: corner values in ``uv_mode``, the others linear)."""
    cage_attributes = cage.attributes
    attrs = cage_attributes.attributes
    points = [
        a
        for a in attrs
        if a.domain == "POINT" and a.data_type in _AVERAGED and a.name != CREASE_VERT
    ]
    sets = {
        f"{a.domain}:{a.name}": (a.values.astype(np.float64), uv_mode)
        for a in attrs
        if a.domain == "CORNER" and a.data_type in _AVERAGED
    }
    if cage_attributes.custom_normals is not None:
        sets[_NORMALS_SET] = (np.asarray(cage_attributes.custom_normals, np.float64), "all")
    if any(_by_value(a) and a.name != CREASE_VERT for a in attrs):
        sets[_QUADRANT_SET] = (_Corners.unit_vectors(cage), "all")
    return points, sets


def _by_value(a: Attribute) -> bool:
    """A point or corner attribute taken from one cage value (not averaged)."""
    return a.domain in ("POINT", "CORNER") and (
        a.data_type not in _AVERAGED or (a.domain, a.name) == ("POINT", CREASE_VERT)
    )


def adaptive_attributes(
    result: bidegree.AdaptiveResult,
    cage: Any,
    points: list[Attribute],
    point_values: np.ndarray | None,
    corner_edges: np.ndarray,
    *,
    use_creases: bool,
) -> tuple[SurfaceAttributes, np.ndarray | None]:
    """The attributes adaptive output carries (see :func:`adaptive_request`; ``point_values``
    are the columns of ``points`` in ``result.vertex_values``; ``corner_edges``: the output
    edge of each triangle corner's edge), with the face attributes through ``face_origin``
    and the edge attributes on the triangle edges along their cage edge (the crease as
    ``result.edge_sharpness`` keeps it), integer and boolean values from the quadrant's cage
    corner (as uniform output), and the custom normals per triangle corner (renormalized) or
    ``None``; vertex creases on the cage vertices' own output vertices, lowered by their
    level."""
    cage_attributes = cage.attributes
    origin = np.asarray(result.face_origin, dtype=np.int64)
    out = [_like(a, a.values[origin]) for a in cage_attributes.attributes if a.domain == "FACE"]
    at = np.flatnonzero(np.asarray(result.cage_vertex) >= 0)
    source = np.asarray(result.cage_vertex, dtype=np.int64)[at]
    levels = np.asarray(result.vertex_level)[at]
    for a in cage_attributes.attributes:
        if (a.domain, a.name) == ("POINT", CREASE_VERT):
            out.append(_vertex_crease(a, result.num_vertices, at, source, levels, use_creases))
    edge_attrs = [a for a in cage_attributes.attributes if a.domain == "EDGE"]
    if edge_attrs:
        corner_edges = np.asarray(corner_edges, dtype=np.int64)
        count = int(corner_edges.max()) + 1 if len(corner_edges) else 0
        per_edge = []
        for values, dtype in (
            (result.edge_origin, np.int64),
            (result.edge_sharpness, np.float32),
            (result.edge_level, np.int64),
        ):
            column = np.zeros(count, dtype=dtype)
            column[corner_edges] = values  # both corners of an edge agree
            per_edge.append(column)
        on = _OutputEdges(result.cage_edges, per_edge[0], lambda: per_edge[1], per_edge[2])
        out += _edge_attributes(edge_attrs, on, cage, use_creases)
    if points and point_values is not None:
        out += _split(points, point_values)
    for a in cage_attributes.attributes:
        values = result.face_varying.get(f"{a.domain}:{a.name}")
        if values is not None:
            out += _split([a], values.reshape(len(values), -1))
    direction = result.face_varying.get(_QUADRANT_SET)
    if direction is not None:
        triangles = np.asarray(result.triangles).reshape(-1)
        output = SimpleNamespace(
            face_origin=result.face_origin,
            face_sizes=np.full(result.num_triangles, 3),
            face_indices=triangles,
            output="primal",
            num_output_vertices=result.num_vertices,
        )
        corners = _Corners(output, cage, direction)
        for a in cage_attributes.attributes:
            if _by_value(a) and a.name != CREASE_VERT:
                source = corners.point_source() if a.domain == "POINT" else corners.quadrant
                out.append(_like(a, a.values[source]))
    normals = result.face_varying.get(_NORMALS_SET)
    if normals is not None:
        length = np.linalg.norm(normals, axis=1, keepdims=True)
        normals = (normals / np.where(length > 0, length, 1.0)).astype(np.float32)
    order = {(a.domain, a.name): i for i, a in enumerate(cage_attributes.attributes)}
    out.sort(key=lambda a: order[(a.domain, a.name)])
    return SurfaceAttributes(out, cage_attributes.colors), normals


def custom_normals(plan: bidegree.Plan, normals: np.ndarray) -> np.ndarray:
    """The cage's corner normals at the output corners: linear face-varying (Subsurf's
    bilinear mix of *Use Custom Normals*), renormalized; float32 ``(corners, 3)``."""
    out = face_varying(plan, np.asarray(normals, dtype=np.float64), "all")
    length = np.linalg.norm(out, axis=1, keepdims=True)
    return (out / np.where(length > 0, length, 1.0)).astype(np.float32)


def _stack(attrs: list[Attribute]) -> np.ndarray:
    return np.concatenate([a.values.reshape(len(a.values), -1) for a in attrs], axis=1)


def _like(attr: Attribute, values: np.ndarray) -> Attribute:
    return Attribute(attr.name, attr.domain, attr.data_type, values)


def _split(attrs: list[Attribute], values: np.ndarray) -> list[Attribute]:
    """Columns of ``values`` back into one attribute each (in the order of ``attrs``)."""
    out = []
    at = 0
    for a in attrs:
        width = 1 if a.values.ndim == 1 else a.values.shape[1]
        part = values[:, at : at + width]
        at += width
        part = part[:, 0] if a.values.ndim == 1 else part
        if a.data_type == "BYTE_COLOR":
            part = np.clip(part, 0.0, 1.0)
        out.append(_like(a, part.astype(np.float32)))
    return out


def _lowered(sharpness: np.ndarray, levels: int | np.ndarray) -> np.ndarray:
    """OpenSubdiv's uniform decrement, ``levels`` times: minus one per level, 10 stays (in the
    dtype of ``sharpness``, so that per-element levels give the bits of one level for all)."""
    lowered = sharpness - np.asarray(levels, dtype=sharpness.dtype)
    return np.where(sharpness >= _CREASE_SCALE, _CREASE_SCALE, np.maximum(lowered, 0))


def _to_crease(sharpness: np.ndarray) -> np.ndarray:
    return np.sqrt(np.clip(sharpness, 0.0, _CREASE_SCALE) / _CREASE_SCALE).astype(np.float32)


def _vertex_crease(
    attr: Attribute,
    count: int,
    at: np.ndarray,
    source: np.ndarray,
    levels: int | np.ndarray,
    use_creases: bool,
) -> Attribute:
    """The crease of cage vertex ``source[i]`` on output vertex ``at[i]`` (lowered by its level,
    ``levels``: one for all or per vertex), 0 on the other of the ``count`` output vertices."""
    values = np.zeros(count, dtype=np.float32)
    crease = attr.values[source]
    if use_creases:
        sharpness = _CREASE_SCALE * np.clip(crease, 0.0, 1.0) ** 2
        crease = _to_crease(_lowered(sharpness, levels))
    values[at] = crease
    return _like(attr, values)


def _edge_attributes(
    attrs: list[Attribute],
    on: _OutputEdges,
    cage: Any,
    use_creases: bool,
) -> list[Attribute]:
    """Edge attributes on the child edges of each cage edge (the default elsewhere)."""
    cage_edges = np.asarray(on.cage_edges, dtype=np.int64)
    core_keys = cage_edges[:, 0] << 32 | cage_edges[:, 1]
    edges = np.sort(np.asarray(cage.edges, dtype=np.int64).reshape(-1, 2), axis=1)
    keys = edges[:, 0] << 32 | edges[:, 1]
    at = np.minimum(np.searchsorted(core_keys, keys), max(len(core_keys) - 1, 0))
    found = (core_keys[at] == keys) if len(core_keys) else np.zeros(len(keys), bool)
    blender_of_core = np.full(len(core_keys), -1, dtype=np.int64)
    blender_of_core[at[found]] = np.flatnonzero(found)
    origin = np.asarray(on.origin, dtype=np.int64)
    source = np.where(origin >= 0, blender_of_core[np.maximum(origin, 0)], -1)
    on_edge = source >= 0
    out = []
    for a in attrs:
        values = np.zeros((len(origin), *a.values.shape[1:]), dtype=a.values.dtype)
        values[on_edge] = a.values[source[on_edge]]
        if a.name == CREASE_EDGE and a.data_type == "FLOAT" and use_creases:
            values = _edge_crease(a.values, values, source, on, cage)
        out.append(_like(a, values))
    return out


def _edge_crease(
    crease: np.ndarray, copied: np.ndarray, source: np.ndarray, on: _OutputEdges, cage: Any
) -> np.ndarray:
    """The crease each child edge keeps: the core's sharpness at the last level (its own
    per-level rule), the uniform decrement on boundary edges (always infinitely sharp in the
    core, so the user's value is lowered as it would be inside)."""
    faces_per_edge = np.bincount(np.asarray(cage.corner_edges), minlength=len(crease))
    creased = (source >= 0) & (copied > 0)
    boundary = np.zeros(len(source), dtype=bool)
    boundary[creased] = faces_per_edge[source[creased]] == 1
    sharpness = np.asarray(on.sharpness(), dtype=np.float32).copy()
    cage_sharpness = _CREASE_SCALE * np.clip(copied, 0.0, 1.0) ** 2
    levels = np.broadcast_to(np.asarray(on.levels), sharpness.shape)
    sharpness[boundary] = _lowered(cage_sharpness[boundary], levels[boundary])
    return np.where(creased, _to_crease(sharpness), 0.0).astype(np.float32)


def write_attributes(mesh: bpy.types.Mesh, surface: SurfaceAttributes) -> None:
    """Create every attribute of ``surface`` on ``mesh`` (which has the surface's topology)."""
    for a in surface.attributes:
        existing = mesh.attributes.get(a.name)
        if existing is not None:
            if existing.domain == a.domain and existing.data_type == a.data_type:
                target = existing
            else:
                mesh.attributes.remove(existing)
                target = None
        else:
            target = None
        if target is None:
            target = mesh.attributes.new(a.name, a.data_type, a.domain)
            if target is None:  # a reserved name on this Blender version
                continue
        prop, dtype, _width = _LAYOUT[a.data_type]
        values = np.ascontiguousarray(a.values, dtype=dtype).ravel()
        if values.size:
            target.data.foreach_set(prop, values)
    colors = mesh.color_attributes
    active, default = surface.colors
    if active in colors:
        colors.active_color_name = active
    if default in colors:
        colors.default_color_name = default
