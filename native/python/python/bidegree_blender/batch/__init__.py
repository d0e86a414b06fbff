"""Batch subdivision of ``.blend`` / ``.obj`` files with the ``bpy`` module, here or on a farm.

Usage::

    python -m bidegree_blender.batch IN... --out DIR [--degree 4] [--levels 2] [--usd | --usda]
        [--workers N | --scheduler tcp://HOST:PORT] [--resume] [--trust-scripts]

For every input file a ``.blend`` contributes every mesh object (modifiers applied), an ``.obj``
is imported with Blender's OBJ importer. Each result is written to
``DIR/<stem>.bidegree.blend`` (one object per source object, same transform and materials) and,
with ``--usd``, to ``DIR/<stem>[_<object>].usdc`` (``--usda`` for text).

Modules: :mod:`.cli` (arguments, the local loop, progress, summary), :mod:`.convert` (one file:
load with scripts off, subdivide, write atomically), :mod:`.manifest` (what was done, for
``--resume``), :mod:`.farm` (``dask.distributed``). The Open Job Description template that runs
this entry on a render farm is ``packaging/openjd/bidegree-batch.yaml``.
"""

from __future__ import annotations

from .cli import main, run_local
from .convert import FileRecord, Job, convert_file

__all__ = ["FileRecord", "Job", "convert_file", "main", "run_local"]
