"""jaxmesh.linalg and what uses it, against named peers in the same run.

    .venv/bin/python benchmarks/bench_linalg.py [--big]

* the differentiable solve (``jaxmesh.linalg.mesh_solve`` under ``jit``, a fresh matrix
  each call, so factorization included) against cholespy's factor + solve alone and
  SciPy's SuperLU, on M + tL of the bunny (3 right-hand sides); and the backward pass's
  cost, counted in factorizations and solves;
* heat-method geodesics from 200 seeded sources on the bunny (intrinsic Delaunay
  triangulation and the mesh's own triangles) against potpourri3d's heat method
  (setup included, and without it);
* the implicit cotangent flow (3 steps) with the direct solve against CG, on the bunny
  and, with ``--big``, the bunny subdivided twice (~556k vertices), with the distance
  between the two results.

Not part of the test suite; numbers depend on the machine, compare ratios.
"""

from __future__ import annotations

import argparse
import time

import jax

jax.config.update("jax_enable_x64", True)

import jax.numpy as jnp  # noqa: E402
import numpy as np  # noqa: E402
import scipy.sparse as sp  # noqa: E402
import scipy.sparse.linalg as spla  # noqa: E402
import trimesh  # noqa: E402

import jaxmesh  # noqa: E402
from jaxmesh import linalg, stats  # noqa: E402
from jaxmesh.denoise import METHODS  # noqa: E402
from jaxmesh.geodesics import heat_distances  # noqa: E402


def best_of(fn, repeat=3, before=None):
    best = np.inf
    for _ in range(repeat):
        if before is not None:
            before()
        t = time.perf_counter()
        out = fn()
        jax.block_until_ready(out)
        best = min(best, time.perf_counter() - t)
    return best, out


def heat_system(mesh, scale=1.0):
    """M + tL on the mesh's pattern (t = ℓ̄², cotangent weights clamped at 0)."""
    area = jaxmesh.geometry.face_areas(mesh)
    mass = jnp.zeros(mesh.num_vertices).at[mesh.faces.reshape(-1)].add(jnp.repeat(area / 3, 3))
    c = jnp.maximum(0.5 * jaxmesh.operators.cotangent_weights(mesh), 0)
    t = jaxmesh.mean_edge_length(mesh) ** 2 * scale
    e = mesh.edges
    rows = jnp.zeros(mesh.num_vertices).at[e[:, 0]].add(c).at[e[:, 1]].add(c)
    return mass + t * rows, -t * c


def solve_section(bunny):
    print(f"solve: M + tL on the bunny (V={bunny.num_vertices}), 3 right-hand sides, a new matrix each call")
    d, a = heat_system(bunny)
    b = jnp.asarray(np.random.default_rng(0).standard_normal((bunny.num_vertices, 3)))
    solve = jax.jit(lambda d, a, b: linalg.mesh_solve(bunny, d, a, b))
    solve(d, a, b).block_until_ready()
    scales = iter(np.linspace(1.5, 2.0, 100))        # never the compile call's matrix; the cache emptied too
    t_ours, _ = best_of(lambda: solve(d * next(scales), a, b), 5, before=linalg.clear_factor_cache)
    e = np.asarray(bunny.edges)
    n = bunny.num_vertices
    rows = np.concatenate([np.arange(n), e[:, 0], e[:, 1]]).astype(np.int32)
    cols = np.concatenate([np.arange(n), e[:, 1], e[:, 0]]).astype(np.int32)
    dn, an, bn = np.array(d), np.array(a), np.array(b)     # writable copies (cholespy refuses read-only)
    import cholespy

    def chol():
        s = cholespy.CholeskySolverD(n, rows, cols, np.concatenate([dn, an, an]), cholespy.MatrixType.COO)
        x = np.zeros_like(bn)
        s.solve(np.ascontiguousarray(bn), x)
        return x

    t_chol, _ = best_of(chol, 5)
    mat = sp.csc_matrix((np.concatenate([dn, an, an]), (rows, cols)), shape=(n, n))
    t_lu, _ = best_of(lambda: spla.splu(mat).solve(bn), 3)
    print(f"  jaxmesh mesh_solve (jit)        {t_ours * 1e3:7.1f} ms")
    print(f"  cholespy factor + solve alone   {t_chol * 1e3:7.1f} ms   -> jaxmesh / cholespy = {t_ours / t_chol:.2f}")
    print(f"  SciPy SuperLU factor + solve    {t_lu * 1e3:7.1f} ms")
    grad = jax.jit(jax.grad(lambda d, a, b: jnp.sum(linalg.mesh_solve(bunny, d, a, b) ** 2), argnums=(0, 1, 2)))
    jax.block_until_ready(grad(d * 3.0, a, b))
    linalg.clear_factor_cache()
    t_grad, _ = best_of(lambda: grad(d * 3.5, a, b), 1)
    counts = linalg.clear_factor_cache()
    print(f"  value and gradient (jit)        {t_grad * 1e3:7.1f} ms   ({counts['factorizations']} factorization, "
          f"{counts['solves']} solves: the backward pass is one more solve with the same factor)")


def heat_section(bunny):
    src = stats.sample_sources(bunny, 200, seed=0)
    print(f"\nheat geodesics from 200 sources on the bunny (V={bunny.num_vertices}), setup included "
          "(jaxmesh: flips, factorizations; its first call also compiles):")
    moved = bunny.with_vertices(bunny.vertices * 1.001)       # new positions: new flips and factors, same program
    times = {}
    for label, kw in (("intrinsic Delaunay", {}), ("own triangles", {"intrinsic": False, "boundary": "neumann"})):
        first, _ = best_of(lambda: heat_distances(bunny, src, **kw), 1, before=linalg.clear_factor_cache)
        again, _ = best_of(lambda: heat_distances(moved, src, **kw), 1, before=linalg.clear_factor_cache)
        times[label] = again
        print(f"  jaxmesh, {label:20s} {again:6.2f} s   (first call, compile included: {first:.2f} s)")
    t_int, t_own = times["intrinsic Delaunay"], times["own triangles"]
    try:
        import potpourri3d as pp3d
    except ImportError:
        print("  potpourri3d not installed: no peer timing")
        return
    v, f = np.asarray(bunny.vertices, np.float64), np.asarray(bunny.faces)
    for robust in (True, False):
        t0 = time.perf_counter()
        solver = pp3d.MeshHeatMethodDistanceSolver(v, f, use_robust=robust)
        setup = time.perf_counter() - t0
        t, _ = best_of(lambda: [solver.compute_distance(int(s)) for s in src], 1)
        label = "robust (intrinsic)" if robust else "plain"
        print(f"  potpourri3d {label:18s} {setup + t:6.2f} s  ({t:.2f} s without its setup)   "
              f"-> jaxmesh {'intrinsic' if robust else 'own'} / potpourri3d = "
              f"{(t_int if robust else t_own) / (setup + t):.2f}")


def flow_section(mesh, label):
    print(f"\nimplicit cotangent flow, 3 steps, dt = 0.3, on {label} (V={mesh.num_vertices}):")
    out = {}
    for solver in ("cg", "cholesky"):
        f = jax.jit(lambda v: METHODS["cotangent_implicit"](mesh.with_vertices(v), solver=solver).vertices)
        f(mesh.vertices).block_until_ready()
        t, out[solver] = best_of(lambda: f(mesh.vertices), 2, before=linalg.clear_factor_cache)
        print(f"  {solver:9s} {t:7.2f} s")
    diag = float(jaxmesh.bounding_box_diagonal(mesh))
    gap = float(jnp.max(jnp.linalg.norm(out["cg"] - out["cholesky"], axis=-1))) / diag
    print(f"  largest distance between the two results: {gap:.1e} of the diagonal (CG's tolerance)")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--big", action="store_true", help="also the flow on the bunny subdivided twice (minutes)")
    args = ap.parse_args()
    bunny = jaxmesh.data.load_sample("bunny", dtype=np.float64)
    solve_section(bunny)
    heat_section(bunny)
    noisy = jaxmesh.add_noise(bunny, 0.3, 1)
    flow_section(noisy, "the noisy bunny (0.3 ℓ̄)")
    if args.big:
        v, f = np.asarray(noisy.vertices), np.asarray(noisy.faces)
        for _ in range(2):
            v, f = trimesh.remesh.subdivide(v, f)
        flow_section(jaxmesh.Mesh.from_arrays(v, f, warn=False), "the noisy bunny subdivided twice")


if __name__ == "__main__":
    main()
