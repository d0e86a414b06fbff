"""bpy-facing logic of bidegree (used by the Blender extension, the batch tool and scripts).

Nothing in here registers classes or handlers. The layers:

* :mod:`.mesh_io` -- Blender mesh <-> numpy arrays (fast bulk access);
* :mod:`.pipeline` -- the pure pipeline: read a cage, check, plan, evaluate, write a surface;
* :mod:`.cache` -- the plan cache of live surfaces (does only the work a change needs);
* :mod:`.modifier` -- bidegree as a Geometry Nodes modifier: node group, holders, updates;
* :mod:`.export` -- USD export; :mod:`.batch` -- batch conversion of files.

The extension (``addon/bidegree``) is a thin layer of handlers and UI over them::

    import bpy, bidegree_blender
    mod = bidegree_blender.add_modifier(bpy.data.objects["Cube"], degree=4, levels=2)
    mesh = bidegree_blender.subdivide_object(bpy.data.objects["Cube"], degree=4, levels=2)
"""

from __future__ import annotations

from bidegree.options import Options

from . import mesh_io
from .cache import LiveCache
from .modifier import add_modifier, bidegree_modifiers, configure, options_of, read_cage
from .pipeline import evaluated_cage, object_materials, subdivide_object

__all__ = [
    "LiveCache",
    "Options",
    "add_modifier",
    "bidegree_modifiers",
    "configure",
    "evaluated_cage",
    "mesh_io",
    "object_materials",
    "options_of",
    "read_cage",
    "subdivide_object",
]
