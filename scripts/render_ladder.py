"""Renders docs/ladder.png: one cage (Blender's Suzanne) and its bidegree surfaces of degree 2,
3, 4 and 9, drawn with matplotlib (flat shading, back faces culled, painter's order).

    .venv/bin/python scripts/render_ladder.py [OUT.png]
"""

from __future__ import annotations

import sys

import bpy
import matplotlib
import numpy as np

matplotlib.use("Agg")
import bidegree
import matplotlib.pyplot as plt
from matplotlib.collections import PolyCollection

LIGHT = np.array([0.4, -0.6, 0.7]) / np.linalg.norm([0.4, -0.6, 0.7])


def suzanne() -> bidegree.Mesh:
    """Blender's Suzanne as a bidegree cage (read with the attribute API)."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.ops.mesh.primitive_monkey_add(size=2.0)
    mesh = bpy.context.active_object.data
    points = np.empty(3 * len(mesh.vertices), np.float32)
    mesh.attributes["position"].data.foreach_get("vector", points)
    sizes = np.empty(len(mesh.polygons), np.int32)
    mesh.polygons.foreach_get("loop_total", sizes)
    corners = np.empty(len(mesh.loops), np.int32)
    mesh.attributes[".corner_vert"].data.foreach_get("value", corners)
    return bidegree.Mesh(points.reshape(-1, 3), face_sizes=sizes, face_indices=corners)


def draw(
    ax: plt.Axes, points: np.ndarray, sizes: np.ndarray, indices: np.ndarray, title: str
) -> None:
    """Flat-shaded orthographic view from the front (-y), back faces culled."""
    offsets = np.concatenate([[0], np.cumsum(sizes)])
    polys = [points[indices[offsets[f] : offsets[f + 1]]] for f in range(len(sizes))]
    normals = np.array([np.cross(p[1] - p[0], p[-1] - p[0]) for p in polys])
    normals /= np.linalg.norm(normals, axis=1, keepdims=True) + 1e-30
    front = normals[:, 1] < 0
    depth = np.array([p[:, 1].mean() for p in polys])
    order = [f for f in np.argsort(-depth) if front[f]]
    shade = np.clip(normals @ LIGHT, 0.0, 1.0) * 0.75 + 0.2
    colors = [(0.85 * shade[f], 0.62 * shade[f], 0.38 * shade[f]) for f in order]
    ax.add_collection(
        PolyCollection(
            [polys[f][:, [0, 2]] for f in order],
            facecolors=colors,
            edgecolors=colors,
            linewidths=0.3,
        )
    )
    ax.set_xlim(-1.5, 1.5)
    ax.set_ylim(-1.1, 1.2)
    ax.set_aspect("equal")
    ax.axis("off")
    ax.set_title(title, fontsize=11)


def main(out: str) -> None:
    """Renders the ladder to ``out``."""
    cage = suzanne()
    fig, axes = plt.subplots(1, 5, figsize=(16, 3.2), dpi=110)
    draw(
        axes[0],
        cage.points,
        cage.face_sizes,
        cage.face_indices,
        f"cage ({len(cage.face_sizes)} faces)",
    )
    for ax, degree in zip(axes[1:], [2, 3, 4, 9], strict=True):
        result = bidegree.subdivide(cage, degree=degree, levels=3)
        name = {
            2: "Doo-Sabin variant",
            3: "Catmull-Clark variant",
            4: "biquartic",
            9: "bidegree 9",
        }
        draw(
            ax,
            result.points,
            result.face_sizes,
            result.face_indices,
            f"degree {degree}: {name[degree]}",
        )
    fig.tight_layout()
    fig.savefig(out)
    print(f"wrote {out}")


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else "docs/ladder.png")
