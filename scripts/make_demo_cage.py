"""Writes the demo cage, Blender's Suzanne (triangles, quads, poles of valence 3 to 6 and open
boundaries), as a .blend file, made with the bpy module."""

import sys

import bpy


def main(path: str) -> None:
    """Saves a scene holding only Suzanne to ``path``."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.ops.mesh.primitive_monkey_add(size=2.0)
    bpy.context.active_object.name = "Suzanne"
    bpy.ops.wm.save_as_mainfile(filepath=path)
    print(f"cage: {path}")


if __name__ == "__main__":
    main(sys.argv[1])
