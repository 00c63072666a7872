"""Degree / clustering statistics and geodesic distributions against named peers.

    .venv/bin/python benchmarks/bench_stats.py [--no-networkx] [--memory] [--spectra]

* clustering + average neighbour degree + degree assortativity on the bunny
  subdivided twice (~556k vertices), graph already built, against
  python-igraph (C core) and networkx, in the same run (jaxmesh warm; its
  one-off XLA compile is reported separately); and clustering + assortativity
  alone against networkit (OpenMP, all cores; a ``[bench]`` extra), best of five;
* geodesic distance distributions from 200 seeded sources on the bunny: edge
  graph, kNN graph and heat method, and potpourri3d's heat method as a peer;
* ``--memory``: only the peak resident memory and wall time of the command
  ``jaxmesh stats igea.ply --json`` (134k vertices, 200 sources; needs
  ../shared/meshes), in a child process, against the size of one (S, V) float64
  distance array, which it no longer holds;
* ``--spectra``: only the kernel-polynomial spectra (both Laplacians, 256 moments, 16
  probes) of fandisk and the bunny, warm, best of three: ``spectral_density`` (the
  products through a padded row table) against the same recurrence with the products as
  segment sums over every entry (jitted here) and against it on ``scipy.sparse``
  (numpy, the same probe count).

Not part of the test suite; numbers depend on the machine, compare ratios.
"""

from __future__ import annotations

import argparse
import resource
import subprocess
import sys
import time
from pathlib import Path

import jax
import numpy as np
import trimesh

jax.config.update("jax_enable_x64", True)   # as `jaxmesh stats` runs: the heat flow underflows in float32 on the bunny

import jaxmesh  # noqa: E402
from jaxmesh import stats  # noqa: E402


def timed(fn, repeat=3):
    best = np.inf
    for _ in range(repeat):
        t = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - t)
    return best, out


def networkit_peer(big: jaxmesh.Mesh) -> None:
    """Clustering + degree assortativity, jaxmesh against networkit."""
    try:
        import networkit as nk
    except ImportError:
        print("  networkit not installed (pip install '.[bench]'): no peer timing")
        return
    e = np.asarray(big.edges)
    g = nk.GraphFromCoo((np.ones(len(e)), (e[:, 0].astype(np.uint64), e[:, 1].astype(np.uint64))),
                        n=big.num_vertices, directed=False)

    def theirs():
        lcc = nk.centrality.LocalClusteringCoefficient(g, turbo=True)
        lcc.run()
        deg = nk.centrality.DegreeCentrality(g)
        deg.run()
        nk.correlation.Assortativity(g, deg.scores()).run()
        return np.array(lcc.scores())

    ours = lambda: (stats.clustering(big), stats.degree_assortativity(big))  # noqa: E731
    ours()
    t_ours, (c, _) = timed(ours, 5)
    t_nk, c_nk = timed(theirs, 5)
    assert np.allclose(c, c_nk)
    print(f"  clustering + assortativity: jaxmesh {t_ours:.3f} s, networkit {t_nk:.3f} s "
          f"({nk.getMaxNumberOfThreads()} threads) -> networkit / jaxmesh = {t_nk / t_ours:.2f}x")


def cli_memory() -> None:
    """Peak RSS of ``jaxmesh stats`` on igea, in a child process of its own."""
    path = Path(__file__).resolve().parents[2] / "shared" / "meshes" / "igea.ply"
    if not path.exists():
        raise SystemExit(f"{path} is missing (../shared/meshes)")
    exe = Path(sys.executable).with_name("jaxmesh")
    t = time.perf_counter()
    r = subprocess.run([str(exe), "stats", str(path), "--json"], capture_output=True, text=True)
    wall = time.perf_counter() - t
    if r.returncode:
        raise SystemExit(r.stderr)
    peak = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1e6       # kB -> GB
    v = jaxmesh.load(path).num_vertices
    print(f"jaxmesh stats igea.ply (V={v}, 200 sources): peak RSS {peak:.2f} GB, {wall:.1f} s wall; "
          f"one (200, V) float64 distance array is {200 * v * 8 / 1e9:.2f} GB")


def _bounds(mat) -> tuple[float, float]:
    from jaxmesh.stats.density import MARGIN, largest_eigenvalue

    top = largest_eigenvalue(mat, np.inf)
    return -MARGIN * top, top * (1 + MARGIN)


def _table_moments(mat, seed: int = 0, count: int = 256, probes: int = 16):
    """``spectral_density``'s own moments program (the padded row table), alone."""
    from jaxmesh.stats.density import _moments, _row_table, _seed_array

    a, b = _bounds(mat)
    (columns, values), rest = _row_table(mat)
    table, rest = (jax.device_put(columns), jax.device_put(values)), tuple(jax.device_put(x) for x in rest)
    return lambda: jax.block_until_ready(_moments(table, rest, (a + b) / 2, (b - a) / 2, _seed_array(seed),
                                                  n=mat.shape[0], count=count, probes=probes))


def _segment_moments(mat, seed: int = 0, count: int = 256, probes: int = 16):
    """The same moments with Ã x as segment sums over every entry (the formulation before the table)."""
    a, b = _bounds(mat)
    coo, n = mat.tocoo(), mat.shape[0]
    rows, cols, vals = (jax.device_put(np.asarray(x)) for x in (coo.row.astype(np.int32),
                                                               coo.col.astype(np.int32), coo.data))

    @jax.jit
    def moments(rows, cols, vals, centre, half):
        def apply(x):
            return (jax.ops.segment_sum(vals[:, None] * x[cols], rows, num_segments=n) - centre * x) / half
        z = jax.random.rademacher(jax.random.key(seed), (n, probes), vals.dtype)
        t1 = apply(z)

        def step(carry, _):
            prev, cur = carry
            nxt = 2 * apply(cur) - prev
            return (cur, nxt), (jax.numpy.sum(cur * cur), jax.numpy.sum(nxt * cur))
        return jax.lax.scan(step, (z, t1), None, length=count // 2 - 1)[1]
    return lambda: jax.block_until_ready(moments(rows, cols, vals, (a + b) / 2, (b - a) / 2))


def _scipy_moments(mat, count: int = 256, probes: int = 16):
    """The same recurrence on ``scipy.sparse`` (numpy probes)."""
    a, b = _bounds(mat)
    centre, half = (a + b) / 2, (b - a) / 2
    z = np.random.default_rng(0).choice([-1.0, 1.0], size=(mat.shape[0], probes))

    def run():
        prev, cur, out = z, (mat @ z - centre * z) / half, []
        for _ in range(count // 2 - 1):
            prev, cur = cur, 2 * (mat @ cur - centre * cur) / half - prev
            out.append((np.sum(prev * prev), np.sum(cur * prev)))
        return out
    return run


def spectra() -> None:
    """Both kernel-polynomial spectra of fandisk and the bunny, three ways (module docstring)."""
    from jaxmesh.stats.density import laplacian_of_kind

    shared = Path(__file__).resolve().parents[2] / "shared" / "meshes"
    meshes = {"fandisk": shared / "fandisk.ply", "bunny": None}
    for name, path in meshes.items():
        if path is not None and not path.exists():
            print(f"{name}: {path} is missing (../shared/meshes), skipped")
            continue
        mesh = jaxmesh.data.load_sample("bunny", dtype="float64") if path is None else jaxmesh.load(path)
        mats = [laplacian_of_kind(mesh, kind)[0] for kind in ("combinatorial", "normalized")]
        t_all, _ = timed(lambda: [stats.spectral_density(mesh, kind) for kind in ("combinatorial", "normalized")])
        ways = {"row table": [_table_moments(m) for m in mats], "segment sums": [_segment_moments(m) for m in mats],
                "scipy.sparse": [_scipy_moments(m) for m in mats]}
        times = {}
        for way, runs in ways.items():
            [f() for f in runs]                  # compiled before the clock
            times[way] = timed(lambda runs=runs: [f() for f in runs])[0]
        print(f"{name} (V={mesh.num_vertices}), the moments of both spectra: "
              + "; ".join(f"{way} {t:.3f} s ({t / times['row table']:.2f}x)" for way, t in times.items())
              + f"; spectral_density whole (λ_max, moments, density) {t_all:.3f} s")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--no-networkx", action="store_true", help="skip networkx (about half a minute)")
    ap.add_argument("--memory", action="store_true", help="only the peak memory of `jaxmesh stats` on igea")
    ap.add_argument("--spectra", action="store_true", help="only the kernel-polynomial spectra, three ways")
    args = ap.parse_args()
    if args.memory:
        return cli_memory()
    if args.spectra:
        return spectra()
    bunny = jaxmesh.data.load_sample("bunny", dtype="float64")
    v, f = np.asarray(bunny.vertices, np.float64), np.asarray(bunny.faces)
    for _ in range(2):
        v, f = trimesh.remesh.subdivide(v, f)
    big = jaxmesh.Mesh.from_arrays(v, f)
    print(f"bunny subdivided twice: V={big.num_vertices}, E={big.num_edges}")

    def ours():
        return (stats.clustering(big), stats.neighbor_connectivity(big), stats.degree_assortativity(big))

    t0 = time.perf_counter()
    ours()
    first = time.perf_counter() - t0
    t_ours, (c, knn, r) = timed(ours)
    print(f"  jaxmesh   {t_ours:7.3f} s   (first call {first:.2f} s incl. compile)")
    import igraph as ig

    g = ig.Graph(n=big.num_vertices, edges=np.asarray(big.edges).tolist())

    def igraph_stats():
        return (np.array(g.transitivity_local_undirected(mode="zero")), np.array(g.knn()[0]),
                g.assortativity_degree(directed=False))

    t_ig, (ci, ki, ri) = timed(igraph_stats)
    assert np.allclose(ci, c) and np.allclose(ki, knn) and np.isclose(ri, r)
    print(f"  igraph    {t_ig:7.3f} s   -> jaxmesh is {t_ig / t_ours:.2f}x faster")
    networkit_peer(big)
    if not args.no_networkx:
        import networkx as nx

        gx = nx.Graph()
        gx.add_nodes_from(range(big.num_vertices))
        gx.add_edges_from(np.asarray(big.edges).tolist())
        t = time.perf_counter()
        nx.clustering(gx)
        nx.average_neighbor_degree(gx)
        nx.degree_assortativity_coefficient(gx)
        t_nx = time.perf_counter() - t
        print(f"  networkx  {t_nx:7.3f} s   -> jaxmesh is {t_nx / t_ours:.0f}x faster")

    src = stats.sample_sources(bunny, 200, seed=0)
    print(f"\ngeodesics on the bunny (V={bunny.num_vertices}), 200 sources:")
    for name, fn in (("edge graph", lambda: stats.graph_distances(bunny, src)),
                     ("kNN graph", lambda: stats.graph_distances(bunny, src, "knn")),
                     ("heat method", lambda: stats.heat_geodesics(bunny, src))):
        t, _ = timed(fn, 1)
        print(f"  {name:12s} {t:6.2f} s")
    try:
        import potpourri3d as pp3d

        solver = pp3d.MeshHeatMethodDistanceSolver(np.asarray(bunny.vertices, np.float64), np.asarray(bunny.faces))
        t, _ = timed(lambda: [solver.compute_distance(int(s)) for s in src], 1)
        print(f"  potpourri3d heat (peer) {t:6.2f} s")
    except ImportError:
        print("  potpourri3d not installed: no peer timing")


if __name__ == "__main__":
    main()
