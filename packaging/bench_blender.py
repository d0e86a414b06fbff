"""Benchmark (not a test): bidegree live updates vs Blender's Subdivision Surface modifier.

One ``bpy`` process.  The cage is Suzanne subdivided twice (Catmull-Clark, applied), so it is
all quads.  Timed, each as the median of several repetitions:

* **cached update** at degree 4, level 2: move a vertex, let the depsgraph re-evaluate, then
  the live update through the cached plan (read the evaluated cage, hash, ``Plan.evaluate``,
  write positions) -- what the add-on does on every edit;
* **fresh update**: the same with an empty cache (plan built, full mesh written);
* **Blender Subsurf level 2** on the same cage: move a vertex, depsgraph re-evaluation of an
  object with the modifier and access to its evaluated mesh (which forces Blender's lazy
  subdivision wrapper to subdivide; CPU OpenSubdiv, as in background mode).

Usage: ``.venv/bin/python packaging/bench_blender.py [--repeat 15] [--degree 4] [--levels 2]``
Prints the times and the ratios (target: cached update no slower than Blender's modifier).
"""

from __future__ import annotations

import argparse
import statistics
import time
from collections.abc import Callable

import bpy
from bidegree_blender import LiveCache, Settings, objects


def _median_ms(fn: Callable[[], None], repeat: int) -> float:
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        times.append((time.perf_counter() - t0) * 1000.0)
    return statistics.median(times)


def make_cage() -> bpy.types.Mesh:
    """Suzanne with two levels of Catmull-Clark applied (a pure-quad cage)."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.ops.mesh.primitive_monkey_add()
    monkey = bpy.context.active_object
    mod = monkey.modifiers.new("Subd", "SUBSURF")
    mod.levels = 2
    dg = bpy.context.evaluated_depsgraph_get()
    cage = bpy.data.meshes.new_from_object(monkey.evaluated_get(dg))
    bpy.data.objects.remove(monkey)
    return cage


def main() -> None:
    """Run the benchmark and print the results."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=15)
    parser.add_argument("--degree", type=int, default=4)
    parser.add_argument("--levels", type=int, default=2)
    args = parser.parse_args()

    cage = make_cage()
    scene = bpy.context.scene
    view_layer = bpy.context.view_layer

    source = bpy.data.objects.new("Source", cage)
    scene.collection.objects.link(source)
    result_mesh = bpy.data.meshes.new("Result")
    result = bpy.data.objects.new("Result", result_mesh)
    scene.collection.objects.link(result)
    result.parent = source

    blender = bpy.data.objects.new("Blender", cage.copy())
    scene.collection.objects.link(blender)
    blender.modifiers.new("Subd", "SUBSURF").levels = args.levels
    blender.hide_viewport = True  # evaluated only when timed
    view_layer.update()

    settings = Settings(degree=args.degree, levels=args.levels)
    cache = LiveCache()
    step = [0]

    def nudge(mesh: bpy.types.Mesh) -> None:
        step[0] += 1
        v = mesh.vertices[step[0] % len(mesh.vertices)]
        v.co.z += 1e-3 if step[0] % 2 else -1e-3
        mesh.update()

    def live_cached() -> None:
        nudge(source.data)
        view_layer.update()
        report = objects.update_result(cache, source, result, settings)
        assert report.action == "reused", report.action
        view_layer.update()

    def live_fresh() -> None:
        cache.clear()
        nudge(source.data)
        view_layer.update()
        report = objects.update_result(cache, source, result, settings)
        assert report.action == "built", report.action
        view_layer.update()

    live_fresh()  # warm-up (allocations, first depsgraph of the result)
    fresh_ms = _median_ms(live_fresh, max(3, args.repeat // 3))
    live_cached()
    cached_ms = _median_ms(live_cached, args.repeat)

    source.hide_viewport = True
    result.hide_viewport = True
    blender.hide_viewport = False
    view_layer.update()

    def blender_update() -> None:
        nudge(blender.data)
        view_layer.update()
        # Blender evaluates the last Subsurf lazily (a "subdivision wrapper" mesh): touching the
        # evaluated mesh is what makes it subdivide, as drawing or exporting would.
        ev = blender.evaluated_get(bpy.context.evaluated_depsgraph_get())
        assert len(ev.data.vertices) > len(blender.data.vertices)

    blender_update()
    blender_ms = _median_ms(blender_update, args.repeat)

    faces_out = len(result_mesh.polygons)
    ev = blender.evaluated_get(bpy.context.evaluated_depsgraph_get())
    blender_faces = len(ev.data.polygons)
    print(f"cage: Suzanne subdivided twice, {len(cage.polygons)} faces, {len(cage.vertices)} verts")
    print(f"bidegree degree {args.degree} level {args.levels}: {faces_out} faces")
    print(f"Blender Subsurf level {args.levels}: {blender_faces} faces")
    print(f"bidegree cached update : {cached_ms:8.2f} ms (median of {args.repeat})")
    print(f"bidegree fresh update  : {fresh_ms:8.2f} ms")
    print(f"Blender Subsurf update : {blender_ms:8.2f} ms (median of {args.repeat})")
    print(f"ratio cached / Subsurf : {cached_ms / blender_ms:8.2f}  (target <= 1)")
    print(f"ratio fresh / Subsurf  : {fresh_ms / blender_ms:8.2f}")
    print(f"ratio fresh / cached   : {fresh_ms / cached_ms:8.2f}")


if __name__ == "__main__":
    main()
