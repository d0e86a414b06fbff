"""Fixtures of the batch tests: input files made with the real ``bpy``, the batch run as a user
runs it (``python -m bidegree_blender.batch`` in a child process), and readers of its outputs.

Run these tests in their own pytest process (``pytest tests/batch``, as ``scripts/test.sh``
does): they import ``bpy`` and the installed ``bidegree``, which another test process may have
imported from elsewhere. A temporary ``BLENDER_USER_RESOURCES`` (inherited by every child) keeps
Blender's user folders out of the way.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path
from typing import Any

import numpy as np
import pytest

os.environ["BLENDER_USER_RESOURCES"] = tempfile.mkdtemp(prefix="bidegree-batch-user-")

import bpy

ROOT = Path(__file__).resolve().parents[2]
BATCH = [sys.executable, "-m", "bidegree_blender.batch"]

CUBE_OBJ = (
    "v -1 -1 -1\nv 1 -1 -1\nv 1 1 -1\nv -1 1 -1\nv -1 -1 1\nv 1 -1 1\nv 1 1 1\nv -1 1 1\n"
    "f 1 4 3 2\nf 5 6 7 8\nf 1 2 6 5\nf 2 3 7 6\nf 3 4 8 7\nf 4 1 5 8\n"
)


def grid_obj(n: int = 3) -> str:
    """An open n x n quad grid with UVs (boundary and face-varying data)."""
    lines = [f"v {i} {j} {0.1 * ((i * j) % 3)}" for j in range(n + 1) for i in range(n + 1)]
    lines += [f"vt {i / n} {j / n}" for j in range(n + 1) for i in range(n + 1)]
    for j in range(n):
        for i in range(n):
            a = j * (n + 1) + i + 1
            quad = (a, a + 1, a + n + 2, a + n + 1)
            lines.append("f " + " ".join(f"{v}/{v}" for v in quad))
    return "\n".join(lines) + "\n"


def save_scene(path: Path, build: Any) -> Path:
    """A .blend holding what ``build()`` adds to an empty scene."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    build()
    bpy.ops.wm.save_as_mainfile(filepath=str(path))
    return path


def _two_objects() -> None:
    # A modifier whose result is the same in every run (Blender's Bevel modifier is not: its
    # UVs differ by an ulp from run to run).
    bpy.ops.mesh.primitive_cube_add(location=(0, 0, 0))
    bpy.context.active_object.name = "Arrayed"
    bpy.context.active_object.modifiers.new("Array", "ARRAY").count = 2
    bpy.ops.mesh.primitive_cylinder_add(vertices=6, location=(4, 0, 0))
    bpy.context.active_object.name = "Prism"


def _non_finite() -> None:
    # A .blend, not an OBJ: Blender's OBJ importer reads nan and inf as 0.
    mesh = bpy.data.meshes.new("nonfinite")
    mesh.from_pydata([(0, 0, 0), (1, 0, 0), (0, 1, 0), (1, 1, 0)], [], [(0, 1, 3, 2)])
    mesh.vertices[0].co = (float("nan"), 0.0, 0.0)
    bpy.context.scene.collection.objects.link(bpy.data.objects.new("nonfinite", mesh))


def _monkeys(count: int) -> Any:
    def build() -> None:
        for i in range(count):
            bpy.ops.mesh.primitive_monkey_add(size=2.0, location=(3 * i, 0, 0))

    return build


@pytest.fixture(scope="session")
def inputs(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """Input files: good (``cube``, ``grid``, ``scene``, ``monkey``, ``slow``) and broken."""
    folder = tmp_path_factory.mktemp("inputs")
    files = {
        "cube": folder / "cube.obj",
        "grid": folder / "grid.obj",
        "garbage": folder / "garbage.blend",
    }
    files["cube"].write_text(CUBE_OBJ)
    files["grid"].write_text(grid_obj())
    files["garbage"].write_bytes(b"BLENDER-v500 this is not a blend file\n" * 4)
    files["nonfinite"] = save_scene(folder / "nonfinite.blend", _non_finite)
    files["scene"] = save_scene(folder / "scene.blend", _two_objects)
    files["monkey"] = save_scene(folder / "monkey.blend", _monkeys(1))
    # Three Suzannes at level 3: about a second of work, most of it writing its four outputs.
    files["slow"] = save_scene(folder / "slow.blend", _monkeys(3))
    bpy.ops.wm.read_factory_settings(use_empty=True)
    return files


def run_batch(*args: Any, cwd: Path, timeout: float = 600) -> subprocess.CompletedProcess[str]:
    """``python -m bidegree_blender.batch ARGS`` in a child process."""
    return subprocess.run(
        [*BATCH, *map(str, args)],
        capture_output=True,
        text=True,
        cwd=str(cwd),
        timeout=timeout,
        check=False,
    )


def progress_lines(stdout: str) -> list[str]:
    """The batch's per-file lines (``[k/n] path: ...``)."""
    return [line for line in stdout.splitlines() if line.startswith("[")]


def read_manifest(out: Path) -> dict[str, dict[str, Any]]:
    """The manifest's entries by input file name."""
    data = json.loads((out / "bidegree-manifest.json").read_text())
    assert data["format"] == "bidegree-batch-manifest/1"
    return {Path(e["input"]).name: e for e in data["files"]}


def output_files(out: Path) -> set[str]:
    """Names of everything in ``out`` but the manifest and its lock."""
    return {p.name for p in out.iterdir()} - {"bidegree-manifest.json", ".bidegree-manifest.lock"}


def blend_meshes(path: Path) -> dict[str, tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """Points, face sizes and corner vertices of every mesh object of the .blend ``path``."""
    bpy.ops.wm.open_mainfile(filepath=str(path), load_ui=False, use_scripts=False)
    meshes = {}
    for ob in bpy.data.objects:
        me = ob.data
        points = np.empty(3 * len(me.vertices), np.float32)
        me.vertices.foreach_get("co", points)
        sizes = np.empty(len(me.polygons), np.int32)
        me.polygons.foreach_get("loop_total", sizes)
        corners = np.empty(len(me.loops), np.int32)
        me.loops.foreach_get("vertex_index", corners)
        meshes[ob.name] = (points.reshape(-1, 3), sizes, corners)
    bpy.ops.wm.read_factory_settings(use_empty=True)
    return meshes


def usd_text(path: Path) -> str:
    """The USD file ``path`` as text (its whole content, whatever the file format)."""
    from pxr import Sdf

    layer = Sdf.Layer.OpenAsAnonymous(str(path))
    assert layer is not None, path
    return str(layer.ExportToString())


def assert_same_outputs(a: Path, b: Path, names: set[str]) -> None:
    """The outputs ``names`` in folders ``a`` and ``b`` hold the same meshes and USD content."""
    for name in sorted(names):
        if name.endswith(".blend"):
            ma, mb = blend_meshes(a / name), blend_meshes(b / name)
            assert ma.keys() == mb.keys(), name
            for key in ma:
                for x, y in zip(ma[key], mb[key], strict=True):
                    np.testing.assert_array_equal(x, y, err_msg=f"{name} {key}")
        else:
            assert usd_text(a / name) == usd_text(b / name), name
