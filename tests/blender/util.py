"""Helpers of the Blender tests: scenes built with the plain bpy API, independent references.

The references never use the add-on's own reading path: a cage is read from a separate object
that shares the mesh and has only the modifiers above bidegree, with the per-element API.
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterator
from typing import Any, ClassVar

import numpy as np
import pytest

bpy = pytest.importorskip("bpy")

CUBE_POINTS = [(x, y, z) for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)]
CUBE_FACES = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]


def make_object(scene: Any, name: str, points: Any, faces: Any, edges: Any = ()) -> Any:
    """A mesh object linked into ``scene`` (built with the plain, slow API on purpose)."""
    mesh = bpy.data.meshes.new(name)
    mesh.from_pydata([tuple(map(float, p)) for p in points], list(edges), [list(f) for f in faces])
    mesh.update()
    obj = bpy.data.objects.new(name, mesh)
    scene.collection.objects.link(obj)
    return obj


def cube(scene: Any, name: str = "Cube") -> Any:
    """The cube [-1, 1]^3."""
    return make_object(scene, name, CUBE_POINTS, CUBE_FACES)


def update() -> Any:
    """Evaluate the view layer (the add-on's handlers run) and return its depsgraph."""
    bpy.context.view_layer.update()
    return bpy.context.evaluated_depsgraph_get()


def mesh_arrays(mesh: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Points, face sizes and corner vertices of a mesh (plain API)."""
    points = np.array([tuple(v.co) for v in mesh.vertices], dtype=np.float32).reshape(-1, 3)
    sizes = np.array([p.loop_total for p in mesh.polygons], dtype=np.int32)
    corners = np.array([i for p in mesh.polygons for i in p.vertices], dtype=np.int32)
    return points, sizes, corners


def evaluated(obj: Any, depsgraph: Any = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`mesh_arrays` of ``obj``'s evaluated mesh."""
    depsgraph = depsgraph or bpy.context.evaluated_depsgraph_get()
    ev = obj.evaluated_get(depsgraph)
    mesh = ev.to_mesh()
    try:
        return mesh_arrays(mesh)
    finally:
        ev.to_mesh_clear()


def snapshot(obj: Any) -> tuple[bytes, bytes, bytes, int]:
    """The object's own mesh, for checks that nothing of it changed."""
    points, sizes, corners = mesh_arrays(obj.data)
    return points.tobytes(), sizes.tobytes(), corners.tobytes(), len(obj.data.edges)


@contextlib.contextmanager
def only_modifiers_above(obj: Any, mod: Any, *, render: bool = False) -> Iterator[Any]:
    """A temporary object sharing ``obj``'s mesh, transform and the modifiers above ``mod``
    (copies, with their toggles): its evaluated mesh is the cage at ``mod``'s place."""
    ref = bpy.data.objects.new(f"{obj.name}.reference", obj.data)
    bpy.context.scene.collection.objects.link(ref)
    ref.matrix_world = obj.matrix_world
    for other in obj.modifiers:
        if other == mod:
            break
        copy = ref.modifiers.new(other.name, other.type)
        for prop in other.bl_rna.properties:
            if not prop.is_readonly and prop.identifier not in {"name", "type"}:
                with contextlib.suppress(AttributeError, TypeError, ValueError):
                    setattr(copy, prop.identifier, getattr(other, prop.identifier))
    try:
        yield ref
    finally:
        bpy.data.objects.remove(ref)


def cage_reference(obj: Any, mod: Any, depsgraph: Any = None, *, crease: bool = True) -> Any:
    """The cage at ``mod``'s place as a :class:`bidegree.Mesh` (viewport evaluation)."""
    import bidegree

    with only_modifiers_above(obj, mod) as ref:
        depsgraph = update()
        ev = ref.evaluated_get(depsgraph)
        me = ev.to_mesh()
        try:
            points = np.array([tuple(v.co) for v in me.vertices], dtype=np.float32)
            faces = [list(p.vertices) for p in me.polygons]
            creases = None
            attr = me.attributes.get("crease_edge")
            if crease and attr is not None:
                pairs = [(e.vertices[0], e.vertices[1], attr.data[e.index].value) for e in me.edges]
                pairs = [p for p in pairs if p[2] > 0]
                if pairs:
                    creases = (
                        np.array([p[:2] for p in pairs], dtype=np.int64),
                        np.array([10.0 * p[2] ** 2 for p in pairs], dtype=np.float32),
                    )
            return bidegree.Mesh(points, faces, creases=creases)
        finally:
            ev.to_mesh_clear()


def assert_surface(arrays: tuple[np.ndarray, np.ndarray, np.ndarray], ref: Any, atol=1e-6) -> None:
    """Evaluated mesh arrays equal the bidegree ``Result`` ``ref``."""
    points, sizes, corners = arrays
    np.testing.assert_array_equal(sizes, np.asarray(ref.face_sizes))
    np.testing.assert_array_equal(corners, np.asarray(ref.face_indices))
    np.testing.assert_allclose(points, np.asarray(ref.points), rtol=0, atol=atol)


class Probe:
    """A render engine that records what a render depsgraph evaluates (no pixels)."""

    seen: ClassVar[list[dict[str, Any]]] = []
    engine: ClassVar[Any] = None

    @classmethod
    def register(cls) -> None:
        if cls.engine is not None:
            return

        class BIDEGREE_TEST_probe(bpy.types.RenderEngine):
            bl_idname = "BIDEGREE_TEST_PROBE"
            bl_label = "bidegree test probe"

            def render(self, depsgraph: Any) -> None:
                frame = {"frame": depsgraph.scene.frame_current, "mode": depsgraph.mode}
                for inst in depsgraph.object_instances:
                    ob = inst.object
                    if ob.type == "MESH":
                        frame[ob.original.name] = mesh_arrays(ob.to_mesh())
                        ob.to_mesh_clear()
                Probe.seen.append(frame)

        bpy.utils.register_class(BIDEGREE_TEST_probe)
        cls.engine = BIDEGREE_TEST_probe

    @classmethod
    def render(cls, scene: Any, *, animation: bool = False) -> list[dict[str, Any]]:
        """Render ``scene`` with the probe; returns one record per frame."""
        cls.register()
        cls.seen = []
        if scene.camera is None:
            camera = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
            scene.collection.objects.link(camera)
            scene.camera = camera
        engine = scene.render.engine
        scene.render.engine = "BIDEGREE_TEST_PROBE"
        scene.render.resolution_x = scene.render.resolution_y = 4
        try:
            assert bpy.ops.render.render(animation=animation, write_still=False) == {"FINISHED"}
        finally:
            scene.render.engine = engine
        return list(cls.seen)


def cycles_coverage(scene: Any, size: int = 64) -> int:
    """Pixels covered by geometry in a tiny Cycles render (1 sample, transparent film)."""
    if scene.camera is None:
        camera = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
        camera.location = (0.0, -6.0, 0.0)
        camera.rotation_euler = (1.5708, 0.0, 0.0)
        scene.collection.objects.link(camera)
        scene.camera = camera
    scene.render.engine = "CYCLES"
    scene.cycles.samples = 1
    scene.cycles.device = "CPU"
    scene.render.film_transparent = True
    scene.render.resolution_x = scene.render.resolution_y = size
    scene.render.resolution_percentage = 100
    assert bpy.ops.render.render(write_still=False) == {"FINISHED"}
    image = bpy.data.images["Render Result"]
    path = bpy.app.tempdir + "bidegree_coverage.png"
    image.save_render(path)
    loaded = bpy.data.images.load(path)
    try:
        pixels = np.array(loaded.pixels[:], dtype=np.float32).reshape(-1, 4)
        return int((pixels[:, 3] > 0.5).sum())
    finally:
        bpy.data.images.remove(loaded)
