"""Operators of the bidegree extension: Apply, Export USD, Remove, Update."""

from __future__ import annotations

import os
from typing import Any, ClassVar

import bidegree_blender
import bpy
from bidegree_blender import export
from bpy.props import StringProperty
from bpy_extras.io_utils import ExportHelper

import bidegree

from . import live


def _mesh_object(context: bpy.types.Context) -> bpy.types.Object | None:
    obj = getattr(context, "object", None)
    return obj if obj is not None and obj.type == "MESH" else None


class BIDEGREE_OT_apply(bpy.types.Operator):
    """Bake the bidegree surface into the object's mesh (modifiers are applied too)"""

    bl_idname = "object.bidegree_apply"
    bl_label = "Apply"
    bl_options: ClassVar[set[str]] = {"REGISTER", "UNDO"}

    @classmethod
    def poll(cls, context: bpy.types.Context) -> bool:
        obj = _mesh_object(context)
        return obj is not None and obj.mode == "OBJECT"

    def execute(self, context: bpy.types.Context) -> set[str]:
        obj = _mesh_object(context)
        assert obj is not None
        props = obj.bidegree
        settings = live.settings_of(obj)
        try:
            mesh = bidegree_blender.subdivide_object(
                obj,
                degree=settings.degree,
                levels=settings.levels,
                output=settings.output,
                boundary=settings.boundary,
                use_creases=settings.use_creases,
                depsgraph=context.evaluated_depsgraph_get(),
            )
        except bidegree.BidegreeError as exc:
            props.last_error = f"{type(exc).__name__}: {exc}"
            self.report({"ERROR"}, props.last_error)
            return {"CANCELLED"}
        live.remove(obj)
        props.enabled = False
        bidegree_blender.objects.bake_into_object(obj, mesh, None)
        props.last_error = ""
        self.report({"INFO"}, f"bidegree applied: {len(mesh.polygons)} faces")
        return {"FINISHED"}


class BIDEGREE_OT_remove(bpy.types.Operator):
    """Turn bidegree off for this object and delete its live result"""

    bl_idname = "object.bidegree_remove"
    bl_label = "Remove"
    bl_options: ClassVar[set[str]] = {"REGISTER", "UNDO"}

    @classmethod
    def poll(cls, context: bpy.types.Context) -> bool:
        return _mesh_object(context) is not None

    def execute(self, context: bpy.types.Context) -> set[str]:
        obj = _mesh_object(context)
        assert obj is not None
        live.remove(obj)
        obj.bidegree.enabled = False
        obj.bidegree.last_error = ""
        return {"FINISHED"}


class BIDEGREE_OT_update(bpy.types.Operator):
    """Recompute the live bidegree surface of this object now"""

    bl_idname = "object.bidegree_update"
    bl_label = "Update"
    bl_options: ClassVar[set[str]] = {"REGISTER"}

    @classmethod
    def poll(cls, context: bpy.types.Context) -> bool:
        obj = _mesh_object(context)
        return obj is not None and obj.bidegree.enabled

    def execute(self, context: bpy.types.Context) -> set[str]:
        obj = _mesh_object(context)
        assert obj is not None
        action = live.update(obj)
        if action == "error":
            self.report({"ERROR"}, obj.bidegree.last_error)
            return {"CANCELLED"}
        return {"FINISHED"}


class BIDEGREE_OT_export_usd(bpy.types.Operator, ExportHelper):
    """Export the object's bidegree surface (and its cage) to USD"""

    bl_idname = "object.bidegree_export_usd"
    bl_label = "Export USD"
    bl_options: ClassVar[set[str]] = {"REGISTER"}

    filename_ext = ".usdc"
    filter_glob: StringProperty(default="*.usd;*.usdc;*.usda", options={"HIDDEN"})  # type: ignore[valid-type]

    @classmethod
    def poll(cls, context: bpy.types.Context) -> bool:
        return _mesh_object(context) is not None

    def execute(self, context: bpy.types.Context) -> set[str]:
        obj = _mesh_object(context)
        assert obj is not None
        settings = live.settings_of(obj)
        path = bpy.path.abspath(self.filepath)
        try:
            export.export_object_usd(
                obj, path, settings, depsgraph=context.evaluated_depsgraph_get()
            )
        except (bidegree.BidegreeError, OSError, RuntimeError) as exc:
            obj.bidegree.last_error = f"{type(exc).__name__}: {exc}"
            self.report({"ERROR"}, obj.bidegree.last_error)
            return {"CANCELLED"}
        self.report({"INFO"}, f"bidegree: wrote {os.path.basename(path)}")
        return {"FINISHED"}


classes: tuple[Any, ...] = (
    BIDEGREE_OT_apply,
    BIDEGREE_OT_remove,
    BIDEGREE_OT_update,
    BIDEGREE_OT_export_usd,
)


def register() -> None:
    """Register the operators."""
    for cls in classes:
        bpy.utils.register_class(cls)


def unregister() -> None:
    """Unregister the operators."""
    for cls in reversed(classes):
        bpy.utils.unregister_class(cls)
