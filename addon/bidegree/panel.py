"""The bidegree panel (Properties editor, Modifiers tab)."""

from __future__ import annotations

import bpy


class BIDEGREE_PT_surface(bpy.types.Panel):
    """Settings, status and actions of the object's bidegree surface."""

    bl_idname = "BIDEGREE_PT_surface"
    bl_label = "bidegree Surface"
    bl_space_type = "PROPERTIES"
    bl_region_type = "WINDOW"
    bl_context = "modifier"

    @classmethod
    def poll(cls, context: bpy.types.Context) -> bool:
        obj = getattr(context, "object", None)
        return obj is not None and obj.type == "MESH" and "bidegree_result_of" not in obj

    def draw_header(self, context: bpy.types.Context) -> None:
        self.layout.prop(context.object.bidegree, "enabled", text="")

    def draw(self, context: bpy.types.Context) -> None:
        layout = self.layout
        layout.use_property_split = True
        props = context.object.bidegree

        col = layout.column()
        col.active = props.enabled
        col.prop(props, "degree")
        col.prop(props, "rules")
        sub = col.column(align=True)
        sub.prop(props, "levels", text="Levels Viewport")
        sub.prop(props, "render_levels", text="Render")
        col.prop(props, "output")
        col.prop(props, "boundary")
        col.prop(props, "use_creases")
        col.prop(props, "uv_mode")
        sub = col.column(heading="Limit Surface", align=True)
        sub.prop(props, "use_limit", text="Positions")
        sub.prop(props, "use_limit_normals", text="Normals")
        col.prop(props, "adaptive")
        sub = col.column()
        sub.active = props.adaptive
        sub.prop(props, "tolerance")

        box = layout.box()
        status = box.column(align=True)
        status.label(
            text=f"Cage: {props.cage_faces:,} faces   Result: {props.result_faces:,} faces"
        )
        if props.last_action:
            status.label(text=f"Last update: {props.last_update_ms:.1f} ms ({props.last_action})")
        if props.last_warning:
            status.label(text=props.last_warning, icon="INFO")
        if props.last_error:
            for i, chunk in enumerate(_wrap(props.last_error, 60)):
                status.label(text=chunk, icon="ERROR" if i == 0 else "BLANK1")

        row = layout.row(align=True)
        row.operator("object.bidegree_apply", icon="CHECKMARK")
        row.operator("object.bidegree_export_usd", icon="EXPORT")
        row.operator("object.bidegree_remove", icon="X")


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
