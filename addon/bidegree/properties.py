"""Object properties of the bidegree extension (``Object.bidegree``)."""

from __future__ import annotations

from typing import Any

import bpy
from bpy.props import (
    BoolProperty,
    EnumProperty,
    FloatProperty,
    IntProperty,
    PointerProperty,
    StringProperty,
)

from . import live


def _settings_changed(self: Any, context: bpy.types.Context) -> None:
    """Any subdivision setting changed: refresh the live result of the owning object."""
    obj = self.id_data
    if isinstance(obj, bpy.types.Object):
        live.request_update(obj)


def _enabled_changed(self: Any, context: bpy.types.Context) -> None:
    """Turning bidegree on creates the live result; turning it off removes it."""
    obj = self.id_data
    if not isinstance(obj, bpy.types.Object):
        return
    if self.enabled:
        live.update(obj)
    else:
        live.remove(obj)


class BidegreeObjectSettings(bpy.types.PropertyGroup):
    """Per-object bidegree settings and status."""

    enabled: BoolProperty(  # type: ignore[valid-type]
        name="Enabled",
        description="Show this object's bidegree surface (the object itself is drawn as its cage)",
        default=False,
        update=_enabled_changed,
    )
    degree: IntProperty(  # type: ignore[valid-type]
        name="Degree",
        description="Degree of the limit surface (bi-degree d B-splines on regular regions)",
        default=4,
        min=1,
        max=31,
        update=_settings_changed,
    )
    levels: IntProperty(  # type: ignore[valid-type]
        name="Viewport Levels",
        description="Subdivision levels in the viewport",
        default=2,
        min=0,
        soft_max=6,
        max=16,
        update=_settings_changed,
    )
    render_levels: IntProperty(  # type: ignore[valid-type]
        name="Render Levels",
        description="Subdivision levels for rendering",
        default=3,
        min=0,
        soft_max=6,
        max=16,
    )
    output: EnumProperty(  # type: ignore[valid-type]
        name="Output",
        description="Which mesh of the refinement is shown",
        items=[
            ("primal", "Primal", "The drawing mesh of the subdivision surface"),
            ("dual", "Dual", "The true dual mesh of the last level"),
        ],
        default="primal",
        update=_settings_changed,
    )
    boundary: EnumProperty(  # type: ignore[valid-type]
        name="Boundary",
        description="Boundary interpolation rule",
        items=[
            (
                "edge-only",
                "Edge Only",
                "Boundary edges are sharp, boundary corners smooth",
            ),
            (
                "edge-and-corner",
                "Edge and Corner",
                "Boundary edges and corners are sharp",
            ),
        ],
        default="edge-only",
        update=_settings_changed,
    )
    rules: EnumProperty(  # type: ignore[valid-type]
        name="Rules",
        description="Rule set of the scheme",
        items=[
            ("averaging", "Averaging", "Repeated averaging: any degree (Zorin-Schroeder)"),
            (
                "classic",
                "Classic",
                "Degree 3: Catmull-Clark exactly as OpenSubdiv (Blender's Subdivision Surface); "
                "degree 2: the original Doo-Sabin",
            ),
        ],
        default="averaging",
        update=_settings_changed,
    )
    use_limit: BoolProperty(  # type: ignore[valid-type]
        name="Limit Positions",
        description="Place the result's vertices on the limit surface",
        default=False,
        update=_settings_changed,
    )
    use_limit_normals: BoolProperty(  # type: ignore[valid-type]
        name="Limit Normals",
        description="Shade with the limit surface's normals (custom normals, split at creases)",
        default=False,
        update=_settings_changed,
    )
    use_creases: BoolProperty(  # type: ignore[valid-type]
        name="Use Creases",
        description="Use edge and vertex creases (sharpness 10 * crease^2, as OpenSubdiv)",
        default=True,
        update=_settings_changed,
    )
    uv_mode: EnumProperty(  # type: ignore[valid-type]
        name="UV Smooth",
        description="How UV maps are interpolated",
        items=[
            (
                "linear",
                "Linear",
                "UVs are interpolated linearly (bidegree's face-varying data)",
            ),
            # "smooth" (UVs subdivided like positions) is a planned option; the core lacks it.
        ],
        default="linear",
    )
    adaptive: BoolProperty(  # type: ignore[valid-type]
        name="Adaptive",
        description="Viewport: refine only where the surface is not flat (up to the viewport "
        "levels), drawn as crack-free triangles; renders stay uniform",
        default=False,
        update=_settings_changed,
    )
    tolerance: FloatProperty(  # type: ignore[valid-type]
        name="Tolerance",
        description="Adaptive flatness tolerance, relative to the cage's bounding-box diagonal "
        "(0 refines everywhere)",
        default=1e-3,
        min=0.0,
        soft_max=0.05,
        precision=4,
        step=0.01,
        update=_settings_changed,
    )
    result: PointerProperty(  # type: ignore[valid-type]
        name="Result",
        description="Object holding the live bidegree surface",
        type=bpy.types.Object,
    )

    # Status (read-only in the UI).
    cage_faces: IntProperty(name="Cage Faces", default=0)  # type: ignore[valid-type]
    result_faces: IntProperty(name="Result Faces", default=0)  # type: ignore[valid-type]
    last_update_ms: FloatProperty(name="Last Update (ms)", default=0.0)  # type: ignore[valid-type]
    last_action: StringProperty(name="Last Action", default="")  # type: ignore[valid-type]
    last_error: StringProperty(name="Last Error", default="")  # type: ignore[valid-type]
    last_warning: StringProperty(name="Last Warning", default="")  # type: ignore[valid-type]


classes = (BidegreeObjectSettings,)


def register() -> None:
    """Register the property group and attach it to ``bpy.types.Object``."""
    for cls in classes:
        bpy.utils.register_class(cls)
    bpy.types.Object.bidegree = PointerProperty(type=BidegreeObjectSettings)


def unregister() -> None:
    """Detach and unregister the property group."""
    del bpy.types.Object.bidegree
    for cls in reversed(classes):
        bpy.utils.unregister_class(cls)
