"""The ``jaxmesh`` command line (also ``python -m jaxmesh``).

One module per command, each with ``configure(parser)`` and ``run(args) -> exit code``,
named with its one-line help in :data:`COMMANDS`; a new command is a new module and one
line there.  Only the command being run is imported (``jaxmesh --help`` imports none, and
not JAX).  Each command parses, makes one library call and prints.  Conventions, as for
any Unix tool: results on stdout (``--json`` for machine output, one JSON object per
line), diagnostics on stderr prefixed with ``jaxmesh:``, exit status 0 on success, 1 on
a bad input or failed operation, 2 on a usage error, 130 on Ctrl-C.  Output files are
never overwritten without ``--force``.  Every command runs with 64-bit floats (files are
never rounded), and with :func:`jaxmesh.compiler.prefer_fast_cpu_compiles`'s XLA setting
unless ``JAXMESH_XLA_DEFAULTS=1``.  Compiled programs are kept between runs in JAX's
persistent compilation cache (:func:`jaxmesh.compiler.enable_compilation_cache`;
``--no-cache`` or ``JAXMESH_CACHE_DIR=off`` for none).  The executable
(:func:`command`) exits as soon as its output is flushed, without the interpreter's
teardown (freeing XLA's programs and buffers, a noticeable share of a short command).
On glibc it also caps malloc at :data:`MALLOC_ARENAS` arenas unless ``MALLOC_ARENA_MAX`` is
set (:func:`limit_malloc_arenas`).
"""

from __future__ import annotations

import argparse
import logging
import os
import sys
import warnings

import importlib

from ._common import CLIError
from ._run import run_command

__all__ = ["main", "command", "build_parser", "COMMANDS", "CLIError"]

#: each command (the module ``jaxmesh.cli.NAME``) and its one-line help, in ``--help``'s order
COMMANDS = {
    "info": "counts, topology and geometry summary of a mesh",
    "convert": "convert between OBJ, PLY, OFF and STL, keeping vertex order",
    "noise": "add Gaussian or impulsive noise to a mesh",
    "denoise": "denoise a mesh with any registered method",
    "demo": "denoise the shipped bunny and print the errors before and after",
    "train": "train a learned denoiser on your own clean (and noisy) meshes",
    "stats": "degree, assortativity, clustering, geodesic and spectral statistics (ch.5)",
    "hash": "print a mesh's hash, or compare two meshes (thesis ch.4)",
    "compress": "compress a mesh to a .jxm file (spectral geometry, lossless connectivity; ch.3)",
    "decompress": "decode a .jxm file to a mesh file",
    "view": "write one self-contained HTML page showing meshes side by side",
}


def _named_command(argv: list[str]) -> str | None:
    """The command ``argv`` runs: its first word that is not an option (the top-level
    options take no value)."""
    return next((word for word in argv if not word.startswith("-")), None)


def build_parser(commands: tuple[str, ...] | None = None) -> argparse.ArgumentParser:
    """The argument parser, with the options of ``commands`` (every command's with None).

    Arguments:
        commands: the commands whose modules are imported and whose options are added
            (the others are listed with their help only); None for all of them.

    Returns:
        The parser."""
    from .. import __version__

    parser = argparse.ArgumentParser(prog="jaxmesh", description="Differentiable triangle-mesh processing (JAX).")
    parser.add_argument("--version", action="version", version=f"jaxmesh {__version__}")
    parser.add_argument("--no-cache", action="store_true",
                        help="do not read or write the persistent compilation cache "
                             "(default folder: $JAXMESH_CACHE_DIR, else ~/.cache/jaxmesh/jax)")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name, help_line in COMMANDS.items():
        p = sub.add_parser(name, help=help_line, description=help_line)
        if commands is None or name in commands:
            module = importlib.import_module(f".{name}", __name__)
            module.configure(p)
            p.set_defaults(_run=module.run)
    return parser


def _show_warning(message, category, filename, lineno, file=None, line=None):
    print(f"jaxmesh: warning: {message}", file=sys.stderr)


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else list(argv)
    name = _named_command(argv)
    parser = build_parser((name,) if name else ())
    args = parser.parse_args(argv)
    if not getattr(args, "_run", None):
        parser.print_help(sys.stderr)
        return 2
    from ..compiler import prefer_fast_cpu_compiles

    prefer_fast_cpu_compiles()   # before JAX's backend starts: compiles ~2x faster on CPU
    import jax

    jax.config.update("jax_enable_x64", True)  # the one place: files are read and written unrounded
    # JAX's own log stays quiet during the command unless JAX_LOGGING_LEVEL asks for it: a host
    # callback's exception reaches the command as its one error line, and JAX's log of the same
    # exception (a traceback on stderr) would only repeat it
    jax_log = logging.getLogger("jax")
    level = jax_log.level
    if not os.environ.get("JAX_LOGGING_LEVEL"):
        jax_log.setLevel(logging.CRITICAL)
    # warnings are one stderr line each, whatever filters the caller (a test run with
    # -W error, an embedding program) installed; both are restored on return
    with warnings.catch_warnings():
        warnings.simplefilter("default")
        warnings.showwarning = _show_warning
        if not args.no_cache:
            from ..compiler import enable_compilation_cache

            enable_compilation_cache()
        try:
            return run_command(args._run, args)
        finally:
            jax_log.setLevel(level)


def _finish_jax() -> None:
    """What JAX's own exit handlers must still do: wait for pending effects (host callbacks) and
    leave a ``jax.distributed`` group cleanly (the other processes abort when a member vanishes)."""
    jax = sys.modules.get("jax")
    if jax is None:
        return
    jax.effects_barrier()
    distributed = getattr(jax, "distributed", None)
    if distributed is not None and getattr(distributed, "is_initialized", lambda: True)():
        distributed.shutdown()


MALLOC_ARENAS = 2


def limit_malloc_arenas(arenas: int = MALLOC_ARENAS) -> bool:
    """Cap glibc's malloc arenas (``mallopt(M_ARENA_MAX)``), before JAX starts its threads.
    By default glibc gives each thread that allocates its own arena, up to 8 per core, and
    memory freed in one arena is not reused by another: a command whose stages allocate from
    XLA's threads and from scipy's (``jaxmesh stats`` on a 134k-vertex mesh) peaks
    about 0.2 GB higher for it.  Two arenas cost no measurable time on the denoisers.  Not
    applied when ``MALLOC_ARENA_MAX`` is set (glibc read it already) or off glibc.

    Arguments:
        arenas: the most arenas.

    Returns:
        True if the cap was set."""
    if "MALLOC_ARENA_MAX" in os.environ or not sys.platform.startswith("linux"):
        return False
    try:
        import ctypes

        libc = ctypes.CDLL("libc.so.6")
        return bool(libc.mallopt(-8, int(arenas)))      # -8: M_ARENA_MAX in glibc's malloc.h
    except (OSError, AttributeError):                    # musl, or no libc.so.6
        return False


def command() -> None:
    """The ``jaxmesh`` executable (and ``python -m jaxmesh``): :func:`main` on ``sys.argv``,
    then the process ends with its exit status once pending JAX effects are done, a
    ``jax.distributed`` group is left and stdout and stderr are flushed, skipping the
    interpreter's teardown (module docstring).  Every file a command writes is complete (and
    closed) when :func:`main` returns.

    Arguments:

    Returns:
        Never: the process exits."""
    limit_malloc_arenas()
    try:
        code = main()
    except SystemExit as done:   # argparse: --help, --version, a usage error
        if not (done.code is None or isinstance(done.code, int)):
            raise
        code = done.code or 0
    _finish_jax()
    logging.shutdown()
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (BrokenPipeError, OSError, ValueError):   # a reader that went away, a closed stream
            pass
    os._exit(code)
