"""bidegree as an entry of ``obj.modifiers``: the node group, the surface holders, the updates.

Mechanism (bpy data logic, no GUI; the add-on's handlers call :func:`begin_read` before an
evaluation, :func:`end_read` after it, and :func:`cleanup`):

* A bidegree modifier is a Geometry Nodes modifier whose node group (:func:`ensure_node_group`,
  owned by the add-on, one per file) outputs the surface that bidegree computed into a *holder*
  object, brought in by an Object Info node. Holders are in no scene collection; each modifier
  has a viewport holder and a render holder (its own Object inputs, so a Shift+D or Alt+D
  duplicate gets holders of its own on its first update), and an *Is Viewport* switch picks one.
  Everything Blender does with modifiers then works natively: stack order, the header toggles,
  modifiers after it, Apply, exporters, Object Info and Boolean targets, collections, undo.
* The settings are the modifier's own inputs. The node group checks that a holder was computed
  for them (and for the cage's face count): the holder's location carries that stamp. A holder
  that is empty, refused or stale is not shown; the cage passes through instead (and, from
  Blender 4.4 on, a warning says why in the modifier panel).
* The cage is the mesh *at the modifier's place in the stack*, read from Blender's own
  evaluation: before an evaluation (``depsgraph_update_pre``, ``frame_change_pre``) the
  modifier and everything after it are switched off (``show_viewport``; for a render
  ``show_render``), so the evaluation gives the cage with every modifier above, their toggles
  and animation; after it (``depsgraph_update_post``, ``frame_change_post``) the cages are
  read, the modifiers switched back on and the surfaces written, and the depsgraph's second
  evaluation pass (which Blender runs when a handler changed data) shows them. A nested
  ``depsgraph.update()`` inside a handler would avoid the first switch-off but crashes Blender
  when the outer update changed the scene or its collections, so it is not used.
"""

from __future__ import annotations

import threading
from collections.abc import Hashable, Iterable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import bidegree
from bidegree.options import Options

from . import attributes, mesh_io, pipeline
from .cache import LiveCache, UpdateReport

if TYPE_CHECKING:  # pragma: no cover - typing only
    import bpy

#: Name of the add-on's node group; its custom property says which layout it has.
NODE_GROUP = "bidegree"
NODE_GROUP_TAG = "bidegree_node_group"
NODE_GROUP_VERSION = 3  # 2: the UV Smooth menu; 3: Limit Positions on by default
#: Custom properties of a holder object: its variant, owner object and owner modifier.
HOLDER_TAG = "bidegree_holder"
OWNER_TAG = "bidegree_owner"
MODIFIER_TAG = "bidegree_modifier"
VIEWPORT, RENDER = "viewport", "render"

#: The input of the face-varying mode (a menu of Blender's UV Smooth names).
UV_SMOOTH_INPUT = "UV Smooth"
#: The modifier's settings, as (input name, type, default, min, max, description).
SETTINGS: tuple[tuple[str, str, Any, Any, Any, str], ...] = (
    ("Degree", "INT", 4, 1, 31, "Degree of the surface (3 ~ Catmull-Clark, 4 biquartic)"),
    ("Levels Viewport", "INT", 2, 0, 16, "Subdivision levels in the viewport"),
    ("Render Levels", "INT", 3, 0, 16, "Subdivision levels in renders"),
    (
        "Classic Rules",
        "BOOLEAN",
        False,
        None,
        None,
        "Degree 3: Catmull-Clark exactly as OpenSubdiv (Blender's Subdivision Surface); "
        "degree 2: the original Doo-Sabin",
    ),
    ("Dual Output", "BOOLEAN", False, None, None, "Show the true dual mesh of the last level"),
    (
        "Sharp Boundary Corners",
        "BOOLEAN",
        False,
        None,
        None,
        "Boundary vertices of a single face are corners (edge-and-corner boundary rule)",
    ),
    (
        "Use Creases",
        "BOOLEAN",
        True,
        None,
        None,
        "Use edge and vertex creases (sharpness 10 * crease^2, as OpenSubdiv)",
    ),
    (
        "Limit Positions",
        "BOOLEAN",
        True,
        None,
        None,
        "Vertices on the limit surface, as Subdivision Surface's Use Limit Surface (from level 1, "
        "primal output, uniform levels; classic rules: degree 3; elsewhere left out)",
    ),
    (
        "Limit Normals",
        "BOOLEAN",
        False,
        None,
        None,
        "Shade with the limit surface's normals (custom normals, split at creases)",
    ),
    (
        "Adaptive",
        "BOOLEAN",
        False,
        None,
        None,
        "Viewport: refine only where the surface is not flat, drawn as crack-free triangles; "
        "renders stay uniform",
    ),
    (
        "Tolerance",
        "FLOAT",
        1e-3,
        0.0,
        1.0,
        "Adaptive flatness tolerance, relative to the cage's bounding-box diagonal",
    ),
    (
        UV_SMOOTH_INPUT,
        "MENU",
        attributes.UV_SMOOTH_DEFAULT,
        None,
        None,
        "How UV maps and corner attributes are smoothed (Blender's UV Smooth; Keep "
        "Boundaries: smooth inside, UV boundaries kept sharp)",
    ),
)
#: The UV Smooth names in their stamp order (the default first: node groups from before the
#: setting, which have no such input, stamp 0 for it).
_UV_STAMP = (
    attributes.UV_SMOOTH_DEFAULT,
    *(name for name in attributes.UV_SMOOTH if name != attributes.UV_SMOOTH_DEFAULT),
)
#: Hidden inputs set by the add-on: the holders and the last error.
SURFACE, RENDER_SURFACE, ERROR = "Surface", "Render Surface", "Error"

_SOCKET_TYPES = {
    "MENU": "NodeSocketMenu",
    "INT": "NodeSocketInt",
    "BOOLEAN": "NodeSocketBool",
    "FLOAT": "NodeSocketFloat",
}


# ---------------------------------------------------------------------------------------------
# Runtime state: the plan cache and what each modifier's last update did


#: One plan cache for the session, keyed by :func:`cache_key`.
CACHE = LiveCache()
#: Held while bidegree itself evaluates or writes (its own depsgraph updates are not edits).
_busy = threading.Lock()


@dataclass
class Status:
    """What the last update of one modifier did (shown by the add-on's panel)."""

    error: str = ""
    warning: str = ""
    cage_faces: int = 0
    result_faces: int = 0
    milliseconds: float = 0.0
    action: str = ""
    render_error: str = ""


STATUS: dict[Hashable, Status] = {}


def modifier_key(obj: bpy.types.Object, mod: bpy.types.Modifier) -> Hashable:
    """A key of ``mod`` on ``obj`` that is stable for the session (survives renames)."""
    return (obj.session_uid, mod.persistent_uid)


def cache_key(obj: bpy.types.Object, mod: bpy.types.Modifier, variant: str) -> Hashable:
    """Cache key of the ``variant`` surface of ``mod`` on ``obj``."""
    return (*modifier_key(obj, mod), variant)  # type: ignore[misc]


def status(obj: bpy.types.Object, mod: bpy.types.Modifier) -> Status:
    """The :class:`Status` of ``mod`` (a fresh one before its first update)."""
    return STATUS.setdefault(modifier_key(obj, mod), Status())


def reset() -> None:
    """Forget every cached plan and status (a new file, an undo, unregistering)."""
    CACHE.clear()
    STATUS.clear()
    _IDENTIFIERS.clear()
    _expected.clear()
    _stale.clear()


# ---------------------------------------------------------------------------------------------
# The node group


def _new_node(tree: Any, kind: str, location: tuple[float, float], **props: Any) -> Any:
    node = tree.nodes.new(kind)
    node.location = location
    for name, value in props.items():
        setattr(node, name, value)
    return node


def _build_node_group(tree: Any) -> None:
    """The nodes: holder surfaces that match the settings, else the cage passes through."""
    import bpy

    iface = tree.interface
    iface.new_socket("Geometry", in_out="INPUT", socket_type="NodeSocketGeometry")
    iface.new_socket("Geometry", in_out="OUTPUT", socket_type="NodeSocketGeometry")
    for name, kind, default, low, high, description in SETTINGS:
        socket = iface.new_socket(name, in_out="INPUT", socket_type=_SOCKET_TYPES[kind])
        if kind != "MENU":  # a menu's items come from its Menu Switch (below)
            socket.default_value = default
        socket.description = description
        if low is not None:
            socket.min_value, socket.max_value = low, high
    for name, kind in ((SURFACE, "Object"), (RENDER_SURFACE, "Object"), (ERROR, "String")):
        socket = iface.new_socket(name, in_out="INPUT", socket_type=f"NodeSocket{kind}")
        socket.hide_in_modifier = True
        socket.description = "Set by the bidegree add-on"

    link = tree.links.new
    group_in = _new_node(tree, "NodeGroupInput", (-1400, 0))
    group_out = _new_node(tree, "NodeGroupOutput", (900, 0))
    cage = group_in.outputs["Geometry"]
    cage_faces = _new_node(tree, "GeometryNodeAttributeDomainSize", (-1150, 300))
    link(cage, cage_faces.inputs[0])

    def value(op: str, a: Any, b: Any, location: tuple[float, float]) -> Any:
        node = _new_node(tree, "ShaderNodeMath", location, operation=op)
        for i, x in enumerate((a, b)):
            if isinstance(x, (int, float)):
                node.inputs[i].default_value = x
            else:
                link(x, node.inputs[i])
        return node.outputs[0]

    def logic(op: str, a: Any, b: Any, location: tuple[float, float]) -> Any:
        node = _new_node(tree, "FunctionNodeBooleanMath", location, operation=op)
        link(a, node.inputs[0])
        if b is not None:
            link(b, node.inputs[1])
        return node.outputs[0]

    def equal(a: Any, b: Any, epsilon: float, location: tuple[float, float]) -> Any:
        node = _new_node(
            tree, "FunctionNodeCompare", location, data_type="FLOAT", operation="EQUAL"
        )
        node.inputs["Epsilon"].default_value = epsilon
        link(a, node.inputs["A"])
        link(b, node.inputs["B"])
        return node.outputs[0]

    # The settings stamp (see :func:`stamp`): exact in float32.
    acc: Any = None
    for bit, name in enumerate(_STAMP_FLAGS):
        flag = value("MULTIPLY", group_in.outputs[name], float(1024 << bit), (-1150, -60 * bit))
        acc = flag if acc is None else value("ADD", acc, flag, (-950, -60 * bit))
    # UV Smooth: a Menu Switch gives the menu its items (Blender's names) and the stamp its code.
    uv_menu = _new_node(tree, "GeometryNodeMenuSwitch", (-1150, -600), data_type="INT")
    uv_menu.enum_items.clear()
    for name in attributes.UV_SMOOTH:
        uv_menu.enum_items.new(name)
        uv_menu.inputs[name].default_value = _UV_STAMP.index(name)
    link(group_in.outputs[UV_SMOOTH_INPUT], uv_menu.inputs["Menu"])
    iface.items_tree[UV_SMOOTH_INPUT].default_value = attributes.UV_SMOOTH_DEFAULT
    uv = value("MULTIPLY", uv_menu.outputs[0], float(1024 << 7), (-950, -600))
    acc = value("ADD", acc, uv, (-800, -400))
    common = value("ADD", acc, group_in.outputs["Degree"], (-650, -100))
    adaptive = value("MULTIPLY", group_in.outputs["Adaptive"], float(1024 << 6), (-1150, -400))
    warning_node = "GeometryNodeWarning" if hasattr(bpy.types, "GeometryNodeWarning") else None
    error_shown: Any = None
    if warning_node is not None:
        length = _new_node(tree, "FunctionNodeStringLength", (-950, 500))
        link(group_in.outputs[ERROR], length.inputs[0])
        has_error = value("GREATER_THAN", length.outputs[0], 0.5, (-750, 500))
        warn = _new_node(tree, warning_node, (-550, 500), warning_type="ERROR")
        link(has_error, warn.inputs["Show"])
        link(group_in.outputs[ERROR], warn.inputs["Message"])
        error_shown = warn.outputs[0]

    def surface(holder_input: str, levels_input: str, with_adaptive: bool, y: float) -> Any:
        """(valid, geometry) of one holder."""
        info = _new_node(tree, "GeometryNodeObjectInfo", (-500, y), transform_space="ORIGINAL")
        link(group_in.outputs[holder_input], info.inputs["Object"])
        size = _new_node(tree, "GeometryNodeAttributeDomainSize", (-300, y + 150))
        link(info.outputs["Geometry"], size.inputs[0])
        has_faces = value("GREATER_THAN", size.outputs["Face Count"], 0.5, (-100, y + 150))
        levels = value("MULTIPLY", group_in.outputs[levels_input], 32.0, (-500, y - 200))
        wanted = value("ADD", common, levels, (-300, y - 200))
        if with_adaptive:
            wanted = value("ADD", wanted, adaptive, (-150, y - 200))
        location = _new_node(tree, "ShaderNodeSeparateXYZ", (-300, y - 350))
        link(info.outputs["Location"], location.inputs[0])
        match = logic(
            "AND",
            equal(location.outputs["X"], wanted, 0.5, (-100, y - 200)),
            equal(location.outputs["Z"], cage_faces.outputs["Face Count"], 0.5, (-100, y - 300)),
            (100, y - 200),
        )
        if with_adaptive:
            tolerance = equal(
                location.outputs["Y"], group_in.outputs["Tolerance"], 0.0, (-100, y - 400)
            )
            match = logic("AND", match, tolerance, (250, y - 250))
        valid = logic("AND", has_faces, match, (300, y))
        if warning_node is not None:
            stale = logic(
                "AND", has_faces, logic("NOT", match, None, (300, y - 150)), (450, y - 150)
            )
            warn = _new_node(tree, warning_node, (600, y - 150), warning_type="WARNING")
            warn.inputs["Message"].default_value = (
                "bidegree: the surface does not match the settings or the cage (is the bidegree "
                "add-on installed and enabled?); the cage is shown"
            )
            link(stale, warn.inputs["Show"])
            valid = logic(
                "AND", valid, logic("NOT", warn.outputs[0], None, (750, y - 150)), (750, y)
            )
            valid = logic(
                "AND", valid, logic("NOT", error_shown, None, (750, y + 100)), (800, y + 50)
            )
        return valid, info.outputs["Geometry"]

    valid_v, geo_v = surface(SURFACE, "Levels Viewport", True, 200)
    valid_r, geo_r = surface(RENDER_SURFACE, "Render Levels", False, -700)
    viewport = _new_node(tree, "GeometryNodeSwitch", (500, 100), input_type="GEOMETRY")
    link(valid_v, viewport.inputs["Switch"])
    link(cage, viewport.inputs["False"])
    link(geo_v, viewport.inputs["True"])
    render = _new_node(tree, "GeometryNodeSwitch", (600, -300), input_type="GEOMETRY")
    link(valid_r, render.inputs["Switch"])
    link(viewport.outputs[0], render.inputs["False"])
    link(geo_r, render.inputs["True"])
    is_viewport = _new_node(tree, "GeometryNodeIsViewport", (600, -500))
    pick = _new_node(tree, "GeometryNodeSwitch", (750, 0), input_type="GEOMETRY")
    link(is_viewport.outputs[0], pick.inputs["Switch"])
    link(render.outputs[0], pick.inputs["False"])
    link(viewport.outputs[0], pick.inputs["True"])
    link(pick.outputs[0], group_out.inputs[0])


def ensure_node_group() -> bpy.types.GeometryNodeTree:
    """The add-on's node group of this file (built on first use)."""
    import bpy

    for tree in bpy.data.node_groups:
        if tree.get(NODE_GROUP_TAG) == NODE_GROUP_VERSION and tree.library is None:
            return tree
    tree = bpy.data.node_groups.new(NODE_GROUP, "GeometryNodeTree")
    tree[NODE_GROUP_TAG] = NODE_GROUP_VERSION
    tree.is_modifier = True
    tree.description = "bidegree subdivision surface (computed by the bidegree add-on)"
    _build_node_group(tree)
    return tree


def is_bidegree_modifier(mod: Any) -> bool:
    """Whether ``mod`` is a bidegree modifier (a Geometry Nodes modifier with our node group)."""
    group = getattr(mod, "node_group", None)
    return mod.type == "NODES" and group is not None and NODE_GROUP_TAG in group


def bidegree_modifiers(obj: bpy.types.Object) -> list[bpy.types.Modifier]:
    """The bidegree modifiers of ``obj`` in stack order."""
    if obj.type != "MESH":
        return []
    return [mod for mod in obj.modifiers if is_bidegree_modifier(mod)]


#: Input name -> socket identifier, per node group (by session uid: the add-on's node groups
#: are never edited after they are built).
_IDENTIFIERS: dict[int, dict[str, str]] = {}


def _identifiers(tree: Any) -> dict[str, str]:
    found = _IDENTIFIERS.get(tree.session_uid)
    if found is None:
        found = _IDENTIFIERS[tree.session_uid] = {
            item.name: item.identifier
            for item in tree.interface.items_tree
            if item.item_type == "SOCKET" and item.in_out == "INPUT"
        }
    return found


def get_input(mod: bpy.types.Modifier, name: str) -> Any:
    """The value of the input ``name`` of the bidegree modifier ``mod``."""
    return mod[_identifiers(mod.node_group)[name]]


def set_input(mod: bpy.types.Modifier, name: str, value: Any) -> None:
    """Set the input ``name`` of ``mod`` (the caller tags the object for an update)."""
    mod[_identifiers(mod.node_group)[name]] = value


def options_of(mod: bpy.types.Modifier, *, render: bool = False, uniform: bool = False) -> Options:
    """The :class:`~bidegree.options.Options` a bidegree modifier computes its surface with
    (render: render levels, uniform; uniform: viewport levels without *Adaptive*, as an export).
    Give the *evaluated* modifier to get animated values in a render.

    *Limit Positions* (on by default, as Subdivision Surface's *Use Limit Surface*) is left out
    where the surface has none: at level 0 (the cage, as Blender shows it), for the dual output,
    adaptive output and classic rules at degrees other than 3, where ``Options`` would refuse it.
    """
    return surface_options(settings_of(mod, render=render, uniform=uniform))


def surface_options(settings: Options) -> Options:
    """``settings`` without ``limit`` where their surface has no limit positions (see
    :func:`options_of`)."""
    if settings.limit and (
        settings.levels == 0 or settings.adaptive or not settings.has_limit_positions()
    ):
        return settings.replace(limit=False)
    return settings


def settings_of(mod: bpy.types.Modifier, *, render: bool = False, uniform: bool = False) -> Options:
    """The modifier's settings as they are set (the node group's stamp is made of them), as
    :class:`~bidegree.options.Options`; :func:`options_of` gives what it computes."""
    ids = _identifiers(mod.node_group)

    def read(name: str) -> Any:
        return mod[ids[name]]

    return Options(
        degree=int(read("Degree")),
        levels=int(read("Render Levels" if render else "Levels Viewport")),
        output="dual" if read("Dual Output") else "primal",
        boundary="edge-and-corner" if read("Sharp Boundary Corners") else "edge-only",
        rules="classic" if read("Classic Rules") else "averaging",
        use_creases=bool(read("Use Creases")),
        limit=bool(read("Limit Positions")),
        normals=bool(read("Limit Normals")),
        # Adaptive subdivision is a viewport option: renders stay uniform.
        adaptive=bool(read("Adaptive")) and not (render or uniform),
        tolerance=float(read("Tolerance")),
        uv_mode=attributes.UV_SMOOTH[uv_smooth(mod)],
    )


def uv_smooth(mod: bpy.types.Modifier) -> str:
    """The modifier's *UV Smooth* name (the default on node groups from before the setting)."""
    ident = _identifiers(mod.node_group).get(UV_SMOOTH_INPUT)
    if ident is None:
        return attributes.UV_SMOOTH_DEFAULT
    value = mod[ident]
    for item in mod.id_properties_ui(ident).as_dict().get("items", ()):
        if item[-1] == value:
            return str(item[0])
    return attributes.UV_SMOOTH_DEFAULT


def set_uv_smooth(mod: bpy.types.Modifier, name: str) -> None:
    """Set the modifier's *UV Smooth* by Blender's name (the caller tags the object)."""
    ident = _identifiers(mod.node_group)[UV_SMOOTH_INPUT]
    for item in mod.id_properties_ui(ident).as_dict().get("items", ()):
        if item[0] == name:
            mod[ident] = item[-1]
            return
    raise bidegree.InvalidInputError(
        f"UV Smooth must be one of {', '.join(attributes.UV_SMOOTH)}, got {name!r}"
    )


#: The boolean settings in the stamp, bit 0 first (bit 6 is Adaptive, viewport only).
_STAMP_FLAGS = (
    "Classic Rules",
    "Dual Output",
    "Sharp Boundary Corners",
    "Use Creases",
    "Limit Positions",
    "Limit Normals",
)


def stamp(options: Options) -> float:
    """The settings as one number, exact in float32 (``degree + 32 levels + 1024 flags``); the
    node group computes the same one from its inputs to check that a holder was computed for
    them (see :func:`_build_node_group`)."""
    flags = (
        (options.rules == "classic")
        | (options.output == "dual") << 1
        | (options.boundary == "edge-and-corner") << 2
        | options.use_creases << 3
        | options.limit << 4
        | options.normals << 5
        | options.adaptive << 6
    )
    uv = _UV_STAMP.index(_uv_name(options.uv_mode))
    return float(options.degree + 32 * options.levels + 1024 * (flags + (uv << 7)))


def _uv_name(uv_mode: str) -> str:
    """Blender's *UV Smooth* name of a face-varying mode."""
    return next(name for name, mode in attributes.UV_SMOOTH.items() if mode == uv_mode)


_SETTING_FIELDS = {
    "degree": "Degree",
    "levels": "Levels Viewport",
    "render_levels": "Render Levels",
    "rules": "Classic Rules",
    "output": "Dual Output",
    "boundary": "Sharp Boundary Corners",
    "use_creases": "Use Creases",
    "limit": "Limit Positions",
    "normals": "Limit Normals",
    "adaptive": "Adaptive",
    "tolerance": "Tolerance",
    "uv_mode": UV_SMOOTH_INPUT,
}


def configure(mod: bpy.types.Modifier, **settings: Any) -> None:
    """Set settings of ``mod`` by their :class:`~bidegree.options.Options` names (``degree=3,
    rules="classic", render_levels=2``, ...); values are checked like ``Options``'.

    Raises:
        bidegree.InvalidInputError: an unknown setting or a bad value.
    """
    unknown = sorted(set(settings) - set(_SETTING_FIELDS))
    if unknown:
        raise bidegree.InvalidInputError(
            f"unknown bidegree setting(s) {', '.join(unknown)}; known: {', '.join(_SETTING_FIELDS)}"
        )
    checked = Options(**{k: v for k, v in settings.items() if k != "render_levels"})
    if "render_levels" in settings:
        Options(levels=settings["render_levels"])
    for name, value in settings.items():
        if name == "render_levels":
            set_input(mod, "Render Levels", int(value))
            continue
        if name == "uv_mode":
            set_uv_smooth(mod, _uv_name(checked.uv_mode))
            continue
        value = getattr(checked, name)
        if name == "rules":
            value = value == "classic"
        elif name == "output":
            value = value == "dual"
        elif name == "boundary":
            value = value == "edge-and-corner"
        set_input(mod, _SETTING_FIELDS[name], value)
    mod.id_data.update_tag()


# ---------------------------------------------------------------------------------------------
# Holders


def is_holder(obj: bpy.types.Object) -> bool:
    """Whether ``obj`` is a bidegree surface holder."""
    return HOLDER_TAG in obj.keys()


def _owns(holder: Any, obj: bpy.types.Object, mod: bpy.types.Modifier, variant: str) -> bool:
    return (
        holder is not None
        and holder.get(HOLDER_TAG) == variant
        and holder.get(OWNER_TAG) == obj.name_full
        and holder.get(MODIFIER_TAG) == mod.persistent_uid
    )


def holders(obj: bpy.types.Object, mod: bpy.types.Modifier) -> dict[str, bpy.types.Object]:
    """The viewport and render holders of ``mod`` on ``obj``, made or adopted as needed.

    A holder that only this modifier uses is adopted (the object was renamed); one that other
    modifiers use too (``obj`` is a Shift+D or Alt+D duplicate) is left to its owner, and
    ``mod`` gets holders of its own.
    """
    import bpy

    found: dict[str, bpy.types.Object] = {}
    relink = False
    for variant, name in ((VIEWPORT, SURFACE), (RENDER, RENDER_SURFACE)):
        holder = get_input(mod, name)
        if not _owns(holder, obj, mod, variant):
            if holder is not None and holder.get(HOLDER_TAG) == variant and holder.users == 1:
                holder[OWNER_TAG] = obj.name_full
                holder[MODIFIER_TAG] = mod.persistent_uid
            else:
                suffix = "" if variant == VIEWPORT else ".render"
                label = f"{obj.name}.bidegree{suffix}"
                holder = bpy.data.objects.new(label, bpy.data.meshes.new(label))
                holder[HOLDER_TAG] = variant
                holder[OWNER_TAG] = obj.name_full
                holder[MODIFIER_TAG] = mod.persistent_uid
                invalidate(holder)
                set_input(mod, name, holder)
                relink = True
        found[variant] = holder
    if relink:
        # Python-set inputs do not tell the depsgraph about the new objects: re-setting the
        # node group rebuilds the relations.
        mod.node_group = mod.node_group
        for variant in (VIEWPORT, RENDER):
            CACHE.discard(cache_key(obj, mod, variant))
    return found


def invalidate(holder: bpy.types.Object) -> None:
    """Empty ``holder`` so that the node group shows the cage (no stale surface)."""
    mesh = holder.data
    if len(mesh.vertices) or len(mesh.polygons):
        mesh.clear_geometry()
        mesh.update()
    if tuple(holder.location) != (-1.0, 0.0, -1.0):
        holder.location = (-1.0, 0.0, -1.0)


def _mark(holder: bpy.types.Object, settings: Options, cage_faces: int) -> None:
    """Stamp ``holder`` as computed for the modifier's ``settings`` and a cage of
    ``cage_faces`` faces."""
    wanted = (stamp(settings), float(settings.tolerance), float(cage_faces))
    if tuple(holder.location) != wanted:
        holder.location = wanted


def remove_holder(holder: bpy.types.Object) -> None:
    """Delete ``holder`` and its mesh."""
    import bpy

    mesh = holder.data
    bpy.data.objects.remove(holder)
    if mesh is not None and mesh.users == 0:
        bpy.data.meshes.remove(mesh)


def cleanup() -> int:
    """Delete holders nothing uses any more (their modifier or object was removed); returns
    how many. Forgets the plans of modifiers that are gone."""
    import bpy

    gone = [ob for ob in bpy.data.objects if is_holder(ob) and ob.users == 0]
    for holder in gone:
        remove_holder(holder)
    if len(CACHE) or STATUS:
        alive = {
            modifier_key(ob, mod)
            for ob in bpy.data.objects
            if ob.users and ob.type == "MESH"
            for mod in bidegree_modifiers(ob)
        }
        CACHE.retain(lambda key: key[:2] in alive)  # type: ignore[index]
        for key in [key for key in STATUS if key not in alive]:
            del STATUS[key]
    return len(gone)


def add_modifier(
    obj: bpy.types.Object, name: str = "bidegree", **settings: Any
) -> bpy.types.NodesModifier:
    """Add a bidegree modifier at the end of ``obj``'s stack (as Subsurf is added) with
    ``settings`` (see :func:`configure`); its surface appears on the next depsgraph update.

    Raises:
        bidegree.InvalidInputError: ``obj`` is not a mesh object, or a bad setting.
    """
    if obj is None or getattr(obj, "type", None) != "MESH":
        raise bidegree.InvalidInputError(
            f"bidegree needs a mesh object, not {getattr(obj, 'type', type(obj).__name__)}"
        )
    group = ensure_node_group()
    mod = obj.modifiers.new(name, "NODES")
    try:
        mod.node_group = group
        if settings:
            configure(mod, **settings)
        holders(obj, mod)
    except BaseException:
        obj.modifiers.remove(mod)
        raise
    obj.update_tag()
    return mod


# ---------------------------------------------------------------------------------------------
# Reading the cage at the modifier's place


@dataclass
class _Target:
    """One bidegree modifier to update, with what its update reads."""

    obj: bpy.types.Object
    mod: bpy.types.Modifier
    #: The modifier's settings (its stamp) and what its surface is computed with.
    settings: Options | None = None
    options: Options | None = None
    cage: mesh_io.CageArrays | None = None
    error: BaseException | None = None


def _toggle_off(targets: Iterable[_Target], flag: str) -> list[tuple[Any, str]]:
    """Switch each target modifier and everything after it off (``flag``); returns what to
    switch back on."""
    switched = []
    for target in targets:
        mods = list(target.obj.modifiers)
        for mod in mods[mods.index(target.mod) :]:
            if getattr(mod, flag):
                setattr(mod, flag, False)
                switched.append((mod, flag))
    return switched


def _restore(switched: list[tuple[Any, str]]) -> None:
    owners = set()
    for mod, flag in switched:
        setattr(mod, flag, True)
        owners.add(mod.id_data)
    for owner in owners:
        owner.update_tag()  # the next evaluation pass sees the restored stack


def _read_cages(targets: Iterable[_Target], depsgraph: bpy.types.Depsgraph) -> None:
    for target in targets:
        try:
            target.cage = pipeline.evaluated_cage(target.obj, depsgraph=depsgraph)
        except bidegree.BidegreeError as exc:
            target.error = exc


def read_cage(
    obj: bpy.types.Object,
    mod: bpy.types.Modifier,
    depsgraph: bpy.types.Depsgraph | None = None,
) -> mesh_io.CageArrays:
    """The mesh at ``mod``'s place in ``obj``'s stack as the viewport evaluates it (for an
    export or a script; the updates read it the same way inside their own evaluation).

    Raises:
        bidegree.BidegreeError: the mesh there is empty or not a cage bidegree can read.
    """
    import bpy

    if depsgraph is None:
        depsgraph = bpy.context.evaluated_depsgraph_get()
    target = _Target(obj, mod)
    with _busy:
        switched = _toggle_off([target], "show_viewport")
        try:
            depsgraph.update()
            _read_cages([target], depsgraph)
        finally:
            _restore(switched)
            depsgraph.update()
    if target.error is not None:
        raise target.error
    assert target.cage is not None
    return target.cage


# ---------------------------------------------------------------------------------------------
# Updates


def busy() -> bool:
    """Whether bidegree is inside an update (handlers then ignore the depsgraph's callbacks)."""
    return _busy.locked()


def _enabled(obj: bpy.types.Object, mod: bpy.types.Modifier, render: bool) -> bool:
    if render:
        return bool(mod.show_render)
    if not mod.show_viewport:
        return False
    return obj.mode != "EDIT" or bool(mod.show_in_editmode)


def _set_error(obj: bpy.types.Object, mod: bpy.types.Modifier, text: str) -> None:
    state = status(obj, mod)
    state.error = text
    if get_input(mod, ERROR) != text:
        set_input(mod, ERROR, text)
        obj.update_tag()


def _write(target: _Target, variant: str, holder: bpy.types.Object) -> UpdateReport | None:
    """Bring ``holder`` up to date with the target's cage; on a refusal empty it and record the
    error (the node group then shows the cage)."""
    obj, mod = target.obj, target.mod
    state = status(obj, mod)
    key = cache_key(obj, mod, variant)
    try:
        if target.error is not None:
            raise target.error
        assert target.cage is not None and target.options is not None
        assert target.settings is not None
        report = CACHE.update(
            key,
            target.cage,
            target.options,
            holder.data,
            materials=pipeline.object_materials(obj),
            holder=holder,
        )
    except bidegree.BidegreeError as exc:
        CACHE.discard(key)
        invalidate(holder)
        text = f"{type(exc).__name__}: {exc}"
        if variant == RENDER:
            state.render_error = text
        else:
            _set_error(obj, mod, text)
        return None
    _mark(holder, target.settings, target.cage.num_faces)
    if variant == RENDER:
        state.render_error = ""
        return report
    _set_error(obj, mod, "")
    if report.action != "unchanged":
        state.warning = "; ".join(report.warnings)[:1000]
        state.cage_faces = report.cage_faces
        state.result_faces = report.result_faces
        state.milliseconds = round(report.seconds * 1000.0, 3)
        state.action = report.action
        # The render surface was made from an older cage: never render it.
        invalidate(holders(obj, mod)[RENDER])
    return report


def _targets(objects: Iterable[bpy.types.Object], render: bool) -> list[_Target]:
    """The bidegree modifier of each object that is enabled for the viewport (or renders).

    One per object: its cage is read in the same evaluation that switches it off, and a
    second bidegree modifier of the same object would need a second evaluation (it is refused
    with a message and shows its cage)."""
    targets = []
    for obj in objects:
        mods = bidegree_modifiers(obj)
        if not mods:
            continue
        for extra in mods[1:]:
            _set_error(obj, extra, "bidegree: one bidegree modifier per object is supported")
            invalidate(holders(obj, extra)[RENDER if render else VIEWPORT])
        if _enabled(obj, mods[0], render):
            targets.append(_Target(obj, mods[0]))
    return targets


#: What :func:`begin_read` switched off for the evaluation under way, until :func:`end_read`.
_reading: dict[str, Any] = {"targets": [], "switched": [], "render": False}


def begin_read(objects: Iterable[bpy.types.Object], *, render: bool = False) -> int:
    """Before an evaluation (``depsgraph_update_pre``, ``frame_change_pre``): switch each
    object's bidegree modifier and everything after it off (``show_viewport``, for a render
    ``show_render``), so that the evaluation gives the cages; returns how many."""
    end_read(None)
    if busy():
        return 0
    targets = _targets(objects, render)
    for target in targets:
        holders(target.obj, target.mod)
    _reading["targets"] = targets
    _reading["render"] = render
    _reading["switched"] = _toggle_off(targets, "show_render" if render else "show_viewport")
    return len(targets)


def end_read(depsgraph: bpy.types.Depsgraph | None) -> list[tuple[Any, Any, UpdateReport | None]]:
    """After that evaluation (``depsgraph_update_post``, ``frame_change_post``): read the
    cages ``depsgraph`` evaluated, switch the modifiers back on and write the surfaces, which
    the evaluation's second pass then shows. Without a depsgraph only switches back on.

    Returns, per modifier read, its update report (``None`` after a refusal: see its status).
    """
    targets: list[_Target] = _reading["targets"]
    switched = _reading["switched"]
    render = _reading["render"]
    _reading["targets"], _reading["switched"] = [], []
    done: list[tuple[Any, Any, UpdateReport | None]] = []
    if not targets and not switched:
        return done
    with _busy:
        if depsgraph is not None and (depsgraph.mode == "RENDER") == render:
            flag = "show_render" if render else "show_viewport"
            read = []
            for target in targets:
                evaluated = target.obj.evaluated_get(depsgraph)
                mod = evaluated.modifiers.get(target.mod.name) if evaluated.is_evaluated else None
                if mod is None or getattr(mod, flag):
                    continue  # not evaluated by this depsgraph (hidden, other view layer)
                try:
                    target.settings = settings_of(mod, render=render)
                    target.options = surface_options(target.settings)
                except bidegree.BidegreeError as exc:
                    target.error = exc
                read.append(target)
            _read_cages(read, depsgraph)
        else:
            read = []
        _restore(switched)
        variant = RENDER if render else VIEWPORT
        for target in read:
            holder = holders(target.obj, target.mod)[variant]
            done.append((target.obj, target.mod, _write(target, variant, holder)))
    return done


def reading() -> list[_Target]:
    """The modifiers switched off for the evaluation under way."""
    return list(_reading["targets"])


def estimated_faces(targets: Iterable[_Target] | None = None) -> int:
    """About how many faces the surfaces of ``targets`` (default: the evaluation under way)
    will have: the object's own faces times ``4**levels`` (the add-on announces long work from
    it before the work blocks)."""
    faces = 0
    for target in reading() if targets is None else targets:
        try:
            levels = settings_of(target.mod, render=_reading["render"]).levels
        except bidegree.BidegreeError:  # a bad setting is reported by the update itself
            continue
        faces += len(target.obj.data.polygons) * 4 ** min(levels, 16)
    return faces


def render_writes_allowed(scene: bpy.types.Scene) -> bool:
    """Whether a render may let bidegree write its render surfaces: always on the main thread
    (background renders, scripts); from a render job's thread only with *Lock Interface* on
    (Blender's rule for handlers that change data during a render)."""
    return threading.current_thread() is threading.main_thread() or bool(
        scene.render.use_lock_interface
    )


def viewport_objects(scene: bpy.types.Scene) -> list[bpy.types.Object]:
    """Visible objects of ``scene`` with bidegree modifiers (those the viewport evaluates)."""
    found = []
    for ob in scene.objects:
        if ob.type == "MESH" and bidegree_modifiers(ob):
            try:
                visible = ob.visible_get()
            except RuntimeError:  # not in the current view layer
                visible = False
            if visible:
                found.append(ob)
    return found


#: Objects whose cage is expected to change in the next evaluation (the last read found it
#: changed) and objects that changed without being read (they need another evaluation). In the
#: GUI only these are switched off in ``_pre``: an update that touches no bidegree object (a
#: selection, another object moved) then costs bidegree nothing.
_expected: set[str] = set()
_stale: set[str] = set()


def stale_objects() -> list[bpy.types.Object]:
    """Objects that changed without their cages being read (see :func:`note_changes`)."""
    import bpy

    return [ob for ob in map(bpy.data.objects.get, sorted(_stale)) if ob is not None]


def expected_objects(scene: bpy.types.Scene) -> list[bpy.types.Object]:
    """The visible objects of ``scene`` whose cages the next evaluation should read (see
    :func:`note_changes`)."""
    wanted = _expected | _stale
    return [ob for ob in viewport_objects(scene) if ob.name_full in wanted]


def note_changes(
    depsgraph: bpy.types.Depsgraph, done: list[tuple[Any, Any, UpdateReport | None]]
) -> list[bpy.types.Object]:
    """After :func:`end_read`: keep expecting the objects whose cage changed, stop expecting
    those whose cage did not, and return the bidegree objects this evaluation changed without
    reading their cages (stale until another evaluation reads them: the caller asks for one)."""
    read = {obj.name_full for obj, _mod, _report in done}
    for obj, _mod, report in done:
        if report is None or report.action != "unchanged":
            _expected.add(obj.name_full)
        else:
            _expected.discard(obj.name_full)
    _stale.difference_update(read)
    missed = [ob for ob in changed_objects(depsgraph) if ob.name_full not in read]
    for ob in missed:
        _stale.add(ob.name_full)
    return missed


def changed_objects(depsgraph: bpy.types.Depsgraph) -> list[bpy.types.Object]:
    """Original objects with bidegree modifiers whose geometry this evaluation changed (their
    own update, or their mesh's)."""
    import bpy

    found: dict[str, bpy.types.Object] = {}
    meshes = set()
    for upd in depsgraph.updates:
        orig = getattr(upd.id, "original", upd.id)
        if isinstance(orig, bpy.types.Object):
            if upd.is_updated_geometry and not is_holder(orig) and bidegree_modifiers(orig):
                found[orig.name_full] = orig
        elif isinstance(orig, bpy.types.Mesh):
            meshes.add(orig)
    if meshes:
        for ob in depsgraph.view_layer.objects:
            if ob.data in meshes and not is_holder(ob) and bidegree_modifiers(ob):
                found[ob.name_full] = ob
    return list(found.values())


def render_objects(scene: bpy.types.Scene) -> list[bpy.types.Object]:
    """Objects of ``scene`` with bidegree modifiers that renders evaluate."""
    return [ob for ob in scene.objects if not ob.hide_render and bidegree_modifiers(ob)]
