"""Operators of the bidegree extension: Add, Apply, Export USD."""

from __future__ import annotations

import os
from typing import Any, ClassVar

import bidegree_blender
import bpy
from bidegree_blender import export, modifier
from bpy.props import StringProperty
from bpy_extras.io_utils import ExportHelper

import bidegree


def _mesh_object(context: bpy.types.Context) -> bpy.types.Object | None:
    obj = getattr(context, "object", None)
    return obj if obj is not None and obj.type == "MESH" else None


def _active_bidegree(obj: bpy.types.Object) -> bpy.types.Modifier | None:
    """The active modifier if it is a bidegree one, else the object's first bidegree one."""
    mods = modifier.bidegree_modifiers(obj)
    active = obj.modifiers.active
    if active is not None and active in mods:
        return active
    return mods[0] if mods else None


class BIDEGREE_OT_add(bpy.types.Operator):
    """Add a bidegree subdivision surface modifier at the end of the stack"""

    bl_idname = "object.bidegree_add"
    bl_label = "bidegree Surface"
    bl_options: ClassVar[set[str]] = {"REGISTER", "UNDO"}

    @classmethod
    def poll(cls, context: bpy.types.Context) -> bool:
        return _mesh_object(context) is not None

    def execute(self, context: bpy.types.Context) -> set[str]:
        obj = _mesh_object(context)
        assert obj is not None
        mod = bidegree_blender.add_modifier(obj)
        obj.modifiers.active = mod
        # Render surfaces are written by the render job's handlers: Blender's rule for that is
        # a locked interface (otherwise renders show the viewport surface).
        scene = context.scene
        if scene is not None and not scene.render.use_lock_interface:
            scene.render.use_lock_interface = True
            self.report({"INFO"}, "bidegree: Render > Lock Interface turned on for render levels")
        return {"FINISHED"}


class BIDEGREE_OT_apply(bpy.types.Operator):
    """Apply the bidegree modifier (Blender's own Apply: the mesh becomes what is shown)"""

    bl_idname = "object.bidegree_apply"
    bl_label = "Apply"
    bl_options: ClassVar[set[str]] = {"REGISTER", "UNDO"}

    @classmethod
    def poll(cls, context: bpy.types.Context) -> bool:
        obj = _mesh_object(context)
        return obj is not None and obj.mode == "OBJECT" and _active_bidegree(obj) is not None

    def execute(self, context: bpy.types.Context) -> set[str]:
        obj = _mesh_object(context)
        assert obj is not None
        mod = _active_bidegree(obj)
        assert mod is not None
        with context.temp_override(object=obj, active_object=obj):
            try:
                return bpy.ops.object.modifier_apply(modifier=mod.name)  # type: ignore[no-any-return]
            except RuntimeError as exc:
                self.report({"ERROR"}, str(exc).removeprefix("Error: ").strip())
                return {"CANCELLED"}


class BIDEGREE_OT_export_usd(bpy.types.Operator, ExportHelper):
    """Export the object's bidegree surface (and its cage) to USD"""

    bl_idname = "object.bidegree_export_usd"
    bl_label = "Export USD"
    bl_options: ClassVar[set[str]] = {"REGISTER"}

    filename_ext = ".usdc"
    filter_glob: StringProperty(default="*.usd;*.usdc;*.usda", options={"HIDDEN"})  # type: ignore[valid-type]

    @classmethod
    def poll(cls, context: bpy.types.Context) -> bool:
        obj = _mesh_object(context)
        return obj is not None and _active_bidegree(obj) is not None

    def execute(self, context: bpy.types.Context) -> set[str]:
        obj = _mesh_object(context)
        assert obj is not None
        mod = _active_bidegree(obj)
        assert mod is not None
        path = bpy.path.abspath(self.filepath)
        try:
            export.export_modifier_usd(obj, mod, path, depsgraph=context.evaluated_depsgraph_get())
        except (bidegree.BidegreeError, OSError, RuntimeError) as exc:
            self.report({"ERROR"}, f"{type(exc).__name__}: {exc}")
            return {"CANCELLED"}
        self.report({"INFO"}, f"bidegree: wrote {os.path.basename(path)}")
        return {"FINISHED"}


classes: tuple[Any, ...] = (BIDEGREE_OT_add, BIDEGREE_OT_apply, BIDEGREE_OT_export_usd)


def _menu_entry(self: Any, context: bpy.types.Context) -> None:
    self.layout.operator(BIDEGREE_OT_add.bl_idname, icon="MOD_SUBSURF")


def _modifier_menu() -> Any:
    """The Add Modifier menu's Generate section (Blender 4.2+), else the menu itself."""
    return getattr(bpy.types, "OBJECT_MT_modifier_add_generate", None) or getattr(
        bpy.types, "OBJECT_MT_modifier_add", None
    )


def register() -> None:
    """Register the operators and the Add Modifier menu entry."""
    for cls in classes:
        bpy.utils.register_class(cls)
    menu = _modifier_menu()
    if menu is not None:
        menu.append(_menu_entry)


def unregister() -> None:
    """Unregister the operators and the menu entry."""
    menu = _modifier_menu()
    if menu is not None:
        menu.remove(_menu_entry)
    for cls in reversed(classes):
        bpy.utils.unregister_class(cls)
