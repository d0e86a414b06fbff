"""The import path ``bidegree_blender.objects`` of the batch before issue 12 (kept while the
batch is rebuilt): bidegree's own helper objects are :func:`.modifier.is_holder`."""

from __future__ import annotations

from .modifier import is_holder as is_result_object

__all__ = ["is_result_object"]
