"""bidegree: higher-degree subdivision surfaces for Blender (extension entry point).

The extension is a thin GUI layer; the work is done by the ``bidegree`` wheel
(Rust core) and its ``bidegree_blender`` package.  Scripts can drive it
without the GUI::

    mod = sys.modules[bpy.context.preferences.addons["bl_ext.user_default.bidegree"].module]
    obj.bidegree.enabled = True      # creates the live result
    mod.update(obj)                  # explicit update (headless bpy has no timers)
"""

from __future__ import annotations

from . import live, operators, panel, properties

#: Explicit update entry point (see :func:`live.update`).
update = live.update
#: The plan cache (its ``stats`` count plan builds / reuses / skips).
CACHE = live.CACHE

_modules = (properties, operators, panel, live)


def register() -> None:
    """Register properties, operators, the panel and the live-update handlers."""
    for mod in _modules:
        mod.register()


def unregister() -> None:
    """Undo :func:`register`."""
    for mod in reversed(_modules):
        mod.unregister()
