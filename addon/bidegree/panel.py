"""The bidegree panel (Properties editor, Modifiers tab): status and actions of the object's
bidegree modifiers, beside the modifiers themselves (whose inputs are the settings)."""

from __future__ import annotations

import bpy
from bidegree_blender import modifier


class BIDEGREE_PT_surface(bpy.types.Panel):
    """Status, errors and actions of the object's bidegree surfaces."""

    bl_idname = "BIDEGREE_PT_surface"
    bl_label = "bidegree"
    bl_space_type = "PROPERTIES"
    bl_region_type = "WINDOW"
    bl_context = "modifier"

    @classmethod
    def poll(cls, context: bpy.types.Context) -> bool:
        obj = getattr(context, "object", None)
        return obj is not None and obj.type == "MESH" and not modifier.is_holder(obj)

    def draw(self, context: bpy.types.Context) -> None:
        layout = self.layout
        obj = context.object
        mods = modifier.bidegree_modifiers(obj)
        if not mods:
            layout.operator("object.bidegree_add", icon="MOD_SUBSURF")
            return
        for mod in mods:
            state = modifier.status(obj, mod)
            box = layout.box()
            col = box.column(align=True)
            col.label(text=mod.name, icon="MOD_SUBSURF")
            col.label(text=f"Cage: {state.cage_faces:,} faces   Result: {state.result_faces:,}")
            if state.action:
                col.label(text=f"Last update: {state.milliseconds:.1f} ms ({state.action})")
            if state.warning:
                col.label(text=state.warning, icon="INFO")
            for text, icon in ((state.error, "ERROR"), (state.render_error, "RENDER_STILL")):
                for i, chunk in enumerate(_wrap(text, 60)):
                    col.label(text=chunk, icon=icon if i == 0 else "BLANK1")
        row = layout.row(align=True)
        row.operator("object.bidegree_apply", icon="CHECKMARK")
        row.operator("object.bidegree_export_usd", icon="EXPORT")
        if not context.scene.render.use_lock_interface:
            layout.label(text="Render > Lock Interface is off: renders use viewport levels")


def _wrap(text: str, width: int) -> list[str]:
    """Split ``text`` into lines of at most ``width`` characters at spaces."""
    lines: list[str] = []
    line = ""
    for word in text.split():
        if line and len(line) + 1 + len(word) > width:
            lines.append(line)
            line = word
        else:
            line = f"{line} {word}" if line else word
    if line:
        lines.append(line)
    return lines


classes = (BIDEGREE_PT_surface,)


def register() -> None:
    """Register the panel."""
    for cls in classes:
        bpy.utils.register_class(cls)


def unregister() -> None:
    """Unregister the panel."""
    for cls in reversed(classes):
        bpy.utils.unregister_class(cls)
