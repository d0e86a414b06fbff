"""Dirty cages (issue 13) and face-varying cages (issue 14), as plain numpy data.

Every cage here is something Blender's Subdivision Surface modifier (OpenSubdiv 3.6) subdivides
without complaint and that bidegree must learn to subdivide the same way: non-manifold edges and
vertices, flipped faces, loose edges, faces repeating a vertex, zero-area faces, holes, boundary
interpolation ``none``, bowties, valence-2 vertices on creases; and UV layouts whose seams,
corners and junctions exercise OpenSubdiv's six face-varying modes. What OpenSubdiv does with each
is in ``docs/research/non-manifold.md`` and ``docs/research/face-varying.md``.

The module needs numpy only (no bidegree, no bpy), except :func:`suzanne` and :func:`blender_text`,
which take Blender's Suzanne (positions and UVs) and Blender's Text > Convert to Mesh from ``bpy``
when called (``with_blender=False`` leaves them out). Coordinates are float32 values (Blender
computes in float32) and sharpness values are exactly what Blender derives from its crease
attribute (``10 c^2`` with ``c`` a float32): 10 (infinite), 2.5, 1.40625 and 0.625 are ``c`` =
1, 0.5, 0.375 and 0.25.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass, field

import numpy as np

#: Infinitely sharp (OpenSubdiv's ``Sdc::Crease::SHARPNESS_INFINITE``; Blender's crease 1.0).
INF = 10.0
#: Semi-sharp values Blender represents exactly (crease 0.5, 0.375, 0.25).
SHARP_2_5, SHARP_1_4, SHARP_0_6 = 2.5, 1.40625, 0.625

BOUNDARIES = ("edge-only", "edge-and-corner", "none")


@dataclass(frozen=True)
class DirtyCage:
    """A cage with everything OpenSubdiv's ``Far::TopologyDescriptor`` and Blender carry.

    Attributes:
        name: Short identifier (used as the pytest id).
        points: ``(V, 3)`` float64 positions, float32-representable.
        faces: The polygons (vertex indices; a face may repeat a vertex).
        sharp_edges: ``(a, b, sharpness)`` edge sharpness (OpenSubdiv units, 10 = infinite).
        sharp_vertices: ``(vertex, sharpness)`` vertex sharpness.
        holes: Faces tagged as holes (``Far::TopologyDescriptor::holeIndices``, OBJ ``t hole``).
        loose_edges: Edges in no face (Blender meshes and OBJ ``l`` lines have them).
        boundary: ``"edge-only"``, ``"edge-and-corner"`` or ``"none"`` (boundary faces are holes).
        uvs: ``(C, 2)`` face-varying values, one per face corner, or ``None``.
        note: What the cage is for.
    """

    name: str
    points: np.ndarray
    faces: tuple[tuple[int, ...], ...]
    sharp_edges: tuple[tuple[int, int, float], ...] = ()
    sharp_vertices: tuple[tuple[int, float], ...] = ()
    holes: tuple[int, ...] = ()
    loose_edges: tuple[tuple[int, int], ...] = ()
    boundary: str = "edge-only"
    uvs: np.ndarray | None = field(default=None, compare=False)
    note: str = ""

    def __post_init__(self) -> None:
        if self.boundary not in BOUNDARIES:
            raise ValueError(f"{self.name}: unknown boundary {self.boundary!r}")
        used = {v for f in self.faces for v in f} | {v for e in self.loose_edges for v in e}
        if used and max(used) >= len(self.points):
            raise ValueError(f"{self.name}: vertex index out of range")
        if self.uvs is not None and len(self.uvs) != sum(len(f) for f in self.faces):
            raise ValueError(f"{self.name}: one UV per face corner")

    @property
    def face_sizes(self) -> np.ndarray:
        """``(F,)`` int64 corner count per face."""
        return np.array([len(f) for f in self.faces], dtype=np.int64)

    @property
    def face_indices(self) -> np.ndarray:
        """``(C,)`` int64 vertex of each face corner."""
        return np.array([v for f in self.faces for v in f], dtype=np.int64)

    @property
    def creases(self) -> tuple[np.ndarray, np.ndarray] | None:
        """As :attr:`bidegree.Mesh.creases`: ``((K, 2) int64 pairs, (K,) float32)`` or ``None``."""
        if not self.sharp_edges:
            return None
        pairs = np.array([(a, b) for a, b, _ in self.sharp_edges], dtype=np.int64)
        return pairs, np.array([s for *_, s in self.sharp_edges], dtype=np.float32)

    @property
    def corners(self) -> tuple[np.ndarray, np.ndarray] | None:
        """As :attr:`bidegree.Mesh.corners`: ``((K,) int64 vertices, (K,) float32)`` or ``None``."""
        if not self.sharp_vertices:
            return None
        verts = np.array([v for v, _ in self.sharp_vertices], dtype=np.int64)
        return verts, np.array([s for _, s in self.sharp_vertices], dtype=np.float32)

    def with_changes(self, name: str, **changes: object) -> DirtyCage:
        """A copy under another name with some fields replaced."""
        fields = {k: getattr(self, k) for k in self.__dataclass_fields__}
        fields.update(changes, name=name)
        return DirtyCage(**fields)  # type: ignore[arg-type]


def _f32(points: np.ndarray) -> np.ndarray:
    return np.asarray(points, dtype=np.float32).astype(np.float64)


def _wobble(points: np.ndarray, amount: float = 0.03) -> np.ndarray:
    """A deterministic, non-planar perturbation (no two parity points may coincide by accident)."""
    p = np.asarray(points, dtype=np.float64)
    i = np.arange(p.size, dtype=np.float64).reshape(p.shape)
    return _f32(p + amount * np.sin(1.7 * i + 0.3))


def grid(n: int, m: int | None = None) -> DirtyCage:
    """An open ``n x m`` grid of quads over the xy plane, gently curved (vertex
    ``i * (m + 1) + j`` above (i, j))."""
    m = n if m is None else m
    i, j = np.meshgrid(np.arange(n + 1), np.arange(m + 1), indexing="ij")
    height = 0.2 * np.sin(i + 0.7 * j)
    points = np.stack([i, j, height], axis=-1).reshape(-1, 3).astype(np.float64)
    w = m + 1
    faces = tuple(
        (a * w + b, (a + 1) * w + b, (a + 1) * w + b + 1, a * w + b + 1)
        for a in range(n)
        for b in range(m)
    )
    return DirtyCage(f"grid-{n}x{m}", _f32(points), faces)


def _gv(m: int, i: int, j: int) -> int:
    """Vertex (i, j) of a :func:`grid` with ``m`` quads along y."""
    return i * (m + 1) + j


CUBE_POINTS = np.array(
    [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0, 0, 1], [1, 0, 1], [1, 1, 1], [0, 1, 1]],
    dtype=np.float64,
)
CUBE_FACES = ((0, 3, 2, 1), (4, 5, 6, 7), (0, 1, 5, 4), (1, 2, 6, 5), (2, 3, 7, 6), (3, 0, 4, 7))


def cube() -> DirtyCage:
    """The unit cube, outward faces, slightly perturbed."""
    return DirtyCage("cube", _wobble(CUBE_POINTS, 0.05), CUBE_FACES)


# ------------------------------------------------------------------------------------------
# issue 13: non-manifold, flipped, loose, degenerate, holes, boundary none, bowties, valence 2


def fin(pages: int, strip: int = 2) -> DirtyCage:
    """A 4x4 grid with ``pages - 2`` fins standing on a line of ``strip`` interior grid edges.

    The grid line from (1, 2) to (1 + strip, 2) has ``pages`` faces on each of its edges (two from
    the grid, one per fin). Its inner vertices have two non-manifold edges, no boundary edge and
    more faces than edges: OpenSubdiv does not sharpen them (Crease rule); its end vertices are
    sharpened (corners). Fins alternate their orientation.
    """
    base = grid(4)
    points = list(base.points)
    faces = list(base.faces)
    line = [_gv(4, 1 + k, 2) for k in range(strip + 1)]
    for page in range(pages - 2):
        angle = np.pi * (page + 1) / (pages - 1)
        up = np.array([0.0, 0.8 * np.cos(angle), 0.8 * np.sin(angle)])
        top = []
        for v in line:
            top.append(len(points))
            points.append(base.points[v] + up + [0.02 * page, 0.0, 0.0])
        for k in range(strip):
            quad = (line[k], line[k + 1], top[k + 1], top[k])
            faces.append(quad if page % 2 == 0 else quad[::-1])
    return DirtyCage(
        f"non-manifold-edge-{pages}-faces",
        _f32(np.array(points)),
        tuple(faces),
        note=f"{strip} grid edges with {pages} faces each",
    )


def book(pages: int = 100) -> DirtyCage:
    """``pages`` strips of two quads hinged on one edge (a book): an edge with ``pages`` faces."""
    points = [np.array([0.0, 0.0, 0.0]), np.array([0.0, 0.0, 1.0])]
    faces = []
    for page in range(pages):
        angle = 2 * np.pi * page / pages
        d = np.array([np.cos(angle), np.sin(angle), 0.0])
        bend = np.array([-np.sin(angle), np.cos(angle), 0.0]) * 0.15 * np.sin(3 * angle)
        first = len(points)
        for step in (1, 2):
            points += [step * 0.5 * d + (step - 1) * bend, step * 0.5 * d + [0, 0, 1.0]]
        a, b, c, e = first, first + 1, first + 2, first + 3
        quads = [(0, a, b, 1), (a, c, e, b)]
        faces += [q if page % 2 == 0 else q[::-1] for q in quads]
    return DirtyCage(
        f"non-manifold-edge-{pages}-faces",
        _f32(np.array(points)),
        tuple(faces),
        note="a book: one edge shared by every page",
    )


def duplicate_face() -> DirtyCage:
    """A 3x3 grid whose centre face appears twice (an Array with merge can make this)."""
    base = grid(3)
    return DirtyCage(
        "duplicate-face",
        base.points,
        (*base.faces, base.faces[4]),
        note="each edge of the centre face has 3 faces",
    )


def flipped_face() -> DirtyCage:
    """A cube with one face reversed: its 4 edges have two faces that agree on the direction."""
    c = cube()
    faces = list(c.faces)
    faces[3] = faces[3][::-1]
    return DirtyCage("flipped-face", c.points, tuple(faces), note="face 3 reversed")


def loose_edges() -> DirtyCage:
    """A cube with a loose edge at a cube vertex, a loose edge on its own and an isolated vertex.

    Blender drops the loose edges and the vertices in no face, and makes vertex 6 (on a loose
    edge and on faces) infinitely sharp (``subdiv_converter_mesh.cc``).
    """
    c = cube()
    extra = np.array([[1.6, 1.7, 1.8], [2.5, 0.0, 0.0], [3.0, 0.5, 0.0], [-1.0, -1.0, -1.0]])
    return DirtyCage(
        "loose-edges",
        _f32(np.vstack([c.points, extra])),
        c.faces,
        loose_edges=((6, 8), (9, 10)),
        note="vertex 6 touches a loose edge; 8, 9, 10 and 11 are in no face",
    )


def repeated_vertex() -> DirtyCage:
    """A closed 'UV sphere' whose pole faces are quads repeating the pole (``f 4 3 5 5``)."""
    rings, segments = 3, 6
    points = [[0.0, 0.0, -1.0]]
    for r in range(1, rings + 1):
        phi = np.pi * r / (rings + 1)
        for s in range(segments):
            t = 2 * np.pi * s / segments
            points.append([np.sin(phi) * np.cos(t), np.sin(phi) * np.sin(t), -np.cos(phi)])
    points.append([0.0, 0.0, 1.0])
    south, north = 0, len(points) - 1

    def ring(r: int, s: int) -> int:
        return 1 + (r - 1) * segments + s % segments

    faces = []
    for s in range(segments):
        faces.append((south, ring(1, s + 1), ring(1, s), south))
        for r in range(1, rings):
            faces.append((ring(r, s), ring(r, s + 1), ring(r + 1, s + 1), ring(r + 1, s)))
        faces.append((ring(rings, s), ring(rings, s + 1), north, north))
    return DirtyCage(
        "repeated-vertex",
        _wobble(np.array(points), 0.02),
        tuple(faces),
        note="pole quads repeat the pole vertex (a degenerate edge each)",
    )


def zero_area_faces() -> DirtyCage:
    """A grid with a collapsed quad (two vertices at one position) and a zero-area triangle."""
    base = grid(3)
    points = base.points.copy()
    # Collapse face 4 (the centre quad) onto its side x = 1: (2, 1) and (2, 2) move onto (1, 1)
    # and (1, 2), so its four corners are two pairs of coincident points.
    points[_gv(3, 2, 1)] = points[_gv(3, 1, 1)]
    points[_gv(3, 2, 2)] = points[_gv(3, 1, 2)]
    # A triangle of three collinear points hanging off the boundary edge x = 0.
    a, b = _gv(3, 0, 0), _gv(3, 0, 1)
    mid = len(points)
    points = np.vstack([points, (points[a] + points[b]) / 2])
    faces = [*base.faces, (a, b, mid)]
    return DirtyCage(
        "zero-area-faces",
        _f32(points),
        tuple(faces),
        note="face 4 collapsed onto a segment; the last face has collinear corners",
    )


def text_like() -> DirtyCage:
    """What Text > Convert to Mesh gives: a letter outline (an 'L') fan-triangulated, with
    collinear points along its straight sides, hence zero-area triangles."""
    outline = [
        (0, 0),
        (1, 0),
        (2, 0),
        (3, 0),
        (3, 1),
        (2, 1),
        (1, 1),
        (1, 2),
        (1, 3),
        (1, 4),
        (0, 4),
        (0, 3),
        (0, 2),
        (0, 1),
    ]
    points = np.array([(x * 0.25, y * 0.25, 0.0) for x, y in outline])
    faces = tuple((0, k, k + 1) for k in range(1, len(outline) - 1))
    return DirtyCage(
        "text-like",
        _f32(points),
        faces,
        note="fan triangles from vertex 0; those along the bottom and left sides have zero area",
    )


def blender_text(body: str = "Text") -> DirtyCage:
    """Blender's own Text > Convert to Mesh output (the default text object has four zero-area
    triangles); needs ``bpy``."""
    import bpy

    curve = bpy.data.curves.new("bidegree_text", "FONT")
    obj = bpy.data.objects.new("bidegree_text", curve)
    try:
        curve.body = body
        bpy.context.scene.collection.objects.link(obj)
        evaluated = obj.evaluated_get(bpy.context.evaluated_depsgraph_get())
        mesh = evaluated.to_mesh()
        try:
            points = np.array([v.co[:] for v in mesh.vertices], dtype=np.float64)
            faces = tuple(tuple(p.vertices) for p in mesh.polygons)
        finally:
            evaluated.to_mesh_clear()
    finally:
        bpy.data.objects.remove(obj, do_unlink=True)
        bpy.data.curves.remove(curve)
    return DirtyCage(
        "blender-text", _f32(points), faces, note=f"Text > Convert to Mesh of {body!r}"
    )


def holes() -> DirtyCage:
    """A 5x5 grid with an interior hole and a hole on the boundary."""
    base = grid(5)
    return base.with_changes(
        "holes", holes=(12, 4), note="face 12 interior, face 4 on the boundary"
    )


def torus_with_hole() -> DirtyCage:
    """A closed 8x6 torus with one hole face."""
    n, m = 8, 6
    i, j = np.meshgrid(np.arange(n), np.arange(m), indexing="ij")
    u, v = 2 * np.pi * i / n, 2 * np.pi * j / m
    r = 2.0 + 0.7 * np.cos(v)
    points = np.stack([r * np.cos(u), 0.7 * np.sin(v), r * np.sin(u)], axis=-1).reshape(-1, 3)
    a, b = i * m + j, ((i + 1) % n) * m + j
    c, d = ((i + 1) % n) * m + (j + 1) % m, i * m + (j + 1) % m
    faces = tuple(tuple(int(x) for x in q) for q in np.stack([a, d, c, b], axis=-1).reshape(-1, 4))
    return DirtyCage("torus-hole", _wobble(points, 0.02), faces, holes=(9,))


def boundary_none() -> list[DirtyCage]:
    """``interpolateboundary 0``: a 4x4 grid, plain and with one boundary side creased
    infinitely (the faces along that side are then not holes)."""
    base = grid(4)
    side = [(_gv(4, 0, j), _gv(4, 0, j + 1), INF) for j in range(4)]
    return [
        base.with_changes("boundary-none", boundary="none"),
        base.with_changes("boundary-none-creased-side", boundary="none", sharp_edges=tuple(side)),
    ]


def _rotation(axis: int, angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    i, j = [k for k in range(3) if k != axis]
    r = np.eye(3)
    r[i, i], r[i, j], r[j, i], r[j, j] = c, -s, s, c
    return r


def bowtie(boundary: str) -> DirtyCage:
    """Two 2x2 grids that touch at one vertex, the middle of a side of each, sharing no edge
    (the second is the first turned half round the vertical through that vertex and tilted)."""
    first = grid(2)
    touch = _gv(2, 2, 1)  # (2, 1): middle of the side x = 2
    centre = first.points[touch]
    turn = _rotation(0, 1.2) @ _rotation(2, np.pi)
    second = (first.points - centre) @ turn.T + centre
    keep = [v for v in range(len(second)) if v != touch]
    renumber = {v: len(first.points) + k for k, v in enumerate(keep)}
    renumber[touch] = touch
    faces = list(first.faces) + [tuple(renumber[v] for v in f) for f in first.faces]
    return DirtyCage(
        f"bowtie-{boundary}",
        _f32(np.vstack([first.points, second[keep]])),
        tuple(faces),
        boundary=boundary,
        note=f"vertex {touch}: two fans of two faces each, four boundary edges",
    )


def double_cone() -> DirtyCage:
    """Two closed square pyramids sharing their apex: a bowtie vertex with no boundary edge."""
    ring = [[np.cos(t), np.sin(t), 1.0] for t in np.pi / 2 * np.arange(4)]
    top = np.array([[0.0, 0.0, 0.0], *ring])
    top_faces = [(0, 1 + (k + 1) % 4, 1 + k) for k in range(4)] + [(1, 2, 3, 4)]
    # The second pyramid: mirrored through z = 0 (so its faces reverse), turned and scaled.
    bottom = top[1:] @ (_rotation(2, 0.4) @ np.diag([0.8, 0.8, -1.2])).T
    faces = top_faces + [tuple(0 if v == 0 else v + 4 for v in f[::-1]) for f in top_faces]
    return DirtyCage(
        "bowtie-closed",
        _wobble(np.vstack([top, bottom]), 0.02),
        tuple(faces),
        note="vertex 0: two closed fans of four triangles",
    )


def valence_two(sharpness: float) -> DirtyCage:
    """A cube whose edge 1-2 is split by vertex 8 (valence 2: two faces, two edges), both halves
    creased with ``sharpness`` (none at 0: an interior vertex of valence 2): Blender adds
    min(sharpness) to vertex 8's sharpness (``topology_refiner_factory.cc``,
    ``assignComponentTags``); OpenSubdiv alone does not."""
    c = cube()
    points = np.vstack([c.points, (c.points[1] + c.points[2]) / 2 + [0.08, 0.0, 0.03]])
    faces = [list(f) for f in c.faces]
    faces[0] = [0, 3, 2, 8, 1]  # bottom: 0 3 2 1 with 8 between 2 and 1
    faces[3] = [1, 8, 2, 6, 5]  # side: 1 2 6 5 with 8 between 1 and 2
    creases = ((1, 8, sharpness), (8, 2, sharpness)) if sharpness > 0 else ()
    label = "inf" if sharpness >= INF else f"{sharpness:g}"
    return DirtyCage(
        f"valence-2-crease-{label}" if creases else "valence-2-smooth",
        _f32(points),
        tuple(tuple(f) for f in faces),
        sharp_edges=creases,
        note="vertex 8 has two edges, both creased" if creases else "vertex 8 has two edges",
    )


def creased_plane() -> DirtyCage:
    """A 3x3 grid whose whole boundary is creased semi-sharp: its four corner vertices have two
    edges each, both creased, so Blender makes them semi-sharp corners (edge-only boundary)."""
    base = grid(3)
    w = 4
    ring = [(0, j) for j in range(3)] + [(i, 3) for i in range(3)]
    ring += [(3, j) for j in range(3, 0, -1)] + [(i, 0) for i in range(3, 0, -1)]
    edges = []
    for (i, j), (k, m) in zip(ring, ring[1:] + ring[:1], strict=True):
        edges.append((i * w + j, k * w + m, SHARP_2_5))
    return base.with_changes("creased-boundary", sharp_edges=tuple(edges))


def issue_13_cages(*, with_blender: bool = True) -> dict[str, DirtyCage]:
    """Every cage of issue 13's test list, by name (Blender's text needs ``bpy``)."""
    cages = [
        fin(3),
        fin(4),
        book(100),
        duplicate_face(),
        flipped_face(),
        loose_edges(),
        repeated_vertex(),
        zero_area_faces(),
        text_like(),
        holes(),
        torus_with_hole(),
        *boundary_none(),
        bowtie("edge-only"),
        bowtie("edge-and-corner"),
        double_cone(),
        valence_two(0.0),
        valence_two(INF),
        valence_two(SHARP_2_5),
        valence_two(SHARP_0_6),
        creased_plane(),
    ]
    if with_blender:
        cages.append(blender_text())
    return {c.name: c for c in cages}


# ------------------------------------------------------------------------------------------
# issue 14: UV layouts


def _uv_jitter(uvs: np.ndarray, amount: float = 0.01) -> np.ndarray:
    """Make a layout non-affine (smooth and linear rules then differ everywhere), deterministically
    and the same for every corner that shares a value."""
    u = np.asarray(uvs, dtype=np.float64)
    bumped = u + amount * np.stack(
        [np.sin(7.1 * u[:, 1] + 3.3 * u[:, 0]), np.cos(5.3 * u[:, 0] - 2.1 * u[:, 1])], axis=1
    )
    return np.asarray(bumped, dtype=np.float32).astype(np.float64)


def cube_unwrap() -> DirtyCage:
    """A cube with a cross unwrap (the usual 6-face layout: 14 UV values, 7 seams)."""
    c = cube()
    # Cross layout on a 4 x 3 lattice of unit cells: column 1 holds -y, bottom, +y, top.
    # Cross layout on unit cells: column 1 holds -y, bottom, +y and top (rows 0..3), -x and +x
    # flank the bottom. Each face's corner UVs in face order, so that shared edges line up.
    corner_uv = {
        0: [(1, 1), (1, 2), (2, 2), (2, 1)],  # 0 3 2 1
        1: [(1, 4), (2, 4), (2, 3), (1, 3)],  # 4 5 6 7
        2: [(1, 1), (2, 1), (2, 0), (1, 0)],  # 0 1 5 4
        3: [(2, 1), (2, 2), (3, 2), (3, 1)],  # 1 2 6 5
        4: [(2, 2), (1, 2), (1, 3), (2, 3)],  # 2 3 7 6
        5: [(1, 2), (1, 1), (0, 1), (0, 2)],  # 3 0 4 7
    }
    uvs = np.array([corner_uv[f][k] for f in range(6) for k in range(4)], dtype=np.float64)
    return DirtyCage(
        "uv-cube-unwrap",
        c.points,
        c.faces,
        uvs=_uv_jitter(uvs / 4.0),
        note="cross layout, every value on a seam",
    )


def cylinder_seam(segments: int = 8, rings: int = 3) -> DirtyCage:
    """An open cylinder with UVs wrapped around it and one seam (u = 0 and u = 1)."""
    points, faces, uvs = [], [], []
    for r in range(rings + 1):
        for s in range(segments):
            t = 2 * np.pi * s / segments
            points.append([np.cos(t), np.sin(t), 0.5 * r])
    for r in range(rings):
        for s in range(segments):
            a, b = r * segments + s, r * segments + (s + 1) % segments
            faces.append((a, b, b + segments, a + segments))
            u0, u1 = s / segments, (s + 1) / segments
            v0, v1 = r / rings, (r + 1) / rings
            uvs += [(u0, v0), (u1, v0), (u1, v1), (u0, v1)]
    return DirtyCage(
        "uv-cylinder-seam",
        _wobble(np.array(points), 0.02),
        tuple(faces),
        uvs=_uv_jitter(np.array(uvs)),
        note="open cylinder, one seam along s = 0",
    )


def uv_grid_pinned_corner() -> DirtyCage:
    """A 4x4 grid with its UVs = positions, one corner's UV pinned away from the grid."""
    base = grid(4)
    uvs = np.array([base.points[v, :2] / 4.0 for f in base.faces for v in f])
    corner = _gv(4, 0, 0)
    at = np.array([v == corner for f in base.faces for v in f])
    uvs[at] = (-0.15, -0.08)
    return base.with_changes(
        "uv-grid-pinned-corner", uvs=_uv_jitter(uvs), note="corner (0, 0) pinned at (-0.15, -0.08)"
    )


def uv_junctions() -> DirtyCage:
    """A 4x4 grid cut into five UV islands: vertex (2, 2) has 4 UV values, vertex (2, 1) has 3.

    Seams run along x = 2 and y = 2 (four quadrants) and along y = 1 for x >= 2 (the lower right
    quadrant in two). Each island is shifted, so no two islands share a UV coordinate.
    """
    base = grid(4)

    def island(f: int) -> int:
        a, b = divmod(f, 4)  # the face's cell (x, y)
        if a < 2:
            return 0 if b < 2 else 1
        if b >= 2:
            return 2
        return 3 if b < 1 else 4

    shift = {0: (0.0, 0.0), 1: (0.0, 0.3), 2: (0.3, 0.3), 3: (0.3, -0.2), 4: (0.6, 0.0)}
    uvs = np.array(
        [
            base.points[v, :2] / 4.0 + shift[island(f)]
            for f, face in enumerate(base.faces)
            for v in face
        ]
    )
    return base.with_changes(
        "uv-junctions",
        uvs=_uv_jitter(uvs),
        sharp_edges=((_gv(4, 0, 1), _gv(4, 1, 1), SHARP_1_4),),
        note="vertex 12 = (2, 2) has 4 values, vertex 11 = (2, 1) has 3; one semi-sharp crease",
    )


def suzanne() -> DirtyCage:
    """Blender's Suzanne with its UVs (from ``bmesh.ops.create_monkey(calc_uvs=True)``; needs
    ``bpy``, which the comparison with Blender needs anyway)."""
    import bmesh

    bm = bmesh.new()
    try:
        layer = bm.loops.layers.uv.new("UVMap")
        bmesh.ops.create_monkey(bm, calc_uvs=True)
        points = np.array([v.co[:] for v in bm.verts], dtype=np.float64)
        faces = tuple(tuple(v.index for v in f.verts) for f in bm.faces)
        uvs = np.array([loop[layer].uv[:] for f in bm.faces for loop in f.loops])
    finally:
        bm.free()
    return DirtyCage("uv-suzanne", _f32(points), faces, uvs=_f32(uvs), note="Blender's own UVs")


def _sheet_uvs(cage: DirtyCage, name: str, cut: tuple[int, ...] = ()) -> DirtyCage:
    """``cage`` with a UV island per sheet: faces joined across manifold edges (two faces running
    opposite ways) share an island, flattened on its two principal axes and shifted apart, so
    every non-manifold edge and vertex is a seam between sheets; the faces in ``cut`` are an
    island of their own (a seam inside a sheet)."""
    faces = [list(f) for f in cage.faces]
    uses: dict[tuple[int, int], list[tuple[int, bool]]] = {}
    for f, face in enumerate(faces):
        for a, b in itertools.pairwise([*face, face[0]]):
            uses.setdefault((min(a, b), max(a, b)), []).append((f, a < b))
    island = list(range(len(faces)))

    def root(f: int) -> int:
        while island[f] != f:
            f = island[f]
        return f

    for pair in uses.values():
        if (
            len(pair) == 2
            and pair[0][1] != pair[1][1]
            and (pair[0][0] in cut) == (pair[1][0] in cut)
        ):
            island[root(pair[0][0])] = root(pair[1][0])
    roots = sorted({root(f) for f in range(len(faces))})
    points = np.asarray(cage.points, dtype=np.float64)
    uvs = np.zeros((sum(len(f) for f in faces), 2))
    starts = np.cumsum([0] + [len(f) for f in faces])
    for k, r in enumerate(roots):
        members = [f for f in range(len(faces)) if root(f) == r]
        verts = sorted({v for f in members for v in faces[f]})
        centre = points[verts].mean(axis=0)
        axes = np.linalg.svd(points[verts] - centre)[2][:2]
        for f in members:
            flat = (points[faces[f]] - centre) @ axes.T
            uvs[starts[f] : starts[f + 1]] = 0.25 * flat + [0.8 * k, 0.0]
    return cage.with_changes(
        name, uvs=_uv_jitter(uvs), note=f"{len(roots)} UV islands, one per sheet"
    )


def non_manifold_uv_cages() -> dict[str, DirtyCage]:
    """Issue 13's non-manifold cages with UVs (issue 14's modes on them): a 3-face fin, a book of
    4 pages, a bowtie whose second fan is cut by a seam."""
    cages = [
        _sheet_uvs(fin(3), "uv-fin-3"),
        _sheet_uvs(book(4), "uv-book-4"),
        _sheet_uvs(bowtie("edge-only"), "uv-bowtie-seam", cut=(4, 5)),
    ]
    return {c.name: c for c in cages}


def issue_14_cages(*, with_blender: bool = True) -> dict[str, DirtyCage]:
    """Every UV cage of issue 14's test list, by name (Suzanne needs ``bpy``)."""
    cages = [cube_unwrap(), cylinder_seam(), uv_grid_pinned_corner(), uv_junctions()]
    if with_blender:
        cages.append(suzanne())
    return {c.name: c for c in cages}
