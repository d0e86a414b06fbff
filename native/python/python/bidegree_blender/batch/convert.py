"""One input file, converted in the current ``bpy`` session: load, subdivide, write.

This module is the batch's only contact with the rest of ``bidegree_blender``
(``pipeline.subdivide_object`` in :func:`_subdivide`, ``pipeline.evaluated_cage`` and
``export.export_cage_usd`` in :func:`_export_usd`, ``modifier.is_holder``); its settings are one
:class:`bidegree.options.Options`, so that a change there is one change here.

Every file starts from a reset Blender state (a ``.blend`` replaces the session with
``open_mainfile``, an ``.obj`` is imported into factory settings) and is opened with its Python
scripts off unless the job trusts them (``trust_scripts``): a registered text block or a driver
expression in an asset does not run during a conversion.

Outputs are written into a folder of their own, ``OUT/.bidegree-partial/<stem>@<host>-<pid>-<n>``,
and renamed into ``OUT`` only when all of them are complete, so a file that fails leaves nothing
and a process killed mid-file (a farm worker, SIGKILL, out of memory) leaves no partial output in
``OUT``; the next attempt at the same file removes what such a process left.
"""

from __future__ import annotations

import contextlib
import hashlib
import itertools
import os
import shutil
import socket
import time
from collections.abc import Iterator
from dataclasses import asdict, dataclass, field
from datetime import UTC, datetime
from typing import Any

import bidegree
from bidegree.options import Options

from ..export import export_cage_usd
from ..modifier import is_holder
from ..pipeline import evaluated_cage, subdivide_object

#: Input file types the batch reads.
INPUT_TYPES = (".blend", ".obj")
#: Folder inside the output folder where outputs are written before they are renamed into place.
PARTIAL_DIR = ".bidegree-partial"
#: Separates a file's stem from the writer's token in :data:`PARTIAL_DIR` (never in a stem).
_TOKEN_SEP = "@"
_COUNTER = itertools.count()


@dataclass(frozen=True)
class Job:
    """What is done to every file of a batch run (the same for all of them)."""

    out_dir: str
    settings: Options
    #: ``"usdc"``, ``"usda"`` or ``None`` (no USD output).
    usd: str | None = None
    #: Open ``.blend`` inputs with their Python scripts enabled.
    trust_scripts: bool = False

    def fingerprint(self) -> dict[str, Any]:
        """Everything that shapes the outputs, as JSON data (compared by ``--resume``)."""
        return {**asdict(self.settings), "usd": self.usd, "trust_scripts": self.trust_scripts}


@dataclass
class Output:
    """One written file, named relative to the output folder."""

    path: str
    bytes: int
    sha256: str


@dataclass
class FileRecord:
    """What happened to one input file (a manifest entry)."""

    input: str
    status: str  # "done" or "failed"
    degree: int
    levels: int
    settings: dict[str, Any]
    input_sha256: str = ""
    outputs: list[Output] = field(default_factory=list)
    objects: int = 0
    faces: int = 0
    seconds: float = 0.0
    finished: str = ""
    attempts: int = 1
    worker: str = "local"
    error: str = ""

    @property
    def ok(self) -> bool:
        """Whether the file was converted."""
        return self.status == "done"

    def to_json(self) -> dict[str, Any]:
        """The record as JSON data."""
        return asdict(self)

    @classmethod
    def from_json(cls, data: dict[str, Any]) -> FileRecord:
        """A record read back from :meth:`to_json` data."""
        data = dict(data)
        data["outputs"] = [Output(**o) for o in data.get("outputs", [])]
        return cls(**data)


def safe_name(name: str) -> str:
    """``name`` with every character but letters, digits and ``-_.`` replaced by ``_``."""
    return "".join(c if c.isalnum() or c in "-_." else "_" for c in name)


def output_stem(path: str) -> str:
    """The name every output of ``path`` starts with (its file name without the extension)."""
    return safe_name(os.path.splitext(os.path.basename(path))[0])


def file_sha256(path: str) -> str:
    """SHA-256 of a file's bytes (hex)."""
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def remove_partials(out_dir: str, stem: str) -> None:
    """Remove what earlier attempts at ``stem`` left in :data:`PARTIAL_DIR` (a killed process).

    The partial folder itself goes too once it is empty.
    """
    root = os.path.join(out_dir, PARTIAL_DIR)
    try:
        names = os.listdir(root)
    except FileNotFoundError:
        return
    for name in names:
        if name.split(_TOKEN_SEP, 1)[0] == stem:
            shutil.rmtree(os.path.join(root, name), ignore_errors=True)
    _remove_partial_root(out_dir)


def _remove_partial_root(out_dir: str) -> None:
    try:
        os.rmdir(os.path.join(out_dir, PARTIAL_DIR))
    except OSError:  # not empty (another file is being written) or already gone
        pass


def _make_partial_folder(folder: str) -> None:
    """``os.makedirs(folder)``, again when another process removed :data:`PARTIAL_DIR` meanwhile.

    Another worker's :func:`_remove_partial_root` (a file of its own finished, or started) may
    remove the empty partial root between ``makedirs``' check that it exists and its ``mkdir`` of
    ``folder``: a ``FileNotFoundError`` that is no I/O failure and must not cost the file one of
    its retries. Nothing removes the root once ``folder`` is in it.
    """
    for _ in range(100):
        try:
            os.makedirs(folder)
            return
        except FileNotFoundError:
            if not os.path.isdir(os.path.dirname(os.path.dirname(folder))):
                raise  # the output folder itself is gone: a real failure
    os.makedirs(folder)


def _now() -> str:
    return datetime.now(UTC).isoformat(timespec="seconds")


def _new_record(path: str, job: Job, **kwargs: Any) -> FileRecord:
    """A record of ``path`` under ``job``, finished now."""
    return FileRecord(
        input=path,
        degree=job.settings.degree,
        levels=job.settings.levels,
        settings=job.fingerprint(),
        finished=_now(),
        **kwargs,
    )


def failed_record(path: str, job: Job, exc: BaseException, **kwargs: Any) -> FileRecord:
    """The record of a file that failed with ``exc`` (its message is the record's error)."""
    where = ""
    if isinstance(exc, _ObjectError):
        where, exc = f"object {exc.name!r}: ", exc.error
    message = " ".join(str(exc).split())  # one line in the log, whatever the exception says
    error = f"{type(exc).__name__}: {where}{message}"
    return _new_record(path, job, status="failed", error=error, **kwargs)


def _load(path: str, trust_scripts: bool) -> None:
    """Replace the ``bpy`` session with ``path`` (scripts off unless ``trust_scripts``)."""
    import bpy

    if path.lower().endswith(".blend"):
        # ``use_scripts`` given explicitly overrides the preference (Auto Run Python Scripts).
        bpy.ops.wm.open_mainfile(filepath=path, load_ui=False, use_scripts=trust_scripts)
    else:
        bpy.ops.wm.read_factory_settings(use_empty=True)
        bpy.ops.wm.obj_import(filepath=path)


def _subdivide(ob: Any, settings: Options, depsgraph: Any) -> Any:
    """``ob``'s subdivided surface as a new mesh datablock."""
    return subdivide_object(ob, depsgraph=depsgraph, name=f"{ob.name}.bidegree", options=settings)


def _export_usd(ob: Any, path: str, settings: Options, depsgraph: Any) -> None:
    """Write ``ob``'s subdivided surface (and its cage) to the USD file ``path``."""
    cage = evaluated_cage(ob, depsgraph=depsgraph, use_creases=settings.use_creases)
    export_cage_usd(cage, path, settings)


class _ObjectError(Exception):
    """``error`` happened to the object ``name`` of the file being converted."""

    def __init__(self, name: str, error: Exception) -> None:
        super().__init__(name, error)
        self.name = name
        self.error = error


@contextlib.contextmanager
def _object(name: str) -> Iterator[None]:
    """Tag what goes wrong with the object ``name`` (``OSError`` and ``MemoryError`` stay)."""
    try:
        yield
    except (OSError, MemoryError):
        raise
    except Exception as exc:
        raise _ObjectError(name, exc) from exc


def _usd_names(stem: str, sources: list[Any], ext: str) -> list[str]:
    """USD file names: ``<stem>.<ext>`` for one object, else ``<stem>_<object>[-k].<ext>``."""
    if len(sources) == 1:
        return [f"{stem}.{ext}"]
    names: list[str] = []
    for ob in sources:
        base = f"{stem}_{safe_name(ob.name)}"
        name, k = base, 1
        while f"{name}.{ext}" in names:  # two object names that differ only in unsafe characters
            k += 1
            name = f"{base}-{k}"
        names.append(f"{name}.{ext}")
    return names


def _write_outputs(path: str, job: Job, stem: str, folder: str) -> tuple[list[str], int, int]:
    """Load ``path``, subdivide its mesh objects and write the outputs into ``folder``.

    Returns the output file names, the number of objects and of result faces.
    """
    import bpy

    _load(path, job.trust_scripts)
    sources = [ob for ob in bpy.data.objects if ob.type == "MESH" and not is_holder(ob)]
    if not sources:
        raise bidegree.EmptyMeshError("no mesh objects")
    depsgraph = bpy.context.evaluated_depsgraph_get()
    scene = bpy.data.scenes.new("bidegree_results")
    faces = 0
    for ob in sources:
        with _object(ob.name):
            mesh = _subdivide(ob, job.settings, depsgraph)
        faces += len(mesh.polygons)
        result = bpy.data.objects.new(mesh.name, mesh)
        result.matrix_world = ob.matrix_world
        scene.collection.objects.link(result)
    names = [f"{stem}.bidegree.blend"]
    bpy.data.libraries.write(os.path.join(folder, names[0]), {scene}, compress=False)
    if job.usd is not None:
        for ob, name in zip(sources, _usd_names(stem, sources, job.usd), strict=True):
            with _object(ob.name):
                _export_usd(ob, os.path.join(folder, name), job.settings, depsgraph)
            names.append(name)
    return names, len(sources), faces


def _publish(folder: str, names: list[str], out_dir: str) -> list[Output]:
    """Rename the complete outputs from ``folder`` into ``out_dir`` (all of them, or none)."""
    outputs = []
    for name in names:
        src = os.path.join(folder, name)
        outputs.append(Output(name, os.path.getsize(src), file_sha256(src)))
    done: list[str] = []
    try:
        for name in names:
            os.replace(os.path.join(folder, name), os.path.join(out_dir, name))
            done.append(name)
    except BaseException:
        for name in done:
            try:
                os.unlink(os.path.join(out_dir, name))
            except OSError:
                pass
        raise
    return outputs


def convert_file(path: str, job: Job) -> FileRecord:
    """Convert one input file; returns its record (``status`` ``"done"`` or ``"failed"``).

    Anything wrong with the file itself (unreadable, broken ``.blend``, bad mesh, Blender or
    bidegree refusing it) gives a ``"failed"`` record and leaves no output. ``OSError`` while
    writing and ``MemoryError`` are raised instead (another attempt, on another machine, may
    succeed); they leave no output either.
    """
    import bpy  # noqa: F401  (its first import, a few seconds, is not the file's time)

    t0 = time.perf_counter()
    path = os.path.abspath(path)
    stem = output_stem(path)
    remove_partials(job.out_dir, stem)
    token = f"{socket.gethostname()}-{os.getpid()}-{next(_COUNTER)}"
    folder = os.path.join(job.out_dir, PARTIAL_DIR, f"{stem}{_TOKEN_SEP}{token}")
    try:
        try:
            input_sha256 = file_sha256(path)
        except OSError as exc:
            return failed_record(path, job, exc)
        _make_partial_folder(folder)
        try:
            names, objects, faces = _write_outputs(path, job, stem, folder)
        except (OSError, MemoryError):
            raise
        except Exception as exc:
            return failed_record(
                path, job, exc, input_sha256=input_sha256, seconds=time.perf_counter() - t0
            )
        outputs = _publish(folder, names, job.out_dir)
        return _new_record(
            path,
            job,
            status="done",
            input_sha256=input_sha256,
            outputs=outputs,
            objects=objects,
            faces=faces,
            seconds=time.perf_counter() - t0,
        )
    finally:
        shutil.rmtree(folder, ignore_errors=True)
        _remove_partial_root(job.out_dir)
