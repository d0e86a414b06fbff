"""``python -m bidegree_blender.batch``: arguments, the local loop, progress and the summary.

Arguments are checked before any work (inputs exist and are ``.blend`` / ``.obj`` files with
distinct output names, the settings are ones the core accepts, the output folder is a folder
that can be written); a bad one exits with status 2 and one line on stderr. Then every input is
converted, here one after another or on a cluster (:mod:`.farm`), with one line per finished
file on stdout (a live bar on stderr when it is a terminal and ``tqdm`` is installed), the
manifest updated as files finish (:mod:`.manifest`), and a summary naming every failure. Exit
status: 0 all done, 1 some file failed, 2 bad arguments, 128 + N on signal N.
"""

from __future__ import annotations

import argparse
import os
import signal
import sys
import tempfile
from collections.abc import Callable, Sequence
from types import FrameType
from typing import Any, NoReturn

import bidegree
import numpy as np
from bidegree.options import Options

from .convert import (
    INPUT_TYPES,
    FileRecord,
    Job,
    convert_file,
    failed_record,
    output_stem,
    remove_partials,
)
from .manifest import Manifest, ManifestError, is_current

PROG = "python -m bidegree_blender.batch"


class UsageError(Exception):
    """A bad argument (exit status 2, one line)."""


class _Parser(argparse.ArgumentParser):
    def error(self, message: str) -> NoReturn:
        self.exit(2, f"{self.prog}: error: {message} (see --help)\n")


def build_parser() -> argparse.ArgumentParser:
    """The command line."""
    parser = _Parser(
        prog=PROG,
        description="Subdivide the mesh objects of .blend / .obj files with bidegree (bpy): "
        "DIR/<stem>.bidegree.blend per input and, with --usd, DIR/<stem>[_<object>].usdc; "
        "DIR/bidegree-manifest.json records what was done.",
    )
    parser.add_argument("inputs", nargs="+", metavar="IN", help=".blend or .obj files")
    parser.add_argument("--degree", type=int, default=4)
    parser.add_argument("--levels", type=int, default=2)
    parser.add_argument("--output", choices=("primal", "dual"), default="primal")
    parser.add_argument("--boundary", choices=("edge-only", "edge-and-corner"), default="edge-only")
    parser.add_argument("--no-creases", action="store_true", help="ignore edge/vertex creases")
    parser.add_argument(
        "--rules", choices=("averaging", "classic"), default="averaging", help="rule set"
    )
    parser.add_argument("--limit", action="store_true", help="vertices on the limit surface")
    parser.add_argument("--normals", action="store_true", help="limit normals (custom normals)")
    parser.add_argument("--out", required=True, metavar="DIR", help="output folder")
    parser.add_argument("--usd", action="store_true", help="also write USD (.usdc)")
    parser.add_argument("--usda", action="store_true", help="also write USD as text (.usda)")
    parser.add_argument(
        "--trust-scripts",
        action="store_true",
        help="let .blend inputs run their Python scripts (registered texts, drivers); off by "
        "default whatever Blender's Auto Run preference says",
    )
    parser.add_argument(
        "--resume",
        action="store_true",
        help="skip inputs the manifest lists as done whose input and outputs are unchanged",
    )
    where = parser.add_mutually_exclusive_group()
    where.add_argument(
        "--workers",
        type=int,
        metavar="N",
        help="run on a local dask cluster of N worker processes (one thread each)",
    )
    where.add_argument(
        "--scheduler",
        metavar="ADDRESS",
        help="run on the dask.distributed scheduler at ADDRESS (tcp://HOST:PORT)",
    )
    parser.add_argument(
        "--retries",
        type=int,
        default=2,
        metavar="N",
        help="with --workers/--scheduler: attempts after the first when a worker dies or a "
        "write fails (default 2)",
    )
    return parser


def _check_settings(settings: Options) -> None:
    """Let the core refuse bad settings now, on one quad (its own checks and messages)."""
    quad = bidegree.Mesh(
        np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], dtype=np.float64), [[0, 1, 2, 3]]
    )
    settings.estimate(quad)
    settings.replace(levels=min(settings.levels, 1)).subdivide(quad)


def _check_inputs(inputs: Sequence[str]) -> list[str]:
    """Absolute input paths; each an existing .blend/.obj file, with distinct output names."""
    paths: list[str] = []
    stems: dict[str, str] = {}
    for given in inputs:
        path = os.path.abspath(given)
        if os.path.splitext(path)[1].lower() not in INPUT_TYPES:
            raise UsageError(f"{given}: not a .blend or .obj file")
        if not os.path.isfile(path):
            raise UsageError(f"{given}: no such file")
        stem = output_stem(path)
        if stem in stems:
            other = stems[stem]
            what = "is given twice" if other == path else f"and {other} both write {stem}.*"
            raise UsageError(f"{given} {what}")
        stems[stem] = path
        paths.append(path)
    return paths


def _check_out_dir(out: str) -> str:
    """The output folder, created if needed, checked writable by writing a file into it."""
    out = os.path.abspath(out)
    if os.path.exists(out) and not os.path.isdir(out):
        raise UsageError(f"--out {out}: not a folder")
    try:
        os.makedirs(out, exist_ok=True)
        fd, probe = tempfile.mkstemp(dir=out, prefix=".bidegree-probe-")
        os.close(fd)
        os.unlink(probe)
    except OSError as exc:
        raise UsageError(f"--out {out}: cannot write there ({exc.strerror or exc})") from exc
    return out


def check_arguments(args: argparse.Namespace) -> tuple[list[str], Job]:
    """The input paths and the job, or :class:`UsageError` (nothing is written but ``--out``)."""
    try:
        settings = Options(
            degree=args.degree,
            levels=args.levels,
            output=args.output,
            boundary=args.boundary,
            use_creases=not args.no_creases,
            rules=args.rules,
            limit=args.limit,
            normals=args.normals,
        )
        _check_settings(settings)
    except bidegree.BidegreeError as exc:
        raise UsageError(" ".join(str(exc).split())) from exc
    if args.workers is not None and args.workers < 1:
        raise UsageError(f"--workers {args.workers}: at least 1")
    if args.retries < 0:
        raise UsageError(f"--retries {args.retries}: at least 0")
    if args.workers is not None or args.scheduler is not None:
        from .farm import FarmError, require_distributed

        try:
            require_distributed()
        except FarmError as exc:
            raise UsageError(str(exc)) from exc
    if args.usd and args.usda:
        raise UsageError("--usd and --usda: give one of them")
    inputs = _check_inputs(args.inputs)
    usd = "usda" if args.usda else ("usdc" if args.usd else None)
    job = Job(_check_out_dir(args.out), settings, usd, args.trust_scripts)
    return inputs, job


class Progress:
    """One line per finished file on stdout, a live bar on a terminal, the manifest, the counts."""

    def __init__(self, total: int, manifest: Manifest) -> None:
        self.total = total
        self.manifest = manifest
        self.records: list[FileRecord] = []
        self.skipped: list[str] = []
        self._bar: Any = None
        if sys.stderr.isatty():
            try:
                from tqdm import tqdm
            except ImportError:
                pass
            else:
                self._bar = tqdm(total=total, unit="file", file=sys.stderr, dynamic_ncols=True)

    def _line(self, text: str) -> None:
        if self._bar is not None:
            self._bar.write(text, file=sys.stdout)
            self._bar.update(1)
        else:
            print(text, flush=True)

    def _count(self) -> str:
        return f"[{len(self.records) + len(self.skipped)}/{self.total}]"

    def skip(self, path: str) -> None:
        """``path`` is already done (``--resume``)."""
        self.skipped.append(path)
        self._line(f"{self._count()} {path}: skipped, done before (manifest)")

    def finished(self, record: FileRecord) -> None:
        """``record``'s file has finished (done or failed)."""
        self.records.append(record)
        self.manifest.record(record)
        retried = f" after {record.attempts} attempts" if record.attempts > 1 else ""
        if record.ok:
            outs = ", ".join(o.path for o in record.outputs)
            self._line(
                f"{self._count()} {record.input}: ok, {record.objects} object(s), "
                f"{record.faces} faces, {record.seconds:.2f} s{retried} -> {outs}"
            )
        else:
            self._line(f"{self._count()} {record.input}: FAILED{retried}: {record.error}")

    def close(self) -> None:
        """Write the manifest and take the bar down."""
        if self._bar is not None:
            self._bar.close()
        self.manifest.flush()

    def summary(self) -> str:
        """The closing lines: counts, the manifest, every failure with its message."""
        failed = [r for r in self.records if not r.ok]
        lines = [
            f"bidegree batch: {len(self.records) - len(failed)} done, {len(failed)} failed, "
            f"{len(self.skipped)} skipped; manifest {self.manifest.path}"
        ]
        lines += [f"  failed: {r.input}: {r.error}" for r in failed]
        return "\n".join(lines)


def run_local(inputs: Sequence[str], job: Job, on_record: Callable[[FileRecord], None]) -> None:
    """Convert ``inputs`` one after another in this process's ``bpy`` session."""
    for path in inputs:
        try:
            record = convert_file(path, job)
        except (OSError, MemoryError) as exc:
            record = failed_record(path, job, exc)
        on_record(record)


def _interrupt(signum: int, _frame: FrameType | None) -> NoReturn:
    raise KeyboardInterrupt(signum)


def main(argv: Sequence[str] | None = None) -> int:
    """Command-line entry point; returns the process exit code."""
    args = build_parser().parse_args(argv)
    try:
        inputs, job = check_arguments(args)
        manifest = Manifest(job.out_dir)
        done = manifest.read() if args.resume else {}
    except (UsageError, ManifestError) as exc:
        print(f"{PROG}: error: {exc}", file=sys.stderr)
        return 2
    progress = Progress(len(inputs), manifest)
    todo = []
    for path in inputs:
        if args.resume and is_current(done.get(path), job):
            progress.skip(path)
        else:
            todo.append(path)
    # SIGTERM ends the run as Ctrl-C does: the file being written is removed, the manifest kept.
    if signal.getsignal(signal.SIGTERM) is signal.SIG_DFL:
        signal.signal(signal.SIGTERM, _interrupt)
    try:
        if args.workers is None and args.scheduler is None:
            run_local(todo, job, progress.finished)
        else:
            from .farm import FarmError, run_distributed

            try:
                run_distributed(
                    todo,
                    job,
                    progress.finished,
                    scheduler=args.scheduler,
                    workers=args.workers,
                    retries=args.retries,
                )
            except FarmError as exc:
                print(f"{PROG}: error: {exc}", file=sys.stderr)
                return 2
    except KeyboardInterrupt as exc:
        signum = exc.args[0] if exc.args and isinstance(exc.args[0], int) else signal.SIGINT
        print(f"{PROG}: interrupted", file=sys.stderr)
        return 128 + int(signum)
    finally:
        progress.close()
        for path in todo:
            remove_partials(job.out_dir, output_stem(path))
    print(progress.summary(), flush=True)
    return 1 if any(not r.ok for r in progress.records) else 0
