"""The batch manifest: ``OUT/bidegree-manifest.json``, what became of every input file.

One entry per input (its absolute path): status, outputs (name in the output folder, size and
SHA-256), degree, levels and every other setting, time, attempts, worker and error message; see
:class:`~bidegree_blender.batch.convert.FileRecord`. ``--resume`` skips an input whose entry is
``done`` with the same settings, whose input file has not changed and whose outputs are all
there with the recorded contents (:func:`is_current`).

The file is replaced atomically (a temporary file in the same folder, ``fsync``, rename), and
each write merges into what is on disk under an exclusive lock on
``OUT/.bidegree-manifest.lock``, so several batch runs sharing an output folder (the tasks of an
Open Job Description job, on one host or on hosts sharing the folder) keep each other's entries.
"""

from __future__ import annotations

import contextlib
import json
import os
import time
import uuid
from collections.abc import Iterator
from typing import Any

from .convert import FileRecord, Job, file_sha256

MANIFEST_NAME = "bidegree-manifest.json"
FORMAT = "bidegree-batch-manifest/1"
_LOCK_NAME = ".bidegree-manifest.lock"


class ManifestError(Exception):
    """The manifest exists but cannot be read (not JSON, or not a batch manifest)."""


@contextlib.contextmanager
def _locked(path: str) -> Iterator[None]:
    """An exclusive POSIX lock on ``path`` (no lock where ``fcntl`` does not exist)."""
    try:
        import fcntl
    except ImportError:  # Windows: concurrent runs in one output folder are not guarded
        yield
        return
    with open(path, "a+b") as f:
        fcntl.lockf(f, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.lockf(f, fcntl.LOCK_UN)


class Manifest:
    """Reads and (throttled, merging) writes the manifest of one output folder."""

    def __init__(self, out_dir: str, *, interval: float = 1.0) -> None:
        self.path = os.path.join(out_dir, MANIFEST_NAME)
        self._lock = os.path.join(out_dir, _LOCK_NAME)
        self._interval = interval
        self._pending: dict[str, dict[str, Any]] = {}
        self._last_write = 0.0

    def _read_raw(self) -> dict[str, dict[str, Any]]:
        try:
            with open(self.path, encoding="utf-8") as f:
                data = json.load(f)
        except FileNotFoundError:
            return {}
        except (OSError, ValueError) as exc:
            raise ManifestError(f"cannot read {self.path}: {exc}") from exc
        if not isinstance(data, dict) or data.get("format") != FORMAT:
            raise ManifestError(f"{self.path} is not a bidegree batch manifest ({FORMAT})")
        return {entry["input"]: entry for entry in data.get("files", [])}

    def read(self) -> dict[str, FileRecord]:
        """The entries on disk, by input path."""
        try:
            return {k: FileRecord.from_json(v) for k, v in self._read_raw().items()}
        except (KeyError, TypeError) as exc:
            raise ManifestError(f"{self.path}: malformed entry ({exc})") from exc

    def record(self, record: FileRecord) -> None:
        """Add or replace ``record``'s entry (written at most every ``interval`` seconds)."""
        self._pending[record.input] = record.to_json()
        if time.monotonic() - self._last_write >= self._interval:
            self.flush()

    def flush(self) -> None:
        """Write the pending entries now (merged into what is on disk)."""
        if not self._pending:
            return
        folder = os.path.dirname(self.path)
        with _locked(self._lock):
            entries = self._read_raw()
            entries.update(self._pending)
            data = {"format": FORMAT, "files": [entries[k] for k in sorted(entries)]}
            tmp = os.path.join(folder, f".{MANIFEST_NAME}.{os.getpid()}-{uuid.uuid4().hex}.tmp")
            try:
                with open(tmp, "x", encoding="utf-8") as f:
                    json.dump(data, f, indent=1)
                    f.write("\n")
                    f.flush()
                    os.fsync(f.fileno())
                os.replace(tmp, self.path)
            except BaseException:
                with contextlib.suppress(OSError):
                    os.unlink(tmp)
                raise
        self._pending.clear()
        self._last_write = time.monotonic()


def is_current(record: FileRecord | None, job: Job) -> bool:
    """Whether ``record`` says its input is done with ``job``'s settings and still is.

    The input's and every output's contents are compared with the recorded SHA-256 (a deleted,
    truncated or replaced output, or an edited input, is redone).
    """
    if record is None or not record.ok or record.settings != job.fingerprint():
        return False
    try:
        if file_sha256(record.input) != record.input_sha256:
            return False
        for out in record.outputs:
            path = os.path.join(job.out_dir, out.path)
            if os.path.getsize(path) != out.bytes or file_sha256(path) != out.sha256:
                return False
    except OSError:
        return False
    return True
