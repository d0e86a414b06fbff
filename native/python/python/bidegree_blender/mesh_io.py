"""Fast Blender mesh <-> numpy conversion for bidegree.

Everything goes through the generic attribute API with ``foreach_get`` /
``foreach_set`` on exactly typed (``float32`` / ``int32``) numpy arrays, which
is 100-300x faster than iterating ``mesh.vertices`` / ``mesh.loops`` or using
``from_pydata``.  Results are written with their edges and corner edges
(``Result.edges`` / ``Result.corner_edges``) so that Blender never has to
recompute edges (``calc_edges``).

Creases follow Blender/OpenSubdiv: a crease attribute value ``c`` in ``[0, 1]``
becomes the sharpness ``10 * c**2`` (``c == 1`` is infinitely sharp).
"""

from __future__ import annotations

import hashlib
import warnings
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import bidegree
import numpy as np

from .attributes import CageAttributes

if TYPE_CHECKING:  # pragma: no cover - typing only
    import bpy

#: Sharpness of a crease value of 1.0 (Blender's ``BKE_subdiv_crease_to_sharpness``).
CREASE_SCALE = 10.0

_BOUNDARIES = ("edge-only", "edge-and-corner", "none")


def crease_to_sharpness(crease: np.ndarray) -> np.ndarray:
    """Map Blender crease values (``[0, 1]``) to subdivision sharpness ``10 * c**2``."""
    c = np.clip(np.asarray(crease, dtype=np.float32), 0.0, 1.0)
    return (CREASE_SCALE * c * c).astype(np.float32)


@dataclass
class CageArrays:
    """A Blender mesh read into flat numpy arrays (the subdivision cage).

    Attributes:
        points: ``(V, 3)`` float32 vertex positions.
        face_sizes: ``(F,)`` int32 corner count per face.
        corner_verts: ``(C,)`` int32 vertex of each face corner.
        edges: ``(E, 2)`` int32 vertex pairs.
        corner_edges: ``(C,)`` int32 edge of each face corner.
        edge_creases: ``(E,)`` float32 crease values in ``[0, 1]`` or ``None``.
        vert_creases: ``(V,)`` float32 crease values in ``[0, 1]`` or ``None``.
        uv_maps: UV map name -> ``(C, 2)`` float32 face-varying coordinates.
        vertex_groups: vertex group name -> ``(V,)`` float32 weights (0 where a vertex is not
            in the group), in the object's group order.
        active_uv: name of the active render UV map (or ``None``).
        material_index: ``(F,)`` int32 or ``None`` when the mesh has no such attribute.
        sharp_face: ``(F,)`` bool or ``None`` when the mesh has no such attribute.
        attributes: every other attribute and the custom normals (:mod:`.attributes`).
    """

    points: np.ndarray
    face_sizes: np.ndarray
    corner_verts: np.ndarray
    edges: np.ndarray
    corner_edges: np.ndarray
    edge_creases: np.ndarray | None = None
    vert_creases: np.ndarray | None = None
    uv_maps: dict[str, np.ndarray] = field(default_factory=dict)
    active_uv: str | None = None
    material_index: np.ndarray | None = None
    sharp_face: np.ndarray | None = None
    vertex_groups: dict[str, np.ndarray] = field(default_factory=dict)
    attributes: CageAttributes = field(default_factory=lambda: CageAttributes([]))
    _uv_indices: dict[str, np.ndarray] = field(
        default_factory=dict, init=False, repr=False, compare=False
    )

    @property
    def num_vertices(self) -> int:
        """Number of cage vertices."""
        return int(self.points.shape[0])

    def uv_indices(self, name: str) -> np.ndarray:
        """The face-varying topology Blender's Subdivision Surface gives UV map ``name``: its
        weld within ``STD_UV_CONNECT_LIMIT`` and by UV winding
        (:func:`bidegree.blender_uv_indices`), as indices into the map's corners (computed
        once per read)."""
        if name not in self._uv_indices:
            self._uv_indices[name] = bidegree.blender_uv_indices(
                self.face_sizes, self.corner_verts, self.uv_maps[name]
            )
        return self._uv_indices[name]

    def uv_sets(self) -> dict[str, tuple[np.ndarray, np.ndarray]]:
        """Every UV map as ``(uvs, indices)``: what ``Plan.evaluate_face_varying`` takes to give
        Blender's seams."""
        return {name: (uv, self.uv_indices(name)) for name, uv in self.uv_maps.items()}

    @property
    def num_faces(self) -> int:
        """Number of cage faces."""
        return int(self.face_sizes.shape[0])

    def topology_fingerprint(self, *, use_creases: bool = True) -> str:
        """Hash of everything a :class:`bidegree.Plan` depends on (not the positions).

        Face sizes, corner vertices, the vertex count and, when ``use_creases``,
        the crease data.  Two meshes with the same fingerprint can share a plan.
        """
        h = hashlib.blake2b(digest_size=16)
        h.update(np.int64(self.num_vertices).tobytes())
        h.update(np.ascontiguousarray(self.face_sizes).tobytes())
        h.update(np.ascontiguousarray(self.corner_verts).tobytes())
        if use_creases:
            for name, arr in (("e", self.edge_creases), ("v", self.vert_creases)):
                h.update(name.encode())
                if arr is not None:
                    h.update(np.ascontiguousarray(self.edges).tobytes() if name == "e" else b"")
                    h.update(np.ascontiguousarray(arr).tobytes())
        return h.hexdigest()

    def positions_hash(self) -> str:
        """Hash of the vertex positions (used to skip updates when nothing moved)."""
        return hashlib.blake2b(
            np.ascontiguousarray(self.points).tobytes(), digest_size=16
        ).hexdigest()


def _get(collection: Any, prop: str, count: int, dtype: np.dtype, width: int = 1) -> np.ndarray:
    """``foreach_get`` into a freshly allocated, exactly typed numpy array."""
    out = np.empty(count * width, dtype=dtype)
    if count:
        collection.foreach_get(prop, out)
    return out.reshape(count, width) if width > 1 else out


def _attribute(
    mesh: bpy.types.Mesh, name: str, domain: str, data_type: str | None = None
) -> Any | None:
    """The attribute ``name`` on ``domain`` (and of ``data_type`` if given), or ``None``."""
    attr = mesh.attributes.get(name)
    if attr is None or attr.domain != domain:
        return None
    if data_type is not None and attr.data_type != data_type:
        return None
    return attr


def read_mesh(mesh: bpy.types.Mesh, *, use_creases: bool = True) -> CageArrays:
    """Read a Blender mesh into :class:`CageArrays` (no Python loops over elements).

    Args:
        mesh: Any Blender mesh (typically an evaluated ``obj.to_mesh()``).
        use_creases: Read ``crease_edge`` / ``crease_vert`` attributes.
    """
    nv = len(mesh.vertices)
    ne = len(mesh.edges)
    nc = len(mesh.loops)
    nf = len(mesh.polygons)
    position = mesh.attributes.get("position")
    if nv == 0 or position is None:
        # An empty mesh has no position attribute at all.
        raise bidegree.EmptyMeshError("the mesh has no vertices to subdivide")

    points = _get(position.data, "vector", nv, np.float32, 3)
    edges = (
        _get(mesh.attributes[".edge_verts"].data, "value", ne, np.int32, 2)
        if ne
        else np.zeros((0, 2), np.int32)
    )
    corner_verts = (
        _get(mesh.attributes[".corner_vert"].data, "value", nc, np.int32)
        if nc
        else np.zeros(0, np.int32)
    )
    corner_edges = (
        _get(mesh.attributes[".corner_edge"].data, "value", nc, np.int32)
        if nc
        else np.zeros(0, np.int32)
    )
    face_sizes = _get(mesh.polygons, "loop_total", nf, np.int32)

    cage = CageArrays(
        points=points,
        face_sizes=face_sizes,
        corner_verts=corner_verts,
        edges=edges.reshape(-1, 2),
        corner_edges=corner_edges,
    )

    if use_creases:
        attr = _attribute(mesh, "crease_edge", "EDGE", "FLOAT")
        if attr is not None and ne:
            cage.edge_creases = _get(attr.data, "value", ne, np.float32)
        attr = _attribute(mesh, "crease_vert", "POINT", "FLOAT")
        if attr is not None and nv:
            cage.vert_creases = _get(attr.data, "value", nv, np.float32)

    active = mesh.uv_layers.active
    cage.active_uv = active.name if active is not None else None
    for layer in mesh.uv_layers:
        attr = _attribute(mesh, layer.name, "CORNER", "FLOAT2")
        if attr is None:
            continue
        cage.uv_maps[layer.name] = _get(attr.data, "vector", nc, np.float32, 2)

    attr = _attribute(mesh, "material_index", "FACE", "INT")
    if attr is not None and nf:
        cage.material_index = _get(attr.data, "value", nf, np.int32)
    attr = _attribute(mesh, "sharp_face", "FACE", "BOOLEAN")
    if attr is not None and nf:
        cage.sharp_face = _get(attr.data, "value", nf, bool)
    return cage


def read_vertex_groups(mesh: bpy.types.Mesh, names: list[str]) -> dict[str, np.ndarray]:
    """The weights of the vertex groups ``names`` (the object's groups, in order) on ``mesh``.

    Blender has no bulk access to vertex group weights, so this walks the vertices in Python:
    it is only called for meshes that have vertex groups.
    """
    weights = np.zeros((len(names), len(mesh.vertices)), dtype=np.float32)
    for vertex in mesh.vertices:
        for element in vertex.groups:
            if element.group < len(names):
                weights[element.group, vertex.index] = element.weight
    return {name: weights[i] for i, name in enumerate(names)}


def write_vertex_groups(obj: bpy.types.Object, groups: dict[str, np.ndarray]) -> None:
    """Make ``groups`` (name -> weight per vertex) the vertex groups of ``obj``'s mesh.

    Weights of zero are left out (as Blender stores them); the others are added one call per
    distinct value, since Blender has no bulk write of vertex group weights.
    """
    obj.vertex_groups.clear()
    for name, weights in groups.items():
        group = obj.vertex_groups.new(name=name)
        nonzero = np.flatnonzero(weights > 0.0)
        if not len(nonzero):
            continue
        values, inverse = np.unique(weights[nonzero], return_inverse=True)
        order = np.argsort(inverse, kind="stable")
        bounds = np.searchsorted(inverse[order], np.arange(len(values) + 1))
        for k, value in enumerate(values):
            group.add(nonzero[order[bounds[k] : bounds[k + 1]]].tolist(), float(value), "REPLACE")


class LooseEdgesWarning(UserWarning):
    """The mesh has loose edges (in no face): they are left out of the surface, as Blender's
    Subdivision Surface modifier leaves them out of OpenSubdiv's input."""


def check_cage(cage: CageArrays) -> None:
    """Checks bidegree's core cannot do because it never sees Blender's edge list.

    Raises:
        bidegree.EmptyMeshError: the mesh has no faces.
    """
    if cage.num_faces == 0:
        raise bidegree.EmptyMeshError("the mesh has no faces to subdivide")


def loose_edges(cage: CageArrays) -> np.ndarray:
    """``(K,)`` the edges that no face uses."""
    used = np.bincount(cage.corner_edges, minlength=len(cage.edges)) > 0
    return np.flatnonzero(~used)


def vertex_sharpness(cage: CageArrays, edge_sharpness: np.ndarray) -> np.ndarray:
    """``(V,)`` the sharpness Blender gives each vertex before OpenSubdiv sees the mesh
    (``subdiv_converter_mesh.cc``, ``topology_refiner_factory.cc``): its own crease; plus, at a
    vertex with exactly two face edges, the smaller of their sharpness (capped at 10); and
    infinitely sharp at a vertex of a loose edge that is also on a face.

    Args:
        cage: The arrays read by :func:`read_mesh`.
        edge_sharpness: ``(E,)`` the user's sharpness of every edge (0 smooth).
    """
    nv = len(cage.points)
    sharpness = np.zeros(nv, dtype=np.float32)
    if cage.vert_creases is not None:
        sharpness = crease_to_sharpness(cage.vert_creases).astype(np.float32)
    used = np.bincount(cage.corner_edges, minlength=len(cage.edges)) > 0
    face_edges = cage.edges[used].astype(np.int64)
    ends = face_edges.reshape(-1)
    count = np.bincount(ends, minlength=nv)
    smallest = np.full(nv, np.inf, dtype=np.float32)
    np.minimum.at(smallest, ends, np.repeat(edge_sharpness[used], 2))
    two = (count == 2) & (smallest > 0)
    sharpness[two] = np.minimum(sharpness[two] + smallest[two], 10.0)
    on_face = np.zeros(nv, dtype=bool)
    on_face[cage.corner_verts] = True
    loose = cage.edges[~used].reshape(-1)
    sharpness[loose[on_face[loose]]] = 10.0
    return sharpness


def to_bidegree_mesh(
    cage: CageArrays,
    *,
    boundary: str = "edge-only",
    use_creases: bool = True,
    uv_map: str | None = None,
) -> bidegree.Mesh:
    """Build the :class:`bidegree.Mesh` cage from :class:`CageArrays`, the way Blender's
    modifier hands a mesh to OpenSubdiv: loose edges are left out (with a
    :class:`LooseEdgesWarning` counting them) and Blender's two vertex rules are applied (see
    :func:`vertex_sharpness`).

    Args:
        cage: The arrays read by :func:`read_mesh`.
        boundary: ``"edge-only"``, ``"edge-and-corner"`` or ``"none"``.
        use_creases: Pass edge/vertex creases (sharpness ``10 * c**2``).
        uv_map: Name of the UV map to attach as the mesh's ``uvs`` (or ``None``), with Blender's
            UV topology as its ``uv_indices`` (:meth:`CageArrays.uv_indices`).

    Warns:
        LooseEdgesWarning: the mesh has loose edges.
    """
    if boundary not in _BOUNDARIES:
        raise bidegree.InvalidInputError(f"boundary must be one of {_BOUNDARIES}, got {boundary!r}")
    check_cage(cage)
    loose = loose_edges(cage)
    if len(loose):
        warnings.warn(
            f"{len(loose)} loose edge(s) (in no face) left out of the surface",
            LooseEdgesWarning,
            stacklevel=2,
        )
    edge_sharpness = np.zeros(len(cage.edges), dtype=np.float32)
    if use_creases and cage.edge_creases is not None:
        edge_sharpness = crease_to_sharpness(cage.edge_creases).astype(np.float32)
    creases = None
    sel = np.flatnonzero(edge_sharpness > 0.0)
    sel = sel[np.isin(sel, loose, invert=True)]
    if len(sel):
        creases = (cage.edges[sel].astype(np.int64), edge_sharpness[sel])
    corners = None
    if use_creases:
        sharpness = vertex_sharpness(cage, edge_sharpness)
        sel = np.flatnonzero(sharpness > 0.0)
        if len(sel):
            corners = (sel.astype(np.int64), sharpness[sel])
    uvs = cage.uv_maps.get(uv_map) if uv_map is not None else None
    uv_indices = cage.uv_indices(uv_map) if uvs is not None and uv_map is not None else None
    return bidegree.Mesh(
        cage.points,
        face_sizes=cage.face_sizes,
        face_indices=cage.corner_verts,
        creases=creases,
        corners=corners,
        uvs=uvs,
        uv_indices=uv_indices,
        boundary=boundary,
    )


def _set(collection: Any, prop: str, values: np.ndarray, dtype: np.dtype) -> None:
    """``foreach_set`` from a contiguous array of exactly ``dtype``."""
    arr = np.ascontiguousarray(values, dtype=dtype).ravel()
    if arr.size:
        collection.foreach_set(prop, arr)


def write_mesh(
    mesh: bpy.types.Mesh,
    *,
    points: np.ndarray,
    face_sizes: np.ndarray,
    corner_verts: np.ndarray,
    edges: np.ndarray,
    corner_edges: np.ndarray,
    face_origin: np.ndarray | None = None,
    cage: CageArrays | None = None,
    uv_maps: dict[str, np.ndarray] | None = None,
    active_uv: str | None = None,
    materials: list[Any] | None = None,
    normals: np.ndarray | None = None,
    normals_domain: str = "CORNER",
) -> bpy.types.Mesh:
    """Replace the geometry of ``mesh`` with the given arrays (fast path, no ``calc_edges``).

    Per-face data of the cage (``material_index``, ``sharp_face``) is carried over
    through ``face_origin``; ``uv_maps`` (name -> ``(C, 2)``) become UV maps;
    ``normals`` (one per face corner, or per vertex with ``normals_domain="POINT"``) become
    custom normals.

    Returns:
        ``mesh`` itself.
    """
    points = np.asarray(points)
    nv = int(points.shape[0])
    nf = len(face_sizes)
    nc = len(corner_verts)
    edges = np.asarray(edges).reshape(-1, 2)
    ne = int(edges.shape[0])

    mesh.clear_geometry()
    if materials is not None:
        # Before the material indices: changing the material list clamps them.
        mesh.materials.clear()
        for mat in materials:
            mesh.materials.append(mat)
    mesh.vertices.add(nv)
    mesh.edges.add(ne)
    mesh.loops.add(nc)
    mesh.polygons.add(nf)

    if nv:
        _set(mesh.attributes["position"].data, "vector", points, np.float32)
    if ne:
        _set(mesh.attributes[".edge_verts"].data, "value", edges, np.int32)
    if nc:
        _set(mesh.attributes[".corner_vert"].data, "value", corner_verts, np.int32)
        _set(mesh.attributes[".corner_edge"].data, "value", corner_edges, np.int32)
    if nf:
        offsets = np.zeros(nf, dtype=np.int32)
        np.cumsum(np.asarray(face_sizes, dtype=np.int32)[:-1], out=offsets[1:])
        _set(mesh.polygons, "loop_start", offsets, np.int32)

    if cage is not None and face_origin is not None and nf:
        origin = np.asarray(face_origin, dtype=np.int64)
        if cage.material_index is not None and cage.material_index.any():
            attr = mesh.attributes.new("material_index", "INT", "FACE")
            _set(attr.data, "value", cage.material_index[origin], np.int32)
        if cage.sharp_face is not None and cage.sharp_face.any():
            attr = mesh.attributes.get("sharp_face") or mesh.attributes.new(
                "sharp_face", "BOOLEAN", "FACE"
            )
            _set(attr.data, "value", cage.sharp_face[origin], bool)
        elif mesh.attributes.get("sharp_face") is not None:
            mesh.attributes.remove(mesh.attributes["sharp_face"])

    for name, uv in (uv_maps or {}).items():
        layer = mesh.uv_layers.new(name=name, do_init=False)
        if layer is None:  # Blender's limit on UV maps reached
            continue
        _set(mesh.attributes[layer.name].data, "vector", uv, np.float32)
    if active_uv is not None and active_uv in mesh.uv_layers:
        mesh.uv_layers.active = mesh.uv_layers[active_uv]
        mesh.uv_layers[active_uv].active_render = True

    _set_normals(mesh, normals, normals_domain)
    mesh.update(calc_edges=False)
    return mesh


def write_positions(
    mesh: bpy.types.Mesh,
    points: np.ndarray,
    normals: np.ndarray | None = None,
    normals_domain: str = "CORNER",
) -> None:
    """Overwrite the vertex positions of ``mesh`` (same vertex count) and its custom normals
    (``None`` removes them; per corner, or per vertex with ``normals_domain="POINT"``) and tag
    it for redraw."""
    _set(mesh.attributes["position"].data, "vector", points, np.float32)
    _set_normals(mesh, normals, normals_domain)
    mesh.update(calc_edges=False)


#: The attribute Blender 5 reads custom normals from (a float vector per corner or per vertex,
#: the "free" storage: written directly, no encoding into normal spaces).
CUSTOM_NORMAL = "custom_normal"


def point_normals() -> bool:
    """Whether this Blender keeps custom normals per vertex as they are (5.0 on: a point
    ``custom_normal`` attribute; Blender 4 encodes them per corner whichever way they come)."""
    import bpy

    return bool(bpy.app.version >= (5, 0, 0))


def _set_normals(mesh: bpy.types.Mesh, normals: np.ndarray | None, domain: str = "CORNER") -> None:
    """Custom normals per face corner, or per vertex with ``domain="POINT"`` (``None``: none,
    the shading comes from the faces)."""
    if domain not in ("CORNER", "POINT"):
        raise bidegree.InternalError(f"custom normals per {domain!r}")
    if not point_normals():
        # Blender 4 encodes custom normals into normal spaces; only its own calls write them.
        if normals is not None:
            values = np.ascontiguousarray(normals, dtype=np.float32)
            if domain == "POINT":
                mesh.normals_split_custom_set_from_vertices(values)
            else:
                mesh.normals_split_custom_set(values)
        return
    existing = mesh.attributes.get(CUSTOM_NORMAL)
    if normals is None:
        if existing is not None:
            mesh.attributes.remove(existing)
        return
    if existing is not None and (existing.domain != domain or existing.data_type != "FLOAT_VECTOR"):
        mesh.attributes.remove(existing)
        existing = None
    if existing is None:
        existing = mesh.attributes.new(CUSTOM_NORMAL, "FLOAT_VECTOR", domain)
    _set(existing.data, "vector", normals, np.float32)
