"""Reliability figures, measured on this machine:

* peak RSS of ``jaxmesh stats`` and ``jaxmesh denoise --method kernel --lam auto``
  on a mesh (default: the shared igea, 134k vertices);
* peak RSS of ``jaxmesh decompress`` on files whose header or sections claim
  2^31 elements (built from a small valid file);
* how long ``jaxmesh denoise --iterations 100000`` takes to exit after SIGINT.

Each command runs in a fresh process; peak RSS is that process's ``ru_maxrss``.
Run: ``.venv/bin/python benchmarks/bench_reliability.py [--mesh PATH] [--skip-big]``.
"""

from __future__ import annotations

import argparse
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
# a shell's background jobs ignore SIGINT and children inherit that: reset it, then exec
# (a preexec_fn would fork a multithreaded JAX process)
WITH_SIGINT = [sys.executable, "-c", "import os, signal, sys; signal.signal(signal.SIGINT, signal.SIG_DFL); "
               "os.execv(sys.executable, [sys.executable, *sys.argv[1:]])"]
PROBE = ("import resource, subprocess, sys\n"
         "p = subprocess.run(sys.argv[1:], capture_output=True)\n"
         "print(p.returncode, resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss)\n")


def peak(argv) -> tuple[int, float, float]:
    """(exit status, peak RSS in MB, wall seconds) of one command in a fresh process."""
    start = time.perf_counter()
    out = subprocess.run([sys.executable, "-c", PROBE, *argv], capture_output=True, text=True, check=True)
    code, kb = out.stdout.split()
    return int(code), int(kb) / 1024, time.perf_counter() - start


def interrupt_latency(tmp: Path) -> float:
    argv = [sys.executable, "-m", "jaxmesh.cli", "denoise", "--sample", "bunny", str(tmp / "ci.ply"),
            "--method", "kernel"]
    start = time.perf_counter()
    subprocess.run(argv + ["--iterations", "3"], capture_output=True, check=True)
    startup = time.perf_counter() - start
    (tmp / "ci.ply").unlink()
    proc = subprocess.Popen(WITH_SIGINT + argv[1:] + ["--iterations", "100000"], stderr=subprocess.PIPE)
    time.sleep(2 * startup + 2)
    start = time.perf_counter()
    proc.send_signal(signal.SIGINT)
    proc.communicate(timeout=60)
    return time.perf_counter() - start


def claims(tmp: Path) -> list[tuple[str, int, float]]:
    sys.path.insert(0, str(HERE.parent / "tests" / "fuzz"))
    import jxm  # the fuzz suite's file surgery

    import jaxmesh
    from jaxmesh.compress import compress

    v, f = jxm._sphere()
    data = compress(jaxmesh.Mesh.from_arrays(v, f), keep=0.5, bits=10).data
    fields, secs = jxm._sections(data)
    out = []
    for name, field, word in [("header vertices", 3, None), ("header faces", 4, None), ("header patches", 5, None),
                              ("connectivity vertices", None, 8), ("connectivity faces", None, 12)]:
        fl, sc = list(fields), [bytearray(s) for s in secs]
        if field is not None:
            fl[field] = 2**31
        else:
            sc[0][word:word + 4] = (2**31).to_bytes(4, "little")
        p = tmp / f"{name.replace(' ', '_')}.jxm"
        p.write_bytes(jxm._pack(fl, sc))
        code, mb, _ = peak([sys.executable, "-m", "jaxmesh.cli", "decompress", str(p), str(tmp / "o.ply")])
        out.append((name, code, mb))
    return out


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--mesh", default=str(HERE.parent.parent / "shared" / "meshes" / "igea.ply"))
    ap.add_argument("--skip-big", action="store_true", help="skip the stats / --lam auto runs")
    a = ap.parse_args()
    with tempfile.TemporaryDirectory() as d:
        tmp = Path(d)
        for name, code, mb in claims(tmp):
            print(f"decompress, {name} = 2^31: exit {code}, peak RSS {mb:.0f} MB")
        print(f"Ctrl-C on denoise --iterations 100000: exited {interrupt_latency(tmp):.2f} s after SIGINT")
        if not a.skip_big:
            jm = [sys.executable, "-m", "jaxmesh.cli"]
            for label, argv in [("stats", jm + ["stats", a.mesh]),
                                ("denoise --lam auto", jm + ["denoise", a.mesh, str(tmp / "d.ply"), "--method",
                                                             "kernel", "--lam", "auto"])]:
                code, mb, sec = peak(argv)
                print(f"{label} on {Path(a.mesh).name}: exit {code}, peak RSS {mb / 1024:.2f} GB, {sec:.0f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
