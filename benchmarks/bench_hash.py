"""Hashing time on the shared meshes, against trimesh's shape identifier in the same run.

    .venv/bin/python benchmarks/bench_hash.py [--meshes bunny igea] [--repeat 3]

For each mesh: median wall time of ``jaxmesh.hashing.mesh_hash`` (the thesis's hash:
8 METIS parts, r = 16), of ``jaxmesh.hashing.robust_hash``, and of the peer
``trimesh.comparison.identifier_simple`` (trimesh's rotation-invariant shape
identifier, the nearest thing a peer library ships), with the ratio
peer / jaxmesh (> 1: jaxmesh is faster).  The thesis hash is also split into
its phases (METIS, MSTs, eigenvalues).  Needs ../shared/meshes.  Not part of the
test suite.
"""

from __future__ import annotations

import argparse
import statistics
import time
import warnings
from pathlib import Path

import jax

jax.config.update("jax_enable_x64", True)

import numpy as np  # noqa: E402
import trimesh  # noqa: E402
import trimesh.comparison  # noqa: E402

import jaxmesh  # noqa: E402
from jaxmesh.hashing import (euclidean_mst_length, laplace_beltrami_eigenvalues, mesh_hash,  # noqa: E402
                          metis_partition, robust_hash, submesh)

SHARED = Path(__file__).resolve().parents[2] / "shared" / "meshes"


def median_time(fn, repeat: int) -> float:
    times = []
    for _ in range(repeat):
        t = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t)
    return statistics.median(times)


def phases(mesh) -> dict[str, float]:
    v, f = np.asarray(mesh.vertices), np.asarray(mesh.faces)
    t = time.perf_counter()
    labels = metis_partition(mesh, 8)
    out = {"metis": time.perf_counter() - t}
    t = time.perf_counter()
    for k in range(8):
        euclidean_mst_length(v[labels == k])
    out["mst"] = time.perf_counter() - t
    t = time.perf_counter()
    for k in range(8):
        laplace_beltrami_eigenvalues(*submesh(v, f, labels == k)[:2], 16)
    out["eigen"] = time.perf_counter() - t
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--meshes", nargs="+", default=["cow", "bunny", "armadillo", "igea"])
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()
    print("| mesh | vertices | thesis hash s | robust hash s | trimesh identifier s | "
          "trimesh/thesis | trimesh/robust | thesis phases s (METIS / MST / eigen) |")
    print("|---|---|---|---|---|---|---|---|")
    for name in args.meshes:
        path = SHARED / f"{name}.ply"
        if not path.is_file():
            raise SystemExit(f"{path} not found: needs ../shared/meshes beside the repo")
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", jaxmesh.MeshWarning)
            mesh = jaxmesh.load(path, dtype=np.float64)
        tm = trimesh.Trimesh(np.asarray(mesh.vertices), np.asarray(mesh.faces), process=False)
        t_thesis = median_time(lambda: mesh_hash(mesh), args.repeat)
        t_robust = median_time(lambda: robust_hash(mesh), args.repeat)
        t_peer = median_time(lambda: trimesh.comparison.identifier_simple(tm.copy()), args.repeat)
        ph = phases(mesh)
        print(f"| {name} | {mesh.num_vertices} | {t_thesis:.2f} | {t_robust:.2f} | {t_peer:.2f} | "
              f"{t_peer / t_thesis:.2f} | {t_peer / t_robust:.2f} | "
              f"{ph['metis']:.2f} / {ph['mst']:.2f} / {ph['eigen']:.2f} |", flush=True)


if __name__ == "__main__":
    main()
