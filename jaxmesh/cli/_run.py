"""Running one command: a worker thread the main thread waits on (so Ctrl-C is
seen at once), and the mapping of every expected failure to one error line."""

from __future__ import annotations

import os
import sys
import threading

__all__ = ["run_command"]


def _in_worker(run, args):
    """``run(args)`` in a worker thread.  The main thread would otherwise be blocked
    in C++ while XLA compiles or runs, and Python would see SIGINT only when that
    call returns.  On Ctrl-C the temporary files being written are removed and the
    process exits with 130 without waiting for the worker."""
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
        io = sys.modules.get("jaxmesh.io")     # the files being written, if any module writes
        for tmp in list(io.IN_PROGRESS if io else ()):
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


def _os_error(err: OSError) -> str:
    reason = err.strerror or type(err).__name__
    return f"{err.filename}: {reason}" if err.filename is not None else reason


def run_command(run, args) -> int:
    """Exit status of ``run(args)``: 0, or 1 with one ``jaxmesh: error:`` line."""
    try:
        return int(_in_worker(run, args) or 0)
    except (ValueError, FileExistsError, FloatingPointError) as err:  # CLIError, MeshFileError, CodecError too
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
