"""Checks the reference of ``tests/test_dirty_reference.py`` against OpenSubdiv itself.

A research tool, not a test (it needs Debian's ``libosd-dev`` and g++, which CI does not have):
every cage of ``tests/cages_dirty.py`` goes through Blender's Subdivision Surface modifier
(``bidegree.compare.opensubdiv_surface``) and through OpenSubdiv's own ``Far`` API
(``osd_reference.cpp``, built on first use), and the two are compared:

- positions (levels 1 to 3) as point sets of the faces drawn, with OpenSubdiv's hole tags and
  ``VTX_BOUNDARY_NONE`` for the cages that have them, once with the cage as it is and once with
  Blender's additions (``opensubdiv_reference.blender_semantics``);
- UVs per face corner in all six face-varying modes, OpenSubdiv given the face-varying topology
  ``opensubdiv_reference.blender_uv_values`` computes (Blender's welding).

Run: ``.venv/bin/python docs/research/check_opensubdiv.py`` (about a minute). The table it
printed is in ``docs/research/non-manifold.md`` and ``face-varying.md``.
"""

from __future__ import annotations

import subprocess
import sys
import warnings
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "tests"))

import bpy  # noqa: E402,F401  (Blender, for the reference)
import cages_dirty  # noqa: E402
import opensubdiv_reference as ref  # noqa: E402
from bidegree import compare  # noqa: E402

DRIVER = Path("/tmp/bidegree_osd_reference")
BOUNDARY = {"none": 0, "edge-only": 1, "edge-and-corner": 2}
FVAR = {"none": 0, "corners-only": 1, "corners-plus1": 2, "corners-plus2": 3, "boundaries": 4}
FVAR["all"] = 5


def driver() -> Path:
    source = Path(__file__).with_name("osd_reference.cpp")
    if not DRIVER.exists() or DRIVER.stat().st_mtime < source.stat().st_mtime:
        subprocess.run(
            ["g++", "-std=c++17", "-O2", "-o", str(DRIVER), str(source), "-losdCPU"], check=True
        )
    return DRIVER


def opensubdiv(
    cage: cages_dirty.DirtyCage, levels: int, mode: str = "all"
) -> tuple[compare.SurfaceMesh, np.ndarray | None]:
    """OpenSubdiv's uniform refinement: the faces that are not holes, and the UVs per corner."""
    lines = [f"boundary {BOUNDARY[cage.boundary]}", f"fvar {FVAR[mode]}", f"levels {levels}"]
    lines += ["v {:.9g} {:.9g} {:.9g}".format(*p) for p in cage.points]
    lines += [f"f {len(f)} " + " ".join(map(str, f)) for f in cage.faces]
    lines += [f"crease {a} {b} {s}" for a, b, s in cage.sharp_edges]
    lines += [f"corner {v} {s}" for v, s in cage.sharp_vertices]
    lines += [f"hole {h}" for h in cage.holes]
    if cage.uvs is not None:
        values = ref.blender_uv_values(cage)
        table = np.zeros((values.max() + 1, 2))
        table[values] = cage.uvs
        lines += ["uv {:.9g} {:.9g}".format(*u) for u in table]
        at = 0
        for f in cage.faces:
            lines.append("fv " + " ".join(map(str, values[at : at + len(f)])))
            at += len(f)
    out = subprocess.run(
        [str(driver())], input="\n".join(lines), capture_output=True, text=True, check=True
    ).stdout
    points, faces, holes, uvs, face_uvs = [], [], [], [], []
    for line in out.splitlines():
        key, *rest = line.split()
        if key == "v":
            points.append([float(x) for x in rest])
        elif key == "f":
            holes.append(rest[0] == "1")
            faces.append([int(x) for x in rest[1:]])
        elif key == "uv":
            uvs.append([float(x) for x in rest])
        elif key == "fv":
            face_uvs.append([int(x) for x in rest])
    keep = ~np.array(holes)
    faces_kept = np.array(faces)[keep]
    # Uniform refinement numbers the child faces of each parent face consecutively.
    per_face = [4**levels if len(f) == 4 else len(f) * 4 ** (levels - 1) for f in cage.faces]
    origin = np.repeat(np.arange(len(cage.faces)), per_face)[keep]
    mesh = compare.SurfaceMesh(
        np.array(points),
        np.full(len(faces_kept), 4, dtype=np.int32),
        faces_kept.ravel(),
        face_origin=origin,
    )
    corner_uvs = np.array(uvs)[np.array(face_uvs)[keep].ravel()] if uvs else None
    return mesh, corner_uvs


def drawn(mesh: compare.SurfaceMesh) -> np.ndarray:
    return mesh.points[np.unique(mesh.face_indices)]


def diagonal(cage: cages_dirty.DirtyCage) -> float:
    return float(np.linalg.norm(np.ptp(cage.points[np.unique(cage.face_indices)], axis=0)))


def main() -> None:
    print("positions: Blender against OpenSubdiv (as is / with Blender's additions), levels 1-3")
    for name, cage in cages_dirty.issue_13_cages().items():
        row = []
        for variant in (cage, ref.blender_semantics(cage)):
            gaps = []
            for levels in (1, 2, 3):
                blender = compare.opensubdiv_surface(cage, levels)
                osd, _ = opensubdiv(variant, levels)
                gaps.append(ref.point_gap(drawn(blender), drawn(osd), diagonal(cage)))
            row.append(max(gaps))
        print(f"  {name:30s} {row[0]:9.1e} {row[1]:9.1e}")
    print("UVs: Blender against OpenSubdiv with Blender's welding, max over levels 1-3")
    for name, cage in cages_dirty.issue_14_cages().items():
        gaps = {}
        for mode in FVAR:
            worst = 0.0
            for levels in (1, 2, 3):
                blender = compare.opensubdiv_surface(cage, levels, uv_mode=mode)
                osd, uvs = opensubdiv(cage, levels, mode)
                corners = ref.corner_map(blender, osd, tolerance=1e-5 * diagonal(cage))
                worst = max(worst, float(np.abs(uvs[corners] - blender.uvs).max()))
            gaps[mode] = worst
        print(f"  {name:22s} " + " ".join(f"{m} {g:.1e}" for m, g in gaps.items()))


if __name__ == "__main__":
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        main()
