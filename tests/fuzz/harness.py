"""A small fuzzing harness: cases run in a worker process under a memory and time limit.

A *suite* is a module in this folder with ``setup() -> state`` and
``case(state, i) -> (label, outcome)``, where the outcome is one of

* ``"valid"``: a result equal to what the input describes;
* ``"error"``: the documented error type, with a message naming the problem;
* ``"traceback"``: any other exception (a user would see a traceback);
* ``"silent"``: a result that differs from what the input describes, with no error.

The parent adds the outcomes a case cannot report about itself:

* ``"hang"``: no answer within the time limit (the worker is killed);
* ``"memory"``: the case needed more than the memory budget (``MemoryError``
  under ``RLIMIT_DATA``, the budget counted from the worker's size after setup);
* ``"crash"``: the worker died (a signal, a C-level abort).

Cases are deterministic functions of their index, so a failure is reproduced by
``python tests/fuzz/harness.py SUITE --only I``.
"""

from __future__ import annotations

import argparse
import collections
import importlib
import json
import resource
import select
import signal
import subprocess
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
OUTCOMES = ("valid", "error", "forged", "traceback", "silent", "hang", "memory", "crash")
BAD = ("traceback", "silent", "hang", "memory", "crash")


class _Timeout(Exception):
    pass


def _data_bytes() -> int:
    with open("/proc/self/status") as fh:
        for line in fh:
            if line.startswith("VmData:"):
                return int(line.split()[1]) * 1024
    return 0


def _worker(suite: str, mem_mb: int, timeout_s: float) -> None:
    """Read case indices from stdin, answer one JSON line each on stdout."""
    sys.path.insert(0, str(HERE))
    mod = importlib.import_module(suite)
    state = mod.setup()
    hard = resource.getrlimit(resource.RLIMIT_DATA)[1]
    resource.setrlimit(resource.RLIMIT_DATA, (_data_bytes() + mem_mb * 2**20, hard))

    def on_alarm(signum, frame):
        raise _Timeout()

    signal.signal(signal.SIGALRM, on_alarm)
    out = sys.stdout
    sys.stdout = sys.stderr  # cases may print; keep the protocol channel clean
    for line in sys.stdin:
        i = int(line)
        t0 = time.perf_counter()
        signal.setitimer(signal.ITIMER_REAL, timeout_s)
        try:
            label, outcome = mod.case(state, i)
            detail = ""
        except _Timeout:
            label, outcome, detail = f"case {i}", "hang", "alarm"
        except MemoryError as err:
            label, outcome, detail = f"case {i}", "memory", str(err)[:200]
        finally:
            signal.setitimer(signal.ITIMER_REAL, 0)
        if isinstance(outcome, tuple):
            outcome, detail = outcome
        out.write(json.dumps({"i": i, "label": label, "outcome": outcome, "detail": str(detail)[:300],
                              "seconds": time.perf_counter() - t0}) + "\n")
        out.flush()


def run(suite: str, indices, *, mem_mb: int = 200, timeout_s: float = 20.0, grace_s: float = 30.0,
        recycle: int = 200):
    """Run the cases ``indices`` of ``suite``; returns a list of result dicts.  A worker is
    replaced after ``recycle`` cases: each compiled program stays in its address space, and
    hundreds of them reach the ``mem_mb`` limit, where XLA fails to map memory and crashes."""
    results, todo = [], list(indices)
    while todo:
        proc = subprocess.Popen(
            [sys.executable, str(Path(__file__)), suite, "--worker", "--mem-mb", str(mem_mb),
             "--timeout", str(timeout_s)],
            stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True,
        )
        first, served = True, 0
        while todo and served < recycle:
            served += 1
            i = todo[0]
            proc.stdin.write(f"{i}\n")
            proc.stdin.flush()
            # the first case also waits for the worker's imports and setup
            wait = timeout_s + grace_s + (120 if first else 0)
            ready, _, _ = select.select([proc.stdout], [], [], wait)
            line = proc.stdout.readline() if ready else ""
            todo.pop(0)
            if line:
                results.append(json.loads(line))
                first = False
                if results[-1]["outcome"] == "hang":
                    break  # the alarm may leave a thread or a C call running: start a fresh worker
                continue
            outcome = "hang" if proc.poll() is None else "crash"
            results.append({"i": i, "label": f"case {i}", "outcome": outcome,
                            "detail": f"worker exit {proc.poll()}", "seconds": wait})
            break
        try:  # let a healthy worker finish (its setup's temporary files are removed at exit)
            proc.stdin.close()
            proc.wait(timeout=10)
        except (OSError, subprocess.TimeoutExpired):
            pass
        proc.kill()
        proc.wait()
        for pipe in (proc.stdin, proc.stdout):
            try:
                pipe.close()
            except OSError:  # a dead worker's stdin
                pass
    return results


def summary(results) -> dict:
    counts = collections.Counter(r["outcome"] for r in results)
    return {k: counts.get(k, 0) for k in OUTCOMES}


def bad(results) -> list:
    return [r for r in results if r["outcome"] in BAD]


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("suite")
    ap.add_argument("--cases", type=int, default=200)
    ap.add_argument("--only", type=int, nargs="*")
    ap.add_argument("--mem-mb", type=int, default=200)
    ap.add_argument("--timeout", type=float, default=20.0)
    ap.add_argument("--worker", action="store_true", help=argparse.SUPPRESS)
    ap.add_argument("--verbose", action="store_true")
    a = ap.parse_args(argv)
    if a.worker:
        _worker(a.suite, a.mem_mb, a.timeout)
        return 0
    t0 = time.perf_counter()
    res = run(a.suite, a.only if a.only else range(a.cases), mem_mb=a.mem_mb, timeout_s=a.timeout)
    for r in res:
        if a.verbose or r["outcome"] in BAD:
            print(f"{r['i']:5d} {r['outcome']:9s} {r['seconds']:6.2f}s {r['label']}: {r['detail']}")
    print(json.dumps({"suite": a.suite, "cases": len(res), "seconds": round(time.perf_counter() - t0, 1),
                      **summary(res)}))
    return 1 if bad(res) else 0


if __name__ == "__main__":
    sys.exit(main())
