"""Running one command: a worker thread the main thread waits on (so Ctrl-C is
seen at once), and the mapping of every expected failure to one error line."""

from __future__ import annotations

import os
import signal
import sys
import threading

__all__ = ["run_command"]


class _Terminated(KeyboardInterrupt):
    """SIGTERM, raised in the main thread like Ctrl-C's KeyboardInterrupt."""


def _raise_terminated(signum, frame):
    raise _Terminated()


def _in_worker(run, args):
    """``run(args)`` in a worker thread.  The main thread would otherwise be blocked
    in C++ while XLA compiles or runs, and Python would see SIGINT only when that
    call returns.  On Ctrl-C (or SIGTERM) the temporary files being written are
    removed and the process exits with 130 (143) without waiting for the worker;
    the files already written stay."""
    box: dict = {}

    def work():
        try:
            box["value"] = run(args)
        except BaseException as err:  # re-raised in the main thread
            box["error"] = err

    thread = threading.Thread(target=work, name="jaxmesh-command", daemon=True)
    main = threading.current_thread() is threading.main_thread()
    previous = signal.signal(signal.SIGTERM, _raise_terminated) if main else None
    thread.start()
    try:
        while thread.is_alive():
            thread.join(0.1)
    except KeyboardInterrupt as err:
        io = sys.modules.get("jaxmesh.io")     # the files being written, if any module writes
        for tmp in list(io.IN_PROGRESS if io else ()):
            try:
                os.unlink(tmp)
            except OSError:
                pass
        what = "terminated" if isinstance(err, _Terminated) else "interrupted"
        print(f"jaxmesh: {what}; no partly written file is left", file=sys.stderr)
        sys.stderr.flush()
        sys.stdout.flush()
        os._exit(143 if isinstance(err, _Terminated) else 130)
    finally:
        if main and previous is not None:
            signal.signal(signal.SIGTERM, previous)
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
