"""Peak resident memory of the default commands against the mesh size.

    .venv/bin/python benchmarks/bench_memory.py [--meshes spot bunny igea] [--commands denoise stats]

Each command (``jaxmesh denoise IN OUT``, the blind default; ``jaxmesh stats IN``) runs on
each shared mesh in a fresh process, started by a fresh wrapper process whose
``RUSAGE_CHILDREN`` peak is then that one command's.  Reported: vertices, the command's
wall time and its peak RSS.  ``--no-cache``: every program compiled (a cold start; the
compiles add to the peak).
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SHARED = ROOT.parent / "shared" / "meshes"
WRAPPER = ("import resource, subprocess, sys; subprocess.run(sys.argv[1:], check=True, stdout=subprocess.DEVNULL, "
           "stderr=subprocess.DEVNULL); print(resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss)")


def peak(argv: list[str]) -> tuple[float, float]:
    """(seconds, peak RSS in MB) of one command."""
    start = time.perf_counter()
    out = subprocess.run([sys.executable, "-c", WRAPPER, *argv], check=True, capture_output=True, text=True)
    return time.perf_counter() - start, int(out.stdout.split()[-1]) / 1024


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--meshes", nargs="*", default=["spot", "bunny", "igea"])
    ap.add_argument("--commands", nargs="*", default=["denoise", "stats"], choices=["denoise", "stats"])
    ap.add_argument("--no-cache", action="store_true", help="run the commands without the compilation cache "
                    "(every program compiled: the cold start)")
    args = ap.parse_args()
    exe = [str(Path(sys.executable).parent / "jaxmesh")] + (["--no-cache"] if args.no_cache else [])
    print("| mesh | vertices | command | seconds | peak RSS |")
    print("|---|---|---|---|---|")
    for name in args.meshes:
        path = SHARED / f"{name}.ply"
        if not path.is_file():
            raise SystemExit(f"{path} not found: this benchmark needs ../shared/meshes beside the repo")
        import jaxmesh

        vertices = jaxmesh.load(path).num_vertices
        for command in args.commands:
            with tempfile.TemporaryDirectory() as tmp:
                argv = exe + (["denoise", str(path), f"{tmp}/out.ply"] if command == "denoise"
                              else ["stats", str(path)])
                seconds, mb = peak(argv)
            print(f"| {name} | {vertices} | {command} | {seconds:.1f} | {mb / 1024:.2f} GB |", flush=True)


if __name__ == "__main__":
    main()
