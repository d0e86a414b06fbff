"""Benchmark (not a test): bidegree in the modifier stack against Blender's Subdivision Surface.

One ``bpy`` process with the extension's handlers registered from ``addon/bidegree``. Cages:
Suzanne subdivided twice (7,872 quads) and three times (31,488 quads), Catmull-Clark applied.
For each cage, level (2, 3) and scheme (bidegree classic degree 3 = what Subsurf computes, and
bidegree's default averaging degree 4, both with the default *Limit Positions* as Subsurf's
default *Use Limit Surface*; degree 4 without it, ``avg 4 refin``, and with *Limit Normals*,
``avg 4 normal``), two operations are timed, each as the median of several repetitions, with
everything Blender does included (handlers, mesh writes, both depsgraph passes, the evaluated
mesh read back):

* **edit**: move one vertex of the cage (its shape keys' basis), ``view_layer.update()``, touch
  the evaluated mesh (as drawing or exporting would; it makes Subsurf's lazy wrapper subdivide);
* **frame**: step a shape-key animation one frame (``scene.frame_set``), touch the evaluated
  mesh.

The reference is an object with Blender's Subdivision Surface modifier (CPU OpenSubdiv, as in
background mode) at the same level on the same cage, timed the same way in the same run. The
ratio column is bidegree's time over Subsurf's (target: at most 0.5 on every row); the first
update (plan built, full mesh written) is reported as ``fresh``.

Usage: ``.venv/bin/python packaging/bench_blender.py [--repeat 7] [--cages 8k,30k]
[--levels 2,3]``. Prints the load average first: on a shared machine, compare ratios only.
"""

from __future__ import annotations

import argparse
import importlib.util
import os
import statistics
import sys
import time
from collections.abc import Callable
from pathlib import Path

import bpy

ROOT = Path(__file__).resolve().parents[1]


def _register_addon() -> None:
    """Register the extension's handlers and operators from the source tree (its package name
    would clash with the ``bidegree`` wheel, so it is loaded under another one)."""
    spec = importlib.util.spec_from_file_location(
        "bidegree_addon",
        ROOT / "addon" / "bidegree" / "__init__.py",
        submodule_search_locations=[str(ROOT / "addon" / "bidegree")],
    )
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules["bidegree_addon"] = module
    spec.loader.exec_module(module)
    module.register()


def _median_ms(fn: Callable[[], None], repeat: int) -> float:
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        times.append((time.perf_counter() - t0) * 1000.0)
    return statistics.median(times)


def make_cage(subdivisions: int) -> bpy.types.Mesh:
    """Suzanne with ``subdivisions`` levels of Catmull-Clark applied (a pure-quad cage)."""
    bpy.ops.mesh.primitive_monkey_add()
    monkey = bpy.context.active_object
    mod = monkey.modifiers.new("Subd", "SUBSURF")
    mod.levels = subdivisions
    cage = bpy.data.meshes.new_from_object(
        monkey.evaluated_get(bpy.context.evaluated_depsgraph_get())
    )
    bpy.data.objects.remove(monkey)
    return cage


def _objects(scene: bpy.types.Scene, cage: bpy.types.Mesh, name: str) -> list[bpy.types.Object]:
    """Two objects on copies of ``cage``: one to edit, one with a shape key animated over
    frames 1..100 (edits of a shape-keyed mesh go through its basis key, not its vertices)."""
    edited = bpy.data.objects.new(f"{name} edit", cage.copy())
    animated = bpy.data.objects.new(f"{name} frame", cage.copy())
    for obj in (edited, animated):
        scene.collection.objects.link(obj)
    animated.shape_key_add(name="Basis")
    key = animated.shape_key_add(name="Bend", from_mix=False)
    for point in key.data:
        point.co.z += 0.2 * point.co.x * point.co.x
    block = animated.data.shape_keys.key_blocks["Bend"]
    block.value = 0.0
    block.keyframe_insert("value", frame=1)
    block.value = 1.0
    block.keyframe_insert("value", frame=100)
    return [edited, animated]


def _show_only(objects: list[bpy.types.Object], shown: bpy.types.Object) -> None:
    for obj in objects:
        obj.hide_viewport = obj is not shown
    bpy.context.view_layer.update()


def _touch(obj: bpy.types.Object) -> bytes:
    """Read the evaluated mesh's positions (drawing or exporting would; it makes Subsurf's lazy
    wrapper subdivide); returns them."""
    ev = obj.evaluated_get(bpy.context.evaluated_depsgraph_get())
    positions = ev.data.attributes["position"].data
    out = bytearray(12 * len(positions))
    positions.foreach_get("vector", memoryview(out).cast("f"))
    return bytes(out)


def _timings(
    pair: list[bpy.types.Object], everything: list[bpy.types.Object], repeat: int
) -> tuple[float, float]:
    """(edit ms, frame ms) of the pair (edited, animated), each alone visible; checks that
    every timed step changed the evaluated surface."""
    edited, animated = pair
    scene = bpy.context.scene
    step = [0]
    last = [b""]

    def changed(now: bytes) -> None:
        assert now != last[0], "the evaluated surface did not change"
        last[0] = now

    def edit() -> None:
        step[0] += 1
        point = edited.data.vertices[step[0] % len(edited.data.vertices)]
        point.co.z += 1e-2 if step[0] % 2 else -1e-2
        edited.data.update()
        bpy.context.view_layer.update()
        changed(_touch(edited))

    frame = [1]

    def next_frame() -> None:
        frame[0] = frame[0] % 99 + 1
        scene.frame_set(frame[0])
        changed(_touch(animated))

    _show_only(everything, edited)
    last[0] = _touch(edited)
    edit()  # warm-up: caches
    edit_ms = _median_ms(edit, repeat)
    _show_only(everything, animated)
    last[0] = _touch(animated)
    next_frame()
    return edit_ms, _median_ms(next_frame, repeat)


def main() -> None:
    """Run the benchmark and print the rows."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=7)
    parser.add_argument("--cages", default="8k,30k")
    parser.add_argument("--levels", default="2,3")
    args = parser.parse_args()
    levels = [int(x) for x in args.levels.split(",")]
    cages = {"8k": 2, "30k": 3}
    cages = {k: v for k, v in cages.items() if k in args.cages.split(",")}

    bpy.ops.wm.read_factory_settings(use_empty=True)
    _register_addon()
    import bidegree_blender
    from bidegree_blender import modifier

    print(f"load average before: {' '.join(f'{x:.2f}' for x in os.getloadavg())}")
    print(
        f"{'cage':>5} {'faces':>6} {'lvl':>3} {'scheme':<12} {'out faces':>9} "
        f"{'fresh ms':>9} {'edit ms':>8} {'frame ms':>8} {'edit x':>7} {'frame x':>7}"
    )
    scene = bpy.context.scene
    for label, subdivisions in cages.items():
        cage = make_cage(subdivisions)
        for level in levels:
            reference = _objects(scene, cage, "Subsurf")
            for obj in reference:
                obj.modifiers.new("Subsurf", "SUBSURF").levels = level
            rows = []
            for scheme, settings in (
                ("classic 3", {"degree": 3, "rules": "classic"}),
                ("averaging 4", {"degree": 4}),
                ("avg 4 refin", {"degree": 4, "limit": False}),
                ("avg 4 normal", {"degree": 4, "normals": True}),
            ):
                pair = _objects(scene, cage, scheme)
                for obj in pair:
                    bidegree_blender.add_modifier(obj, levels=level, **settings)
                rows.append((scheme, pair))
            everything = reference + [obj for _, pair in rows for obj in pair]
            ref_edit, ref_frame = _timings(reference, everything, args.repeat)
            ref_faces = len(  # the animated one is the one still visible
                reference[1].evaluated_get(bpy.context.evaluated_depsgraph_get()).data.polygons
            )
            print(
                f"{label:>5} {len(cage.polygons):>6} {level:>3} {'Subsurf':<12} {ref_faces:>9} "
                f"{'':>9} {ref_edit:>8.1f} {ref_frame:>8.1f} {1.0:>7.2f} {1.0:>7.2f}",
                flush=True,
            )
            for scheme, pair in rows:
                for other in everything:
                    other.hide_viewport = other is not pair[0]
                t0 = time.perf_counter()
                bpy.context.view_layer.update()
                _touch(pair[0])
                fresh = (time.perf_counter() - t0) * 1000.0
                mods = [modifier.bidegree_modifiers(obj)[0] for obj in pair]
                edit, frame = _timings(pair, everything, args.repeat)
                for obj, mod in zip(pair, mods, strict=True):
                    state = modifier.status(obj, mod)
                    assert state.error == "" and state.action == "reused", state
                faces = modifier.status(pair[0], mods[0]).result_faces
                print(
                    f"{label:>5} {len(cage.polygons):>6} {level:>3} {scheme:<12} {faces:>9} "
                    f"{fresh:>9.1f} {edit:>8.1f} {frame:>8.1f} {edit / ref_edit:>7.2f} "
                    f"{frame / ref_frame:>7.2f}",
                    flush=True,
                )
            for obj in everything:
                bpy.data.objects.remove(obj)
            modifier.cleanup()
    print(f"load average after: {' '.join(f'{x:.2f}' for x in os.getloadavg())}")


if __name__ == "__main__":
    main()
