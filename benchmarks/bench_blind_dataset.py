"""The default, blind ``jaxmesh denoise --out-dir`` on the dataset benchmark's
meshes against the same command with ``--method taubin``, in one run.

    .venv/bin/python benchmarks/bench_blind_dataset.py [--count 200] [--first N] [--data DIR]

The dataset is ``benchmarks/bench_dataset.py``'s (``--count`` distinct noisy
meshes of 1k–60k vertices made from ../shared/meshes, kept in ``--data``);
``--first N`` takes its first N meshes only (the blind search runs per mesh, so
the whole dataset takes a long time).  Each variant is one fresh ``jaxmesh``
process with its own empty compilation cache, timed from start to exit; meshes
per second and the ratio.  Not part of the test suite: compare the ratio.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_dataset import make_dataset  # noqa: E402


def run(files: list[Path], out: Path, cache: Path, extra: list[str]) -> float:
    env = {**os.environ, "JAXMESH_CACHE_DIR": str(cache)}
    start = time.perf_counter()
    done = subprocess.run([sys.executable, "-m", "jaxmesh", "denoise", *map(str, files), "--out-dir", str(out),
                           *extra], env=env, capture_output=True, text=True)
    seconds = time.perf_counter() - start
    if done.returncode:
        raise SystemExit(f"jaxmesh denoise {' '.join(extra)} failed:\n{done.stderr[-2000:]}")
    return seconds


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--count", type=int, default=200)
    ap.add_argument("--first", type=int, default=None, help="only the first N meshes of the dataset")
    ap.add_argument("--data", type=Path, default=Path(tempfile.gettempdir()) / "jaxmesh-bench-dataset")
    args = ap.parse_args()
    files = make_dataset(args.data / f"in{args.count}", args.count)[:args.first]
    print(f"# `jaxmesh denoise --out-dir` on {len(files)} meshes of the {args.count}-mesh dataset "
          f"({os.cpu_count()} CPU cores)\n")
    print("| method | seconds | meshes/s |")
    print("|---|---|---|")
    rates = {}
    with tempfile.TemporaryDirectory() as tmp:
        for name, extra in (("auto (default)", []), ("taubin", ["--method", "taubin"])):
            seconds = run(files, Path(tmp) / f"out-{len(rates)}", Path(tmp) / f"cache-{len(rates)}", extra)
            rates[name] = len(files) / seconds
            print(f"| {name} | {seconds:.1f} | {rates[name]:.3f} |", flush=True)
    print(f"\nauto / taubin: {rates['auto (default)'] / rates['taubin']:.3f}x meshes per second")


if __name__ == "__main__":
    main()
