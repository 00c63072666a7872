"""Kernel-flow and Laplacian iteration cost against named peers in the same run.

    .venv/bin/python benchmarks/bench_denoise.py [--big] [--repeat 3]

* per-iteration time (a 10-iteration call / 10, jitted, warmed up, median of
  --repeat) of the jaxmesh kernel flow (on its one-ring tiers, as for a concrete mesh,
  and on segment sums, as under ``jit`` with the mesh traced and no ``rings=``) and
  Laplacian (umbrella) flow (the same two ways), against Open3D
  ``filter_smooth_laplacian``, trimesh ``filter_laplacian`` (volume constraint
  off) and a plain vectorised numpy implementation of the same kernel flow;
* compile time of a 5-iteration kernel flow (first call minus a warm call);
* peak resident memory of compiling and running one 10-iteration kernel call
  (a fresh subprocess each; the increase over the loaded mesh is shown too);
* batch throughput: 16 noisy bunnies in one batched call vs a loop of 16 calls.

--big adds the bunny subdivided twice (~556k vertices).  float32, CPU.  --xla-flag runs
with the XLA setting the ``jaxmesh`` command uses
(:func:`jaxmesh.compiler.prefer_fast_cpu_compiles`); Open3D's row is left out, with a
note, where Open3D is not installed (``pip install '.[bench]'``).
Not part of the test suite: numbers depend on the machine; compare ratios.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import statistics
import subprocess
import sys
import time

import jax
import jax.numpy as jnp
import numpy as np
import trimesh

import jaxmesh
from jaxmesh.denoise import kernel_diffusion, umbrella_flow, vertex_rings


def median_time(fn, repeat: int) -> float:
    out = []
    for _ in range(repeat):
        t = time.perf_counter()
        fn()
        out.append(time.perf_counter() - t)
    return statistics.median(out)


def numpy_kernel_step(x, src, dst, deg, lam):
    """The random-walk kernel flow step in plain vectorised numpy (peer)."""
    n = len(x)
    c = np.zeros_like(x)
    np.add.at(c, src, x[dst])
    c /= np.maximum(deg, 1)[:, None]
    d = x[dst] - c[src]
    outer = (d[:, :, None] * d[:, None, :]).reshape(-1, 9)
    h = np.zeros((n, 9), x.dtype)
    np.add.at(h, src, outer)
    h = h.reshape(n, 3, 3) + lam * np.eye(3, dtype=x.dtype)
    inv, det = np.linalg.inv(h), np.linalg.det(h)
    delta = x[src] - x[dst]
    q = np.einsum("hk,hkl,hl->h", delta, inv[src], delta)
    kappa = (2 * np.pi) ** -1.5 / np.sqrt(det[src]) * np.exp(-0.5 * q)
    step = np.zeros_like(x)
    np.add.at(step, src, kappa[:, None] * (x[dst] - x[src]))
    total = np.zeros(n, x.dtype)
    np.add.at(total, src, kappa)
    return x + step / np.maximum(deg, total)[:, None]


def load_mesh(big: bool) -> jaxmesh.Mesh:
    m = jaxmesh.normalize(jaxmesh.data.load_sample("bunny"))
    if big:
        v, f = np.asarray(m.vertices), np.asarray(m.faces)
        for _ in range(2):
            v, f = trimesh.remesh.subdivide(v, f)
        m = jaxmesh.Mesh.from_arrays(v.astype(np.float32), f)
    return m


def peak_memory_child(big: bool) -> None:
    mesh = jaxmesh.add_noise(load_mesh(big), 0.3, 0)
    jax.block_until_ready(mesh.vertices)
    base = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss     # mesh loaded, nothing compiled
    rings = vertex_rings(mesh)
    g = jax.jit(lambda m, r: kernel_diffusion(m, 0.4, 10, rings=r))
    jax.block_until_ready(g(mesh, rings).vertices)
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    print(json.dumps({"peak_mib": peak / 1024, "extra_mib": (peak - base) / 1024}))


def bench(mesh: jaxmesh.Mesh, label: str, repeat: int, flag: bool) -> dict:
    noisy = jaxmesh.add_noise(mesh, 0.3, 0)
    v, f = np.array(noisy.vertices, np.float64), np.array(noisy.faces, np.int32)
    res = {"mesh": label, "V": mesh.num_vertices}
    rings = vertex_rings(noisy)
    k10 = jax.jit(lambda m, r: kernel_diffusion(m, 0.4, 10, rings=r))
    s10 = jax.jit(lambda m: kernel_diffusion(m, 0.4, 10))          # traced mesh, no rings: segment sums
    l10 = jax.jit(lambda m, r: umbrella_flow(m, 0.5, 10, rings=r))
    ls10 = jax.jit(lambda m: umbrella_flow(m, 0.5, 10))          # traced mesh, no rings: segment sums
    jax.block_until_ready(k10(noisy, rings).vertices)
    jax.block_until_ready(s10(noisy).vertices)
    jax.block_until_ready(l10(noisy, rings).vertices)
    jax.block_until_ready(ls10(noisy).vertices)
    # the flows alternate, so that a change of the machine's speed reaches all of them
    kernel, segments, laplacian, laplacian_segments = [], [], [], []
    for _ in range(repeat):
        kernel.append(median_time(lambda: jax.block_until_ready(k10(noisy, rings).vertices), 1) / 10)
        segments.append(median_time(lambda: jax.block_until_ready(s10(noisy).vertices), 1) / 10)
        laplacian.append(median_time(lambda: jax.block_until_ready(l10(noisy, rings).vertices), 1) / 10)
        laplacian_segments.append(median_time(lambda: jax.block_until_ready(ls10(noisy).vertices), 1) / 10)
    res["jaxmesh kernel"], res["jaxmesh laplacian"] = statistics.median(kernel), statistics.median(laplacian)
    res["jaxmesh kernel, segment sums"] = statistics.median(segments)
    res["jaxmesh laplacian, segment sums"] = statistics.median(laplacian_segments)
    try:
        import open3d as o3d
    except ImportError:
        res["Open3D filter_smooth_laplacian"] = float("nan")
    else:
        o3 = o3d.geometry.TriangleMesh(o3d.utility.Vector3dVector(v), o3d.utility.Vector3iVector(f))
        res["Open3D filter_smooth_laplacian"] = median_time(
            lambda: o3.filter_smooth_laplacian(number_of_iterations=10, lambda_filter=0.5), repeat) / 10

    def tm():
        m = trimesh.Trimesh(v.copy(), f, process=False)
        trimesh.smoothing.filter_laplacian(m, lamb=0.5, iterations=10, volume_constraint=False)

    res["trimesh filter_laplacian"] = median_time(tm, repeat) / 10
    src, dst, deg = (np.asarray(a) for a in (noisy.src, noisy.dst, noisy.degree))
    x32 = v.astype(np.float32)
    res["numpy kernel"] = median_time(lambda: numpy_kernel_step(x32, src, dst, deg.astype(np.float32), 0.4),
                                      repeat)
    # compile time of a 5-iteration flow: first call minus a warm call
    k5 = jax.jit(lambda m, lam, r: kernel_diffusion(m, lam, 5, rings=r))
    t = time.perf_counter()
    jax.block_until_ready(k5(noisy, 0.4, rings).vertices)
    first = time.perf_counter() - t
    warm = median_time(lambda: jax.block_until_ready(k5(noisy, 0.5, rings).vertices), repeat)
    res["compile_s"] = first - warm
    child = ["--memory-child"] + (["--big"] if label != "bunny" else []) + (["--xla-flag"] if flag else [])
    out = subprocess.run([sys.executable, __file__, *child],
                         capture_output=True, text=True, check=True)
    res["memory"] = json.loads(out.stdout.strip().splitlines()[-1])
    return res


def batch_throughput(repeat: int) -> dict:
    clean = load_mesh(False)
    keys = jax.random.split(jax.random.PRNGKey(0), 16)
    xs = jnp.stack([jaxmesh.add_noise(clean, 0.3, k).vertices for k in keys])
    batched = clean.with_vertices(xs)
    rings = vertex_rings(clean)
    fb = jax.jit(lambda m, r: kernel_diffusion(m, 0.4, 5, rings=r))
    jax.block_until_ready(fb(batched, rings).vertices)
    jax.block_until_ready(fb(clean.with_vertices(xs[0]), rings).vertices)
    t_batch = median_time(lambda: jax.block_until_ready(fb(batched, rings).vertices), repeat)
    t_loop = median_time(lambda: [jax.block_until_ready(fb(clean.with_vertices(xs[i]), rings).vertices)
                                  for i in range(16)], repeat)
    return {"batched_s": t_batch, "loop_s": t_loop, "throughput_ratio": t_loop / t_batch}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--big", action="store_true", help="also the bunny subdivided twice (~556k vertices)")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--xla-flag", action="store_true",
                    help="the jaxmesh command's XLA setting (jaxmesh.compiler.prefer_fast_cpu_compiles)")
    ap.add_argument("--memory-child", action="store_true", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.xla_flag:
        from jaxmesh.compiler import prefer_fast_cpu_compiles

        prefer_fast_cpu_compiles()       # before the first computation starts the backend
    if args.memory_child:
        return peak_memory_child(args.big)
    print(f"backend {jax.default_backend()}, {jax.device_count()} device(s), float32, "
          f"XLA flags {os.environ.get('XLA_FLAGS', '(defaults)')!r}")
    rows = [bench(load_mesh(False), "bunny", args.repeat, args.xla_flag)]
    if args.big:
        rows.append(bench(load_mesh(True), "bunny x2 subdivided", args.repeat, args.xla_flag))
    for r in rows:
        k = r["jaxmesh kernel"]
        print(f"\n{r['mesh']} (V={r['V']}): seconds per iteration, and peer / jaxmesh kernel")
        for name in ("jaxmesh kernel", "jaxmesh kernel, segment sums", "jaxmesh laplacian",
                     "jaxmesh laplacian, segment sums", "Open3D filter_smooth_laplacian",
                     "trimesh filter_laplacian", "numpy kernel"):
            print(f"  {name:32s} {r[name] * 1e3:9.2f} ms   {r[name] / k:6.2f}x")
        print(f"  kernel flow / umbrella (Laplacian) flow, per iteration, both on the one-ring tiers: "
              f"{r['jaxmesh kernel'] / r['jaxmesh laplacian']:.2f}x; both by segment sums: "
              f"{r['jaxmesh kernel, segment sums'] / r['jaxmesh laplacian, segment sums']:.2f}x")
        if r["Open3D filter_smooth_laplacian"] != r["Open3D filter_smooth_laplacian"]:
            print("  (Open3D is not installed: its row is NaN)")
        print(f"  jaxmesh laplacian vs trimesh laplacian: trimesh / jaxmesh = "
              f"{r['trimesh filter_laplacian'] / r['jaxmesh laplacian']:.2f}x")
        print(f"  compile time, 5-iteration kernel flow: {r['compile_s']:.2f} s")
        print(f"  peak RSS of a process that loads the mesh and compiles + runs a 10-iteration "
              f"kernel call: {r['memory']['peak_mib']:.0f} MiB")
    b = batch_throughput(args.repeat)
    print(f"\n16 noisy bunnies, 5 kernel iterations: one batched call {b['batched_s']:.3f} s, "
          f"loop of 16 calls {b['loop_s']:.3f} s -> throughput {b['throughput_ratio']:.2f}x")


if __name__ == "__main__":
    main()
