"""Sixteen noisy bunnies: one packed call against a loop of single calls and a padded vmap.

    .venv/bin/python benchmarks/bench_packed.py [--count 16] [--methods umbrella_flow kernel] [--repeat 7]

The shipped bunny (34,817 vertices) with ``--count`` draws of Gaussian noise of 0.2ℓ̄,
each mesh in its own unit frame (as ``jaxmesh denoise`` runs it), float64, the method's
defaults:

* *loop*: one jitted :func:`~jaxmesh.denoise.framed.framed_run` per mesh (compiled once:
  the meshes share a shape), dispatched back to back, waited for at the end;
* *packed*: :func:`~jaxmesh.denoise.run_packed` once on :func:`~jaxmesh.batch.pack_batch`
  of all of them;
* *vmapped*: :func:`~jaxmesh.denoise.framed.framed_run` vmapped over
  :func:`~jaxmesh.batch.pad_batch` of all of them (no padding: one size).

Warm times (compiled before timing), the median of ``--repeat`` runs; the host-side
packing and padding are timed apart.  Prints the ratios loop / packed and loop / vmapped.
Not part of the test suite: compare ratios, not seconds.
"""

from __future__ import annotations

import argparse
import time

import numpy as np


def _median_seconds(fn, repeat: int) -> float:
    fn()
    times = []
    for _ in range(repeat):
        t = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t)
    return float(np.median(times))


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--count", type=int, default=16)
    ap.add_argument("--methods", nargs="*", default=["umbrella_flow", "kernel"])
    ap.add_argument("--repeat", type=int, default=7)
    args = ap.parse_args()
    from jaxmesh.compiler import prefer_fast_cpu_compiles

    prefer_fast_cpu_compiles()
    import jax

    jax.config.update("jax_enable_x64", True)
    import jaxmesh
    from jaxmesh.batch import pack_batch, pad_batch
    from jaxmesh.denoise import METHODS, run_packed
    from jaxmesh.denoise.framed import framed_run
    from jaxmesh.transforms import far_mask

    bunny = jaxmesh.data.load_sample("bunny", dtype=np.float64)
    meshes = [jaxmesh.add_noise(bunny, 0.2, seed) for seed in range(args.count)]
    t = time.perf_counter()
    packed = pack_batch(meshes)
    pack_s = time.perf_counter() - t
    t = time.perf_counter()
    padded = pad_batch(meshes)
    pad_s = time.perf_counter() - t
    fars = [far_mask(m) for m in meshes]
    padded_far = jax.numpy.stack([jax.numpy.concatenate([f, jax.numpy.zeros(1, bool)]) for f in fars])
    print(f"{args.count} bunnies of {bunny.num_vertices} vertices; host side: pack_batch {pack_s:.3f} s, "
          f"pad_batch {pad_s:.3f} s")
    for name in args.methods:
        cont, statics = METHODS[name].split()
        one = jax.jit(lambda m, f: framed_run(m, name, far=f, **cont, **dict(statics))[0].vertices)
        many = jax.jit(jax.vmap(lambda m, f: framed_run(m, name, far=f, **cont, **dict(statics))[0].vertices))

        def loop():
            jax.block_until_ready([one(m, f) for m, f in zip(meshes, fars)])

        def packed_call():
            run_packed(packed.mesh, packed.segment, packed.far, cont, packed.segments, name,
                       statics)[0].vertices.block_until_ready()

        def vmapped():
            many(padded.mesh, padded_far).block_until_ready()

        t_loop, t_packed, t_vmap = (_median_seconds(f, args.repeat) for f in (loop, packed_call, vmapped))
        print(f"{name}: loop {t_loop * 1e3:.1f} ms, packed {t_packed * 1e3:.1f} ms, vmapped {t_vmap * 1e3:.1f} ms; "
              f"loop / packed {t_loop / t_packed:.2f}x, loop / vmapped {t_loop / t_vmap:.2f}x")


if __name__ == "__main__":
    main()
