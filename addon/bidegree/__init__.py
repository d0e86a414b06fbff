"""bidegree: higher-degree subdivision surfaces for Blender (extension entry point).

The extension is a thin GUI layer: ``handlers`` wires Blender's application handlers to
:mod:`bidegree_blender.modifier`, ``operators`` and ``panel`` are the buttons. The work is done by
the ``bidegree`` wheel (Rust core) and its ``bidegree_blender`` package, which scripts use
directly::

    import bidegree_blender
    mod = bidegree_blender.add_modifier(obj, degree=3, levels=2)   # a real entry of obj.modifiers
    bpy.context.view_layer.update()                                # the surface is evaluated
"""

from __future__ import annotations

from . import handlers, operators, panel

_modules = (operators, panel, handlers)


def register() -> None:
    """Register the operators, the panel and the application handlers."""
    for mod in _modules:
        mod.register()


def unregister() -> None:
    """Undo :func:`register`."""
    for mod in reversed(_modules):
        mod.unregister()
