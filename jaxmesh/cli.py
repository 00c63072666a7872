"""The ``jaxmesh`` command line (also ``python -m jaxmesh``).

Each subcommand is a pair ``(configure(parser), run(args) -> exit code)``
registered in :data:`COMMANDS`; later capabilities add their own pair.
Conventions, as for any Unix tool: results on stdout (``--json`` for machine
output, one JSON object per line), diagnostics on stderr prefixed with
``jaxmesh:``, exit status 0 on success, 1 on a bad input or failed operation,
2 on a usage error.  Output files are never overwritten without ``--force``.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import warnings
from typing import Callable

__all__ = ["main", "COMMANDS"]


from .cli_denoise import DEMO, DENOISE, NOISE, CLIError, _mesh_source
from .cli_compress import COMPRESS, DECOMPRESS
from .cli_hash import HASH


# ---------------------------------------------------------------- info


def _configure_info(p: argparse.ArgumentParser) -> None:
    from . import data

    p.add_argument("mesh", nargs="*", metavar="MESH", help="mesh file(s): OBJ, PLY, OFF, STL")
    p.add_argument("--sample", action="append", choices=sorted(data.SAMPLES),
                   help="use a sample mesh shipped with jaxmesh (repeatable)")
    p.add_argument("--json", action="store_true", help="one JSON object per mesh, per line")


def _format_value(v) -> str:
    if isinstance(v, bool):
        return "yes" if v else "no"
    if v is None:
        return "undefined"
    if isinstance(v, float):
        return f"{v:.6g}"
    return str(v)


def _print_record(record: dict, as_json: bool, first: bool) -> None:
    """One mesh's record: a JSON line, or a labelled block (blank line between meshes)."""
    if as_json:
        print(json.dumps(record), flush=True)
        return
    if not first:
        print()
    print(record["path"])
    width = max(len(k) for k in record)
    for key, value in record.items():
        if key != "path":
            print(f"  {key.replace('_', ' '):<{width}}  {_format_value(value)}")


def _run_info(args) -> int:
    from .topology import mesh_info

    for i, (label, loader) in enumerate(_mesh_source(args)):
        _print_record({"path": label, **mesh_info(loader())}, args.json, i == 0)
    return 0


# ---------------------------------------------------------------- convert


def _configure_convert(p: argparse.ArgumentParser) -> None:
    p.add_argument("input", metavar="IN", help="mesh file to read")
    p.add_argument("output", metavar="OUT", help="mesh file to write (format from the suffix)")
    p.add_argument("--force", action="store_true", help="replace OUT if it exists")
    p.add_argument("--merge-duplicates", action="store_true",
                   help="merge exactly coincident vertices (first occurrence kept, order kept)")


def _run_convert(args) -> int:
    import jax

    from .io import load, save

    # a conversion must not round coordinates: read and write in float64
    jax.config.update("jax_enable_x64", True)
    mesh = load(args.input, merge_duplicates=args.merge_duplicates or None)
    save(mesh, args.output, overwrite=args.force)
    print(f"wrote {args.output}: {mesh.num_vertices} vertices, {mesh.num_faces} faces", file=sys.stderr)
    return 0


# ---------------------------------------------------------------- stats


def _configure_stats(p: argparse.ArgumentParser) -> None:
    from . import data

    p.add_argument("mesh", nargs="*", metavar="MESH", help="mesh file(s)")
    p.add_argument("--sample", action="append", choices=sorted(data.SAMPLES), help="a shipped sample mesh")
    p.add_argument("--json", action="store_true", help="one JSON object per mesh, per line")
    p.add_argument("--plot", metavar="PNG", help="draw the six-panel figure (one mesh only)")
    p.add_argument("--force", action="store_true", help="replace the --plot file if it exists")
    p.add_argument("--sources", type=int, default=200, help="geodesic sources (default 200)")
    p.add_argument("--seed", type=int, default=0, help="seed of the source sample (default 0)")
    p.add_argument("--knn", type=int, default=8, help="neighbours of the kNN graph (default 8)")


def _stage(label: str):
    """Progress lines on stderr for a terminal (long statistics), silent otherwise."""
    if not sys.stderr.isatty():
        return None
    return lambda stage: print(f"jaxmesh: {label}: {stage}...", file=sys.stderr, flush=True)


def _run_stats(args) -> int:
    import jax

    from .stats import mesh_statistics, plot_statistics

    jax.config.update("jax_enable_x64", True)
    sources = _mesh_source(args)
    if args.plot:
        if len(sources) > 1:
            raise CLIError("--plot draws one mesh; name a single MESH")
        if os.path.exists(args.plot) and not args.force:
            raise CLIError(f"{args.plot} exists; use --force to replace it")
    if args.sources < 1:
        raise CLIError(f"--sources must be >= 1, got {args.sources}")
    for i, (label, loader) in enumerate(sources):
        mesh = loader()
        st = mesh_statistics(mesh, sources=args.sources, seed=args.seed, knn=args.knn, progress=_stage(label))
        _print_record({"path": label, **st["summary"]}, args.json, i == 0)
        if args.plot:
            import io

            import matplotlib

            matplotlib.use("Agg")
            from .io import write_bytes_atomic

            buf = io.BytesIO()
            plot_statistics(mesh, st, title=label).savefig(buf, dpi=100, format="png")
            write_bytes_atomic(args.plot, buf.getvalue(), overwrite=args.force)
    return 0


COMMANDS: dict[str, tuple[str, Callable, Callable]] = {
    "info": ("counts, topology and geometry summary of a mesh", _configure_info, _run_info),
    "convert": ("convert between OBJ, PLY, OFF and STL, keeping vertex order", _configure_convert,
                _run_convert),
    "noise": NOISE,
    "denoise": DENOISE,
    "demo": DEMO,
    "stats": ("degree, assortativity, clustering, geodesic and spectral statistics (ch.5)",
              _configure_stats, _run_stats),
    "hash": HASH,
    "compress": COMPRESS,
    "decompress": DECOMPRESS,
}


def build_parser() -> argparse.ArgumentParser:
    from . import __version__

    parser = argparse.ArgumentParser(
        prog="jaxmesh",
        description="Differentiable triangle-mesh processing (JAX).",
    )
    parser.add_argument("--version", action="version", version=f"jaxmesh {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name, (help_text, configure, run) in COMMANDS.items():
        p = sub.add_parser(name, help=help_text, description=help_text)
        configure(p)
        p.set_defaults(_run=run)
    return parser


def _show_warning(message, category, filename, lineno, file=None, line=None):
    print(f"jaxmesh: warning: {message}", file=sys.stderr)


def _os_error(err: OSError) -> str:
    where = err.filename if err.filename is not None else ""
    reason = err.strerror or type(err).__name__
    return f"{where}: {reason}" if where else reason


def _in_worker(run, args):
    """Run the command in a worker thread and wait for it from the main thread, so
    that Ctrl-C is seen within a fraction of a second even while XLA compiles or
    runs a long loop (the main thread would otherwise be blocked in C++ and
    Python would only see the signal when the call returns).  On Ctrl-C the
    temporary files being written are removed and the process exits with 130
    without waiting for the worker."""
    import threading

    from .io import IN_PROGRESS

    box: dict = {}

    def work():
        try:
            box["value"] = run(args)
        except BaseException as err:  # re-raised in the main thread
            box["error"] = err

    thread = threading.Thread(target=work, name="jaxmesh-command", daemon=True)
    thread.start()
    try:
        while thread.is_alive():
            thread.join(0.1)
    except KeyboardInterrupt:
        for tmp in list(IN_PROGRESS):
            try:
                os.unlink(tmp)
            except OSError:
                pass
        print("jaxmesh: interrupted; nothing was written", file=sys.stderr)
        sys.stderr.flush()
        sys.stdout.flush()
        os._exit(130)
    if "error" in box:
        raise box["error"]
    return box.get("value")


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "_run", None):
        parser.print_help(sys.stderr)
        return 2
    from .io import MeshFileError

    warnings.showwarning = _show_warning
    try:
        return int(_in_worker(args._run, args) or 0)
    except (CLIError, MeshFileError, FileExistsError, ValueError, FloatingPointError) as err:
        print(f"jaxmesh: error: {err}", file=sys.stderr)
        return 1
    except BrokenPipeError:  # e.g. `jaxmesh info --json a b | head -1`
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        return 0
    except OSError as err:  # permissions, a full disk, a directory given as a file, ...
        print(f"jaxmesh: error: {_os_error(err)}", file=sys.stderr)
        return 1
    except MemoryError:
        print("jaxmesh: error: out of memory (the input is too large for this machine, or corrupt)",
              file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print("jaxmesh: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
