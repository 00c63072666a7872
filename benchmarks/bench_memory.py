"""Peak resident memory of the default commands against the mesh size.

    .venv/bin/python benchmarks/bench_memory.py [--meshes spot bunny igea] [--commands denoise stats] [--big]

Each command (``jaxmesh denoise IN OUT``, the blind default; ``jaxmesh stats IN``) runs on
each shared mesh in a fresh process, started by a fresh wrapper process whose
``RUSAGE_CHILDREN`` peak is then that one command's.  Reported: vertices, the command's
wall time and its peak RSS.  ``--no-cache``: every program compiled (a cold start; the
compiles add to the peak).  ``--big`` adds the shipped bunny subdivided twice (556k vertices,
as ``bench_denoise.py --big`` builds it) with Gaussian noise of 0.3 mean edge lengths (seed 0;
subdivision alone leaves a mesh too smooth for the blind default to do any work).
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


def big_mesh(folder: str) -> Path:
    """The bunny subdivided twice, noisy at 0.3ℓ̄, written as PLY into ``folder``."""
    import jaxmesh
    from bench_denoise import load_mesh

    path = Path(folder) / "bunny-x16-noisy.ply"
    jaxmesh.save(jaxmesh.add_noise(load_mesh(big=True), 0.3, 0), path)
    return path


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--meshes", nargs="*", default=["spot", "bunny", "igea"])
    ap.add_argument("--commands", nargs="*", default=["denoise", "stats"], choices=["denoise", "stats"])
    ap.add_argument("--no-cache", action="store_true", help="run the commands without the compilation cache "
                    "(every program compiled: the cold start)")
    ap.add_argument("--big", action="store_true", help="also the bunny subdivided twice, noisy (556k vertices)")
    args = ap.parse_args()
    exe = [str(Path(sys.executable).parent / "jaxmesh")] + (["--no-cache"] if args.no_cache else [])
    print("| mesh | vertices | command | seconds | peak RSS |")
    print("|---|---|---|---|---|")
    scratch = tempfile.TemporaryDirectory()
    paths = {name: SHARED / f"{name}.ply" for name in args.meshes}
    if args.big:
        paths["bunny ×16, noisy"] = big_mesh(scratch.name)
    for name, path in paths.items():
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
