"""Guided and bilateral normal filtering at their defaults, this checkout against another,
interleaved.

    .venv/bin/python benchmarks/bench_filters_against.py DIR [--rounds 2] [--big]

``DIR`` is the root of another checkout of jaxmesh (e.g. a ``git worktree`` of an older
commit).  Each round runs one fresh process per checkout, alternating (this one, then
``DIR``), so that the machine's drift falls on both; each process times three warm calls
of each filter (jitted, float64, the face graph built once) on the shipped bunny with
Gaussian noise of 0.2 mean edge lengths, or with ``--big`` the bunny subdivided twice
(~556k vertices).  Prints every call's seconds and the ratio of the medians.  Not part
of the test suite: compare the ratios.
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

CHILD = r"""
import sys, json, time
sys.meta_path[:] = [f for f in sys.meta_path if "editable" not in repr(f).lower()]
sys.path.insert(0, sys.argv[1])
import jax
jax.config.update("jax_enable_x64", True)
from jaxmesh.compiler import prefer_fast_cpu_compiles
prefer_fast_cpu_compiles()
import numpy as np
import jaxmesh
assert jaxmesh.__file__.startswith(sys.argv[1]), jaxmesh.__file__
from jaxmesh.denoise import bilateral_normal_filtering, face_graph, guided_normal_filtering
mesh = jaxmesh.load(sys.argv[2], dtype=np.float64)
graph = face_graph(mesh)
out = {}
for name, fn in (("guided_normal", guided_normal_filtering), ("bilateral_normal", bilateral_normal_filtering)):
    f = jax.jit(lambda m, g: fn(m, graph=g).vertices)
    jax.block_until_ready(f(mesh, graph))
    out[name] = []
    for _ in range(3):
        t = time.perf_counter()
        jax.block_until_ready(f(mesh, graph))
        out[name].append(time.perf_counter() - t)
print(json.dumps(out))
"""


def noisy_mesh(folder: Path, big: bool) -> Path:
    """The bunny (subdivided twice with ``big``) with Gaussian noise of 0.2ℓ̄, written to ``folder``."""
    import numpy as np
    import trimesh

    import jaxmesh

    mesh = jaxmesh.data.load_sample("bunny")
    if big:
        t = trimesh.Trimesh(np.asarray(mesh.vertices), np.asarray(mesh.faces), process=False)
        t = t.subdivide().subdivide()
        mesh = jaxmesh.Mesh.from_arrays(t.vertices, t.faces, warn=False)
    path = folder / "noisy.ply"
    jaxmesh.save(jaxmesh.add_noise(mesh, 0.2, 0), path)
    return path


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("against", type=Path, help="root of the other checkout")
    ap.add_argument("--rounds", type=int, default=2)
    ap.add_argument("--big", action="store_true", help="the bunny subdivided twice (~556k vertices)")
    args = ap.parse_args()
    roots = [ROOT, args.against.resolve()]
    times: dict = {str(r): {"guided_normal": [], "bilateral_normal": []} for r in roots}
    with tempfile.TemporaryDirectory() as tmp:
        path = noisy_mesh(Path(tmp), args.big)
        for _ in range(args.rounds):
            for root in roots:
                run = subprocess.run([sys.executable, "-c", CHILD, str(root), str(path)], capture_output=True,
                                     text=True, check=True, cwd=tmp)
                for name, seconds in json.loads(run.stdout.strip().splitlines()[-1]).items():
                    times[str(root)][name] += seconds
    print(f"{'bunny subdivided twice' if args.big else 'bunny'}, float64, seconds per call\n")
    print(f"| filter | this checkout | {args.against} | ratio of medians |")
    print("|---|---|---|---|")
    for name in ("guided_normal", "bilateral_normal"):
        mine, other = times[str(roots[0])][name], times[str(roots[1])][name]
        cells = [", ".join(f"{t:.2f}" for t in ts) for ts in (mine, other)]
        print(f"| {name} | {cells[0]} | {cells[1]} | {statistics.median(mine) / statistics.median(other):.2f} |")


if __name__ == "__main__":
    main()
