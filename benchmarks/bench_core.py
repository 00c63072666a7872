"""Core operators on the shipped bunny, against named peers in the same run.

    .venv/bin/python benchmarks/bench_core.py [--repeat 20]

Reports median wall time per call and the ratio peer / jaxmesh (> 1: jaxmesh is
faster).  jaxmesh functions are jitted and warmed up first (compile time is
reported separately).  Peers: trimesh (face normals + areas + vertex normals,
recomputed from scratch on a fresh Trimesh each call) and scipy.sparse (umbrella
operator as a CSR mat-vec with a prebuilt matrix).  Not part of the test suite.
"""

from __future__ import annotations

import argparse
import statistics
import time

import jax
import jax.numpy as jnp
import numpy as np
import trimesh

import jaxmesh
from jaxmesh import geometry, operators, sparse


def timeit(fn, repeat: int) -> float:
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--repeat", type=int, default=20)
    args = ap.parse_args()
    mesh = jaxmesh.data.load_sample("bunny")
    v_np, f_np = np.asarray(mesh.vertices, np.float64), np.asarray(mesh.faces)
    print(f"bunny: V={mesh.num_vertices} F={mesh.num_faces}, backend={jax.default_backend()}, "
          f"dtype={mesh.dtype}")

    @jax.jit
    def normals(m):
        return geometry.face_normals(m), geometry.face_areas(m), geometry.vertex_normals(m, "angle")

    t0 = time.perf_counter()
    jax.block_until_ready(normals(mesh))
    compile_s = time.perf_counter() - t0
    t_jm = timeit(lambda: jax.block_until_ready(normals(mesh)), args.repeat)

    def tm_normals():
        tm = trimesh.Trimesh(v_np, f_np, process=False)
        return tm.face_normals, tm.area_faces, tm.vertex_normals

    t_tm = timeit(tm_normals, args.repeat)
    print(f"normals+areas+vertex normals: jaxmesh {t_jm * 1e3:.2f} ms (compile {compile_s:.2f} s), "
          f"trimesh {t_tm * 1e3:.2f} ms, ratio trimesh/jaxmesh {t_tm / t_jm:.2f}")

    umb = jax.jit(operators.umbrella)
    x = mesh.vertices
    jax.block_until_ready(umb(mesh, x))
    t_u = timeit(lambda: jax.block_until_ready(umb(mesh, x)), args.repeat)
    k = sparse.umbrella_matrix(mesh)
    x_np = np.asarray(x)
    t_s = timeit(lambda: k @ x_np, args.repeat)
    print(f"umbrella K x: jaxmesh {t_u * 1e3:.3f} ms, scipy CSR {t_s * 1e3:.3f} ms, "
          f"ratio scipy/jaxmesh {t_s / t_u:.2f}")

    batch = mesh.with_vertices(jnp.stack([x] * 16))
    jax.block_until_ready(normals(batch))
    t_b = timeit(lambda: jax.block_until_ready(normals(batch)), max(3, args.repeat // 4))
    print(f"16-mesh batch of normals: {t_b * 1e3:.1f} ms = {t_b / 16 / t_jm:.2f}x the single-mesh "
          "time per mesh")


if __name__ == "__main__":
    main()
