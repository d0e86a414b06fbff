"""The ``bidegree`` command line.

Subcommands:
    subdivide   subdivide an OBJ cage, write OBJ (or USD through ``bidegree.usd``)
    bench       throughput of fresh and cached subdivision against a plain memory copy
    compare     (when ``bidegree.compare`` is available) compare with OpenSubdiv

Other modules can provide subcommands: a module ``bidegree.<name>`` listed in
:data:`OPTIONAL_SUBCOMMANDS` that defines ``add_arguments(parser)`` and ``run(args) -> int`` is
registered as ``bidegree <name>`` when it imports.

Errors (bad files, invalid meshes, refused requests, a bug in the core) print one line,
``bidegree: error: ...``, on stderr and exit with status 2; warnings print
``bidegree: warning: ...`` lines. SIGINT (Ctrl-C) and SIGTERM stop the work, remove any output
file being written (the target keeps what it had) and exit with 130 and 143. With
``BIDEGREE_DEBUG=1`` in the environment an internal error also prints where the core failed.
"""

from __future__ import annotations

import argparse
import contextlib
import importlib
import os
import signal
import sys
import time
import warnings
from collections.abc import Callable, Iterator, Sequence
from typing import Any

import bidegree
from bidegree.options import Options

#: Modules ``bidegree.<name>`` registered as subcommands when they import (with help text).
OPTIONAL_SUBCOMMANDS: dict[str, str] = {
    "compare": "compare with OpenSubdiv's Catmull-Clark surface of the same cage",
    "analyze": "the paper's §4 analysis of a scheme at one valence (eigenvalues, C1 check, plots)",
}

_USD_EXTENSIONS = (".usda", ".usdc", ".usd")
_SIZE_SUFFIXES = {"k": 1 << 10, "m": 1 << 20, "g": 1 << 30, "t": 1 << 40}


class CliError(Exception):
    """A user error found by the command line itself (bad option value, missing module)."""


class Terminated(BaseException):
    """Raised by the SIGTERM handler (a ``BaseException`` like ``KeyboardInterrupt``: it stops
    the work wherever it is, and cleanup code runs on the way out)."""

    def __init__(self, signum: int) -> None:
        super().__init__(signal.Signals(signum).name)
        self.signum = signum


@contextlib.contextmanager
def _signals_stop_the_work() -> Iterator[None]:
    """SIGTERM raises :class:`Terminated` while the command runs (SIGINT already raises
    ``KeyboardInterrupt``). The core's file readers and writers run Python's signal handlers
    between chunks, so either signal stops a long read or write and removes its temporary
    file. Outside the main thread (``main`` called from a worker) nothing is installed."""

    def terminate(signum: int, frame: Any) -> None:
        raise Terminated(signum)

    try:
        previous = signal.signal(signal.SIGTERM, terminate)
    except ValueError:  # not the main thread
        yield
        return
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


@contextlib.contextmanager
def _printing_warnings() -> Iterator[None]:
    """Prints bidegree's warnings (isolated vertices, skipped OBJ statements) as
    ``bidegree: warning: ...`` lines on stderr, each once."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", bidegree.IsolatedVerticesWarning)
        warnings.simplefilter("always", bidegree.ObjWarning)
        try:
            yield
        finally:
            for warning in caught:
                print(f"bidegree: warning: {_one_line(str(warning.message))}", file=sys.stderr)


def _one_line(text: str) -> str:
    """``text`` as one printable line: line breaks become spaces, other control characters
    (which a file's content could carry into a message) are escaped."""
    text = " ".join(text.splitlines())
    return "".join(c if c.isprintable() else c.encode("unicode_escape").decode() for c in text)


def parse_size(text: str) -> int:
    """Parses a byte count: ``4294967296``, ``4G``, ``512M``, ``64k`` (binary multiples)."""
    value = text.strip().lower().removesuffix("b").removesuffix("i")
    scale = 1
    if value and value[-1] in _SIZE_SUFFIXES:
        scale = _SIZE_SUFFIXES[value[-1]]
        value = value[:-1]
    try:
        number = float(value) if "." in value else int(value)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a byte count: {text!r}") from None
    if number < 0:
        raise argparse.ArgumentTypeError(f"byte count must be >= 0: {text!r}")
    return int(number * scale)


def _seconds(t: float) -> str:
    return f"{t * 1000:.1f} ms" if t < 1 else f"{t:.2f} s"


# ---------------------------------------------------------------------------------------------
# subdivide


def _add_subdivide(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("input", help="cage OBJ file (v, vt, f; OpenSubdiv t-tags)")
    parser.add_argument(
        "-o",
        "--out",
        required=True,
        metavar="OUT",
        help="output file: .obj, or .usda/.usdc/.usd (needs usd-core)",
    )
    parser.add_argument(
        "--degree", type=int, default=4, help="degree, 1..31 (3 ~ Catmull-Clark; default 4)"
    )
    parser.add_argument("--levels", type=int, default=2, help="refinement levels (default 2)")
    parser.add_argument(
        "--output",
        choices=("primal", "dual"),
        default="primal",
        help="drawing mesh (primal, default) or true dual mesh",
    )
    parser.add_argument(
        "--boundary",
        choices=("edge-only", "edge-and-corner"),
        default=None,
        help="boundary rule (default: the OBJ's 't interpolateboundary' tag, else edge-only)",
    )
    parser.add_argument(
        "--rules",
        choices=("averaging", "classic"),
        default="averaging",
        help="averaging (default, any degree) or classic (3: OpenSubdiv catmark, 2: Doo-Sabin)",
    )
    parser.add_argument(
        "--creasing",
        choices=("uniform", "chaikin"),
        default=None,
        help="classic rules: how semi-sharp creases decrease per level (default: the OBJ's "
        "'t creasemethod' tag, else uniform)",
    )
    parser.add_argument(
        "--memory-budget",
        type=parse_size,
        default=None,
        metavar="BYTES",
        help="refuse requests estimated above this size (e.g. 8G; default 4G)",
    )
    parser.add_argument(
        "--max-input-bytes",
        type=parse_size,
        default=None,
        metavar="BYTES",
        help="refuse input files larger than this (e.g. 8G; default 2G)",
    )
    parser.add_argument(
        "--limit",
        action="store_true",
        help="put the output vertices on the limit surface (exact limit positions)",
    )
    parser.add_argument(
        "--normals",
        action="store_true",
        help="write the limit normals (per face corner, split at creases: OBJ vn, USD faceVarying)",
    )
    parser.add_argument(
        "--uv-mode",
        choices=("none", "corners-only", "corners-plus1", "corners-plus2", "boundaries", "all"),
        default="boundaries",
        help="how the OBJ's vt are subdivided: OpenSubdiv's face-varying modes, from smooth "
        "everywhere (none) to linear (all); default boundaries (Blender's Keep Boundaries)",
    )
    parser.add_argument("-q", "--quiet", action="store_true", help="print nothing on success")
    _add_adaptive_arguments(parser)


def _add_adaptive_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--adaptive",
        action="store_true",
        help="adaptive subdivision (quadtrees refined where not flat), crack-free triangles",
    )
    parser.add_argument(
        "--tolerance",
        type=float,
        default=1e-3,
        help="adaptive: flatness tolerance relative to the cage's diagonal (default 1e-3; "
        "0 refines everywhere)",
    )
    parser.add_argument(
        "--max-level",
        type=int,
        default=None,
        metavar="L",
        help="adaptive: deepest level (default: --levels)",
    )


def _run_adaptive(args: argparse.Namespace, say: Callable[[str], None]) -> int:
    """``subdivide --adaptive``: OBJ in, triangles out (OBJ only)."""
    if os.path.splitext(args.out)[1].lower() != ".obj":
        raise CliError(f"{args.out}: adaptive output is written as OBJ only")
    if args.output != "primal" or args.rules != "averaging":
        raise CliError("--adaptive draws the primal drawing mesh with averaging rules only")
    if args.limit or args.normals:
        raise CliError("--adaptive does not compute limit positions or normals yet")
    start = time.perf_counter()
    cage = _read_cage(args)
    say(f"cage: {cage.num_vertices} vertices, {cage.num_faces} faces ({args.input})")
    max_level = args.levels if args.max_level is None else args.max_level
    result = Options.from_namespace(args).subdivide_adaptive(cage)
    elapsed = time.perf_counter() - start
    leaves = ", ".join(
        f"{n} at level {level}" for level, n in enumerate(result.leaves_per_level) if n
    )
    say(
        f"degree {result.degree}, adaptive to level {max_level}, tolerance {result.tolerance:g}: "
        f"{result.num_leaves} leaves ({leaves})"
    )
    say(
        f"output: {result.num_vertices} vertices, {result.num_triangles} triangles (subdivided "
        f"in {_seconds(elapsed)})"
    )
    start = time.perf_counter()
    result.write_obj(args.out)
    say(f"wrote {args.out} in {_seconds(time.perf_counter() - start)}")
    return 0


def _read_cage(args: argparse.Namespace) -> bidegree.Mesh:
    """The input cage, with the file's tags unless the options override them."""
    return bidegree.Mesh.from_obj(
        args.input,
        boundary=args.boundary,
        creasing=args.creasing,
        max_bytes=args.max_input_bytes,
        memory_budget=args.memory_budget,
    )


def _export_usd(path: str, cage: bidegree.Mesh, result: bidegree.Result) -> None:
    try:
        usd = importlib.import_module("bidegree.usd")
    except ImportError as exc:
        raise CliError(f"USD output is not available ({exc})") from None
    try:
        usd.export(path, cage, result)
    except ImportError as exc:
        raise CliError(f"USD output needs usd-core (pip install usd-core): {exc}") from None


def _run_subdivide(args: argparse.Namespace) -> int:
    out_ext = os.path.splitext(args.out)[1].lower()
    if out_ext != ".obj" and out_ext not in _USD_EXTENSIONS:
        raise CliError(f"{args.out}: unsupported output format (use .obj, .usda, .usdc or .usd)")
    say: Callable[[str], None] = (lambda _: None) if args.quiet else print
    if args.adaptive:
        return _run_adaptive(args, say)

    start = time.perf_counter()
    cage = _read_cage(args)
    read_time = time.perf_counter() - start
    say(
        f"cage: {cage.num_vertices} vertices, {cage.num_faces} faces ({args.input}, read in "
        f"{_seconds(read_time)})"
    )

    start = time.perf_counter()
    result = Options.from_namespace(args).subdivide(cage)
    subdivide_time = time.perf_counter() - start
    surface = ", limit positions" if args.limit else ""
    surface += ", limit normals" if args.normals else ""
    say(
        f"degree {result.degree}, {result.levels} levels, {result.output} output, "
        f"{result.boundary} boundary{surface}"
    )
    say(
        f"output: {result.num_vertices} vertices, {result.num_faces} faces (subdivided in "
        f"{_seconds(subdivide_time)})"
    )

    start = time.perf_counter()
    if out_ext == ".obj":
        result.write_obj(args.out)
    else:
        _export_usd(args.out, cage, result)
    write_time = time.perf_counter() - start
    say(f"wrote {args.out} in {_seconds(write_time)}")
    return 0


# ---------------------------------------------------------------------------------------------
# bench


def _add_bench(parser: argparse.ArgumentParser) -> None:
    from . import bench

    bench.add_arguments(parser)


def _run_bench(args: argparse.Namespace) -> int:
    from . import bench

    return bench.run(args)


# ---------------------------------------------------------------------------------------------
# parser and entry point


def _optional_subcommands() -> dict[str, Any]:
    """The optional subcommand modules that import and provide the hooks."""
    found = {}
    for name in OPTIONAL_SUBCOMMANDS:
        try:
            module = importlib.import_module(f"bidegree.{name}")
        except ImportError:
            continue
        if callable(getattr(module, "add_arguments", None)) and callable(
            getattr(module, "run", None)
        ):
            found[name] = module
    return found


def build_parser() -> argparse.ArgumentParser:
    """The argument parser with every available subcommand."""
    parser = argparse.ArgumentParser(
        prog="bidegree",
        description="Subdivision surfaces of any degree by repeated averaging (Zorin-Schröder).",
    )
    parser.add_argument("--version", action="version", version=f"bidegree {bidegree.__version__}")
    commands = parser.add_subparsers(dest="command", metavar="COMMAND")

    sub = commands.add_parser(
        "subdivide",
        help="subdivide an OBJ cage and write OBJ or USD",
        description="Subdivide an OBJ cage with a degree-N scheme and write the result.",
    )
    _add_subdivide(sub)
    sub.set_defaults(handler=_run_subdivide)

    sub = commands.add_parser(
        "bench",
        help="throughput: fresh vs cached plan vs plain memory copy",
        description="Output faces per second for degrees 1..9 at ~4M output faces, fresh "
        "(subdivide) and through a cached Plan, next to a plain memory copy of the same size.",
    )
    _add_bench(sub)
    sub.set_defaults(handler=_run_bench)

    for name, module in _optional_subcommands().items():
        sub = commands.add_parser(name, help=OPTIONAL_SUBCOMMANDS[name])
        module.add_arguments(sub)
        sub.set_defaults(handler=module.run)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Runs the command line; returns the exit status (0 ok, 2 error)."""
    parser = build_parser()
    args = parser.parse_args(argv)
    handler = getattr(args, "handler", None)
    if handler is None:
        parser.print_help(sys.stderr)
        return 2
    try:
        with _signals_stop_the_work(), _printing_warnings():
            return int(handler(args) or 0)
    except (bidegree.BidegreeError, CliError, OSError) as exc:
        print(f"bidegree: error: {_one_line(str(exc)) or type(exc).__name__}", file=sys.stderr)
        detail = getattr(exc, "detail", None)
        if detail and os.environ.get("BIDEGREE_DEBUG", "0") not in ("", "0"):
            print(f"bidegree: debug: {_one_line(str(detail))}", file=sys.stderr)
        return 2
    except MemoryError:
        print("bidegree: error: out of memory (lower --levels or --memory-budget)", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("bidegree: interrupted", file=sys.stderr)
        return 130
    except Terminated as exc:
        print(f"bidegree: terminated ({exc})", file=sys.stderr)
        return 128 + exc.signum


if __name__ == "__main__":
    sys.exit(main())
