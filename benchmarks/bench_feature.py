"""Feature-preserving filters: time per normal-filter pass against PyMeshLab's
two-step smoothing (the only packaged feature-preserving filter) in the same run.

    .venv/bin/python benchmarks/bench_feature.py [--big] [--repeat 3] [--tiers-only]

* jaxmesh ``guided_normal`` and ``bilateral_normal`` with 20 normal passes and
  20 vertex updates (the reference figure for guided filtering in the issue:
  43 s for 20 iterations at 35k vertices on 2 cores), jitted and warmed up,
  median of --repeat; per pass = (time with 20 passes − time with 0 passes) / 20;
* PyMeshLab ``apply_coord_two_steps_smoothing`` (20 normal passes and 20 vertex
  passes), if pymeshlab is installed (``pip install '.[bench]'``);
* ``l0`` (40 half-quadratic steps) on spot and the bunny, its p-steps by sparse Cholesky
  factorizations (the default) and by CG, with the largest difference between the two;
* guided filtering's patch inconsistency on the rings split into width tiers (the face
  graph's ``tiers``, what the filter runs) against every ring padded to the widest (one
  tier), on spot (the size the blind chooser ranks on), the bunny and a simplified bunny
  (``fast_simplification``, irregular valences: the widest ring is about three times the
  mean), per call.

--big adds the bunny subdivided twice (~556k vertices).  float64, CPU.
Numbers depend on the machine; compare the ratios.
"""

from __future__ import annotations

import argparse

import jax

jax.config.update("jax_enable_x64", True)

import numpy as np  # noqa: E402
import trimesh  # noqa: E402

import jaxmesh  # noqa: E402
from jaxmesh.denoise import METHODS  # noqa: E402
from bench_denoise import median_time  # noqa: E402  (same folder)


def jaxmesh_time(name: str, noisy, repeat: int, **params) -> float:
    m = METHODS[name]
    aux = m.prepare(noisy)
    run = jax.jit(lambda mesh, aux: m(mesh, **params, **aux).vertices)
    run(noisy, aux).block_until_ready()
    return median_time(lambda: run(noisy, aux).block_until_ready(), repeat)


def tier_times(noisy, repeat: int) -> tuple[float, float, int, int]:
    """Seconds per patch-inconsistency call with the graph's tiers and with one tier of the widest
    ring, the widest ring and the number of tiers."""
    from jaxmesh.denoise import RingTier, face_graph, patch_inconsistency
    from jaxmesh.geometry import face_normals

    graph = face_graph(noisy)
    one = graph._replace(tiers=(RingTier(jax.numpy.arange(noisy.num_faces, dtype=jax.numpy.int32), graph.ring,
                                         graph.ring_mask),),
                         tier_order=jax.numpy.arange(noisy.num_faces, dtype=jax.numpy.int32))
    normals = face_normals(noisy)
    run = jax.jit(patch_inconsistency)
    out = [run(g, normals).block_until_ready() for g in (graph, one)]
    assert bool((out[0] == out[1]).all()), "the tiers changed the result"
    tiered, padded = (median_time(lambda g=g: run(g, normals).block_until_ready(), repeat) for g in (graph, one))
    return tiered, padded, graph.ring.shape[1], len(graph.tiers)


def simplified(mesh, keep: float = 0.5):
    """The mesh simplified by quadric decimation to ``keep`` of its faces (irregular valences)."""
    import fast_simplification

    v, f = fast_simplification.simplify(np.array(mesh.vertices, np.float64, order="C"),
                                        np.array(mesh.faces, np.int32, order="C"), 1.0 - keep)
    t = trimesh.Trimesh(v, f, process=True)
    t.update_faces(t.nondegenerate_faces())
    t.remove_unreferenced_vertices()
    return jaxmesh.Mesh.from_arrays(t.vertices, t.faces)


def l0_table(bunny) -> None:
    """L0 (40 steps, compiled, one warm run each) with each p-step solver, and how far apart they land."""
    print("\nl0, 40 half-quadratic steps (compiled, warm), seconds")
    print("| mesh | vertices | sparse Cholesky (default) | CG | CG / Cholesky | largest difference (unit diagonal) |")
    print("|---|---|---|---|---|---|")
    m = METHODS["l0"]
    for label, mesh in (("spot", jaxmesh.data.load_sample("spot", dtype=np.float64)), ("bunny", bunny)):
        noisy = jaxmesh.add_noise(jaxmesh.normalize(mesh), 0.2, 0, along_normals=True)
        aux = m.prepare(noisy)
        seconds, out = {}, {}
        for solver in ("cholesky", "cg"):
            run = jax.jit(lambda mesh, aux, solver=solver: m(mesh, solver=solver, **aux).vertices)
            out[solver] = np.asarray(run(noisy, aux))                       # the compile, and the output
            seconds[solver] = median_time(lambda: run(noisy, aux).block_until_ready(), 1)
        gap = float(np.max(np.abs(out["cholesky"] - out["cg"])))
        print(f"| {label} | {noisy.num_vertices} | {seconds['cholesky']:.2f} | {seconds['cg']:.2f} | "
              f"{seconds['cg'] / seconds['cholesky']:.1f}x | {gap:.1e} |")


def pymeshlab_time(noisy, repeat: int):
    try:
        import pymeshlab
    except ImportError:
        return None
    v, f = np.asarray(noisy.vertices), np.asarray(noisy.faces)

    def run():
        ms = pymeshlab.MeshSet()
        ms.add_mesh(pymeshlab.Mesh(v, f))
        ms.apply_coord_two_steps_smoothing(stepsmoothnum=1, normalthr=60, stepnormalnum=20, stepfitnum=20)
    return median_time(run, repeat)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--big", action="store_true")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--tiers-only", action="store_true", help="only the patch-inconsistency table")
    ap.add_argument("--l0-only", action="store_true", help="only the L0 table")
    args = ap.parse_args()
    bunny = jaxmesh.data.load_sample("bunny", dtype=np.float64)
    if args.l0_only:
        return l0_table(bunny)
    meshes = [] if args.tiers_only else [("bunny", bunny)]
    if args.big and not args.tiers_only:
        t = trimesh.Trimesh(np.asarray(bunny.vertices), np.asarray(bunny.faces), process=False)
        t = t.subdivide().subdivide()
        meshes.append(("bunny x16", jaxmesh.Mesh.from_arrays(t.vertices, t.faces)))
    for label, mesh in meshes:
        noisy = jaxmesh.add_noise(jaxmesh.normalize(mesh), 0.2, 0, along_normals=True)
        print(f"{label}: {noisy.num_vertices} vertices")
        times = {}
        for name in ("guided_normal", "bilateral_normal"):
            full = jaxmesh_time(name, noisy, args.repeat, normal_iterations=20, vertex_iterations=20)
            none = jaxmesh_time(name, noisy, args.repeat, normal_iterations=0, vertex_iterations=20)
            times[name] = full
            print(f"  jaxmesh {name:17s} 20 passes + 20 updates {full:7.2f} s; "
                  f"per normal pass {(full - none) / 20 * 1e3:7.1f} ms")
        peer = pymeshlab_time(noisy, args.repeat)
        if peer is None:
            print("  PyMeshLab two-step smoothing: not installed (pip install '.[bench]')")
        else:
            print(f"  PyMeshLab two-step, 20 passes + 20 updates {peer:7.2f} s; ratios jaxmesh / PyMeshLab: "
                  + ", ".join(f"{k} {v / peer:.2f}x" for k, v in times.items()))
    if not args.tiers_only:
        l0_table(bunny)
    print("\nguided filtering's patch inconsistency, ms per call (median of 5 x --repeat)")
    print("| mesh | faces | widest ring | tiers | tiered | widest ring for all | padded / tiered |")
    print("|---|---|---|---|---|---|---|")
    spot = jaxmesh.data.load_sample("spot", dtype=np.float64)
    for label, mesh in (("spot", spot), ("bunny", bunny), ("bunny, simplified to half", simplified(bunny))):
        noisy = jaxmesh.add_noise(jaxmesh.normalize(mesh), 0.2, 0, along_normals=True)
        tiered, padded, width, count = tier_times(noisy, 5 * args.repeat)
        print(f"| {label} | {noisy.num_faces} | {width} | {count} | {tiered * 1e3:.1f} | {padded * 1e3:.1f} | "
              f"{padded / tiered:.2f}x |")


if __name__ == "__main__":
    main()
