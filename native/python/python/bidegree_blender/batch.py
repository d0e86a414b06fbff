"""Batch subdivision of ``.blend`` / ``.obj`` files with the ``bpy`` module.

Usage::

    python -m bidegree_blender.batch IN... --degree 4 --levels 2 --out DIR [--usd] [--output dual]

For every input file: a ``.blend`` contributes every mesh object (modifiers
applied), an ``.obj`` is imported with Blender's OBJ importer.  Each result is
written to ``DIR/<stem>.bidegree.blend`` (one object per source object, same
transform and materials) and, with ``--usd``, to ``DIR/<stem>[_<object>].usdc``
(``--usda`` for text).  One progress line per file; the exit code is 1 when any
file failed (the other files are still processed), 2 on bad arguments.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from collections.abc import Sequence
from dataclasses import dataclass, field

import bidegree

from . import evaluated_cage, object_materials
from .export import bidegree_usd, export_cage_usd
from .live import Settings, build_plan, check_geometry, evaluate_surface, write_full
from .objects import is_result_object


@dataclass
class FileReport:
    """What happened to one input file."""

    path: str
    ok: bool
    objects: int = 0
    faces: int = 0
    seconds: float = 0.0
    outputs: list[str] = field(default_factory=list)
    error: str = ""


def _safe(name: str) -> str:
    return "".join(c if c.isalnum() or c in "-_." else "_" for c in name)


def load_file(path: str) -> None:
    """Replace the current ``bpy`` session data with ``path`` (``.blend`` or ``.obj``)."""
    import bpy

    ext = os.path.splitext(path)[1].lower()
    if not os.path.isfile(path):
        raise bidegree.BidegreeIOError(f"{path}: no such file")
    if ext == ".blend":
        bpy.ops.wm.open_mainfile(filepath=path, load_ui=False)
    elif ext == ".obj":
        bpy.ops.wm.read_factory_settings(use_empty=True)
        bpy.ops.wm.obj_import(filepath=path)
    else:
        raise bidegree.InvalidInputError(f"{path}: unsupported file type {ext!r} (.blend or .obj)")


def process_file(path: str, out_dir: str, settings: Settings, *, usd: str | None) -> FileReport:
    """Subdivide every mesh object of ``path`` and write the results into ``out_dir``.

    Raises ``bidegree.BidegreeError`` (or ``RuntimeError`` from Blender) on failure;
    nothing is written for a file that fails.
    """
    import bpy

    t0 = time.perf_counter()
    load_file(path)
    stem = _safe(os.path.splitext(os.path.basename(path))[0])
    sources = [ob for ob in bpy.data.objects if ob.type == "MESH" and not is_result_object(ob)]
    if not sources:
        raise bidegree.EmptyMeshError(f"{path}: no mesh objects")
    depsgraph = bpy.context.evaluated_depsgraph_get()

    # Compute everything first so that a failing object writes nothing for this file.
    results = []
    faces = 0
    for ob in sources:
        try:
            cage = evaluated_cage(ob, depsgraph=depsgraph, use_creases=settings.use_creases)
            check_geometry(cage)
            plan, _ = build_plan(cage, settings)
            mesh = bpy.data.meshes.new(f"{ob.name}.bidegree")
            points, normals = evaluate_surface(plan, cage.points, settings)
            write_full(mesh, plan, points, cage, object_materials(ob), normals)
        except bidegree.BidegreeError as exc:
            raise type(exc)(f"object {ob.name!r}: {exc}") from exc
        faces += len(mesh.polygons)
        results.append((ob, cage, mesh))

    scene = bpy.data.scenes.new("bidegree_results")
    for ob, _cage, mesh in results:
        res = bpy.data.objects.new(mesh.name, mesh)
        res.matrix_world = ob.matrix_world
        scene.collection.objects.link(res)
    outputs = []
    blend_path = os.path.join(out_dir, f"{stem}.bidegree.blend")
    bpy.data.libraries.write(blend_path, {scene}, compress=False)
    outputs.append(blend_path)

    if usd is not None:
        if bidegree_usd() is not None:
            for ob, cage, _mesh in results:
                name = stem if len(results) == 1 else f"{stem}_{_safe(ob.name)}"
                usd_path = os.path.join(out_dir, f"{name}.{usd}")
                export_cage_usd(cage, usd_path, settings)
                outputs.append(usd_path)
        else:
            usd_path = os.path.join(out_dir, f"{stem}.{usd}")
            current = bpy.context.scene
            for ob in current.objects:
                ob.select_set(False)
            temp = []
            for ob, _cage, mesh in results:
                res = bpy.data.objects.new(mesh.name + ".usd", mesh)
                res.matrix_world = ob.matrix_world
                current.collection.objects.link(res)
                res.select_set(True)
                temp.append(res)
            try:
                bpy.ops.wm.usd_export(filepath=usd_path, selected_objects_only=True)
            finally:
                for res in temp:
                    bpy.data.objects.remove(res)
            outputs.append(usd_path)

    return FileReport(
        path=path,
        ok=True,
        objects=len(results),
        faces=faces,
        seconds=time.perf_counter() - t0,
        outputs=outputs,
    )


def run(
    inputs: Sequence[str], out_dir: str, settings: Settings, *, usd: str | None = None
) -> list[FileReport]:
    """Process every input (continuing after failures); prints one line per file."""
    os.makedirs(out_dir, exist_ok=True)
    reports = []
    n = len(inputs)
    for i, path in enumerate(inputs, 1):
        t0 = time.perf_counter()
        try:
            report = process_file(path, out_dir, settings, usd=usd)
            outs = ", ".join(os.path.basename(p) for p in report.outputs)
            print(
                f"[{i}/{n}] {path}: ok, {report.objects} object(s), {report.faces} faces, "
                f"{report.seconds:.2f} s -> {outs}",
                flush=True,
            )
        except (bidegree.BidegreeError, RuntimeError, OSError) as exc:
            report = FileReport(
                path=path,
                ok=False,
                seconds=time.perf_counter() - t0,
                error=f"{type(exc).__name__}: {exc}",
            )
            print(f"[{i}/{n}] {path}: FAILED: {report.error}", flush=True)
        reports.append(report)
    return reports


def main(argv: Sequence[str] | None = None) -> int:
    """Command-line entry point; returns the process exit code."""
    parser = argparse.ArgumentParser(
        prog="python -m bidegree_blender.batch",
        description="Subdivide the mesh objects of .blend / .obj files with bidegree (bpy).",
    )
    parser.add_argument("inputs", nargs="+", metavar="IN", help=".blend or .obj files")
    parser.add_argument("--degree", type=int, default=4)
    parser.add_argument("--levels", type=int, default=2)
    parser.add_argument("--output", choices=("primal", "dual"), default="primal")
    parser.add_argument("--boundary", choices=("edge-only", "edge-and-corner"), default="edge-only")
    parser.add_argument("--no-creases", action="store_true", help="ignore edge/vertex creases")
    parser.add_argument(
        "--rules", choices=("averaging", "classic"), default="averaging", help="rule set"
    )
    parser.add_argument("--limit", action="store_true", help="vertices on the limit surface")
    parser.add_argument("--normals", action="store_true", help="limit normals (custom normals)")
    parser.add_argument("--out", required=True, help="output directory")
    parser.add_argument("--usd", action="store_true", help="also write USD (.usdc)")
    parser.add_argument("--usda", action="store_true", help="also write USD as text (.usda)")
    args = parser.parse_args(argv)

    settings = Settings(
        degree=args.degree,
        levels=args.levels,
        output=args.output,
        boundary=args.boundary,
        use_creases=not args.no_creases,
        rules=args.rules,
        limit=args.limit,
        normals=args.normals,
    )
    usd = "usda" if args.usda else ("usdc" if args.usd else None)
    reports = run(args.inputs, args.out, settings, usd=usd)
    failed = [r for r in reports if not r.ok]
    print(
        f"bidegree batch: {len(reports) - len(failed)} done, {len(failed)} failed",
        flush=True,
    )
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
