"""The ``jaxmesh`` command line (also ``python -m jaxmesh``).

One module per command, each with ``HELP``, ``configure(parser)`` and
``run(args) -> exit code``, listed in :data:`COMMANDS`; a new command is a new
module and one line there.  Each command parses, makes one library call and
prints.  Conventions, as for any Unix tool: results on stdout (``--json`` for
machine output, one JSON object per line), diagnostics on stderr prefixed with
``jaxmesh:``, exit status 0 on success, 1 on a bad input or failed operation,
2 on a usage error, 130 on Ctrl-C.  Output files are never overwritten without
``--force``.  Every command runs with 64-bit floats (files are never rounded), and
with :func:`jaxmesh.compiler.prefer_fast_cpu_compiles`'s XLA setting unless
``JAXMESH_XLA_DEFAULTS=1``.  Compiled programs are kept between runs in JAX's
persistent compilation cache (:func:`jaxmesh.compiler.enable_compilation_cache`;
``--no-cache`` or ``JAXMESH_CACHE_DIR=off`` for none).  The executable
(:func:`command`) exits as soon as its output is flushed, without the interpreter's
teardown (freeing XLA's programs and buffers, a noticeable share of a short command).
"""

from __future__ import annotations

import argparse
import logging
import os
import sys
import warnings

from . import compress, convert, decompress, demo, denoise, hash, info, noise, stats, view
from ._common import CLIError
from ._run import run_command

__all__ = ["main", "command", "build_parser", "COMMANDS", "CLIError"]

COMMANDS = {module.__name__.rsplit(".", 1)[-1]: module
            for module in (info, convert, noise, denoise, demo, stats, hash, compress, decompress, view)}


def build_parser() -> argparse.ArgumentParser:
    from .. import __version__

    parser = argparse.ArgumentParser(prog="jaxmesh", description="Differentiable triangle-mesh processing (JAX).")
    parser.add_argument("--version", action="version", version=f"jaxmesh {__version__}")
    parser.add_argument("--no-cache", action="store_true",
                        help="do not read or write the persistent compilation cache "
                             "(default folder: $JAXMESH_CACHE_DIR, else ~/.cache/jaxmesh/jax)")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name, module in COMMANDS.items():
        p = sub.add_parser(name, help=module.HELP, description=module.HELP)
        module.configure(p)
        p.set_defaults(_run=module.run)
    return parser


def _show_warning(message, category, filename, lineno, file=None, line=None):
    print(f"jaxmesh: warning: {message}", file=sys.stderr)


def main(argv: list[str] | None = None) -> int:
    from ..compiler import prefer_fast_cpu_compiles

    prefer_fast_cpu_compiles()   # before JAX's backend starts: compiles ~2x faster on CPU
    import jax

    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "_run", None):
        parser.print_help(sys.stderr)
        return 2
    jax.config.update("jax_enable_x64", True)  # the one place: files are read and written unrounded
    # warnings are one stderr line each, whatever filters the caller (a test run with
    # -W error, an embedding program) installed; both are restored on return
    with warnings.catch_warnings():
        warnings.simplefilter("default")
        warnings.showwarning = _show_warning
        if not args.no_cache:
            from ..compiler import enable_compilation_cache

            enable_compilation_cache()
        return run_command(args._run, args)


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


def command() -> None:
    """The ``jaxmesh`` executable (and ``python -m jaxmesh``): :func:`main` on ``sys.argv``,
    then the process ends with its exit status once pending JAX effects are done, a
    ``jax.distributed`` group is left and stdout and stderr are flushed, skipping the
    interpreter's teardown (module docstring).  Every file a command writes is complete (and
    closed) when :func:`main` returns.

    Arguments:

    Returns:
        Never: the process exits."""
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
