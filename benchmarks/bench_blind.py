"""The default command, blind ``jaxmesh denoise IN OUT``, end to end, against one filter
and against the search on the whole mesh, in the same run.

    .venv/bin/python benchmarks/bench_blind.py [--sigma 0.2] [--big] [--skip-whole]

The shipped bunny (34,834 vertices) with Gaussian noise of σ = 0.2 mean edge
lengths (``jaxmesh noise``) is denoised by fresh ``jaxmesh`` processes, each timed
from start to exit (import, read, search, write):

* the default (``--method auto``, ranked on patches) with an empty compilation
  cache, then again with the cache that run left (warm), ``--repeat`` times (the
  median is reported, with the range);
* the same with ``--search-vertices all`` (ranked on the whole mesh), warm;
* ``--method taubin`` at its defaults, warm, run between the default's warm runs:
  one filter, the peer the default's time is compared with.

``--big`` adds the bunny subdivided once and twice (midpoints, ~139k and ~556k
vertices): the default with its own empty cache and warm, and Taubin.  Each
process's JSON summary gives what the default chose, on how many vertices it
ranked, and the seconds of its stages (``AutoResult.seconds``): the last table
puts them against V.  Not part of the test suite: numbers depend on the
machine; compare ratios.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import trimesh

import jaxmesh

JAXMESH = [sys.executable, "-m", "jaxmesh"]


def timed_run(args: list[str], cache: Path) -> tuple[float, dict]:
    """Wall seconds of one fresh ``jaxmesh`` process and its JSON summary."""
    env = {**os.environ, "JAXMESH_CACHE_DIR": str(cache)}
    t = time.perf_counter()
    done = subprocess.run(JAXMESH + args + ["--json"], env=env, capture_output=True, text=True)
    seconds = time.perf_counter() - t
    if done.returncode != 0:
        raise SystemExit(f"{' '.join(args)} failed:\n{done.stderr}")
    return seconds, json.loads(done.stdout)


def describe(summary: dict) -> str:
    auto = summary.get("auto")
    if auto is None:
        return summary.get("method", "?")
    parts = " + ".join(f"{c['weight']:.2f} {c['method']}" for c in auto["components"])
    return f"{parts} (ranked on {auto['search_vertices']} vertices)"


def bench_mesh(name: str, noisy: Path, work: Path, rows: list, stages: list, whole: bool, cold: bool,
               repeat: int) -> None:
    cache = work / f"cache-{name}"
    out = lambda tag: str(work / f"{name}-{tag}.ply")     # noqa: E731
    if cold:
        t, s = timed_run(["denoise", str(noisy), out("cold")], cache)
        rows.append((name, "default (auto), empty compilation cache", t, describe(s)))
    autos, taubins = [], []
    for _ in range(repeat):    # interleaved, so that the machine's drift moves both alike
        autos.append(timed_run(["denoise", str(noisy), out("warm"), "--force"], cache))
        taubins.append(timed_run(["denoise", str(noisy), out("taubin"), "--method", "taubin", "--force"], cache))
    (t_auto, s), spread_auto = median_run(autos)
    rows.append((name, f"default (auto), warm cache, median of {repeat}{spread_auto}", t_auto, describe(s)))
    stages.append((s["auto"]["search_vertices"], t_auto, s["auto"]["seconds"], name))
    if whole:
        t, s = timed_run(["denoise", str(noisy), out("whole"), "--search-vertices", "all"], cache)
        rows.append((name, "auto --search-vertices all, warm cache", t, describe(s)))
    (t_taubin, s), spread_taubin = median_run(taubins)
    rows.append((name, f"--method taubin (one filter), warm cache, median of {repeat}{spread_taubin}", t_taubin,
                 describe(s)))
    rows.append((name, "default / one filter (medians)", t_auto / t_taubin, ""))
    stages[-1] += (t_taubin,)


def median_run(runs: list) -> tuple:
    """The run of median time, and the runs' range as text."""
    ordered = sorted(runs, key=lambda r: r[0])
    spread = f" ({ordered[0][0]:.2f}–{ordered[-1][0]:.2f})" if len(runs) > 1 else ""
    return ordered[(len(ordered) - 1) // 2], spread


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sigma", type=float, default=0.2, help="noise, in mean edge lengths")
    ap.add_argument("--big", action="store_true", help="also the bunny subdivided twice (~556k vertices)")
    ap.add_argument("--skip-whole", action="store_true", help="leave out the whole-mesh search (the slowest row)")
    ap.add_argument("--repeat", type=int, default=3, help="warm runs of the default and of Taubin (medians)")
    args = ap.parse_args()
    rows: list = []
    stages: list = []
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        clean = work / "bunny.ply"
        jaxmesh.save(jaxmesh.data.load_sample("bunny"), clean)
        meshes = [("bunny", clean)]
        if args.big:
            m = jaxmesh.load(clean)
            big = trimesh.Trimesh(np.asarray(m.vertices), np.asarray(m.faces), process=False)
            for times in (1, 2):
                big = big.subdivide()
                path = work / f"bunny-{times}.ply"
                jaxmesh.save(jaxmesh.Mesh.from_arrays(big.vertices, big.faces, warn=False), path)
                meshes.append((f"bunny subdivided {'once' if times == 1 else 'twice'} ({len(big.vertices)} vertices)",
                               path))
        for i, (name, path) in enumerate(meshes):
            noisy = work / f"noisy-{i}.ply"
            subprocess.run(JAXMESH + ["noise", str(path), str(noisy), "--sigma", str(args.sigma)], check=True,
                           env={**os.environ, "JAXMESH_CACHE_DIR": "off"}, capture_output=True)
            bench_mesh(name, noisy, work, rows, stages, whole=i == 0 and not args.skip_whole, cold=True,
                       repeat=args.repeat)
    print(f"# blind `jaxmesh denoise` end to end (σ = {args.sigma}ℓ̄, {os.cpu_count()} CPU cores)\n")
    print("| mesh | run | seconds (ratio) | choice |")
    print("|---|---|---|---|")
    for name, what, value, choice in rows:
        print(f"| {name} | {what} | {value:.2f} | {choice} |")
    print("\n# the warm default's stages against the mesh's size (seconds; AutoResult.seconds)\n")
    print("| mesh | ranked on V | command | noise law | patches | ranking | choice | rest (start-up, I/O) "
          "| one Taubin filter |")
    print("|---|---|---|---|---|---|---|---|---|")
    for ranked, total, sec, name, taubin in stages:
        rest = total - sum(sec.values())
        print(f"| {name} | {ranked} | {total:.2f} | {sec['noise_law']:.2f} | {sec['patches']:.2f} | "
              f"{sec['ranking']:.2f} | {sec['choice']:.2f} | {rest:.2f} | {taubin:.2f} |")


if __name__ == "__main__":
    main()
