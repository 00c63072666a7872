"""XLA's CPU fusion emitters on and off (``--xla_cpu_use_fusion_emitters``), on
jaxmesh's flows: first-call time (compile + one run) and steady-state time.

    .venv/bin/python benchmarks/bench_xla_flags.py [--mesh bunny] [--repeat 5]

Each setting runs in a fresh subprocess (XLA reads ``XLA_FLAGS`` once, when the
backend starts): XLA's defaults, and the flag that
:func:`jaxmesh.compiler.prefer_fast_cpu_compiles` adds for the ``jaxmesh``
command.  float64 (as the command runs), the noisy mesh (0.2ℓ̄, seed 0) in its
unit frame; every method through ``denoise_in_unit_frame``; a vmapped batch of
16 noisy copies through the kernel flow against a loop of 16 calls.  Compare the
ratios, not the seconds.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path

FLAG = "--xla_cpu_use_fusion_emitters=false"
CASES = (("umbrella_flow", {"iterations": 10, "lam": 0.5}), ("taubin", {"iterations": 20}),
         ("kernel", {"iterations": 5}), ("bilateral_normal", {}))


def measure(mesh_name: str, repeat: int) -> dict:
    import jax

    jax.config.update("jax_enable_x64", True)
    import jaxmesh
    from jaxmesh.denoise import denoise_in_unit_frame, kernel_diffusion

    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "experiments"))
    from shared_meshes import load as load_shared

    noisy = jaxmesh.add_noise(load_shared(mesh_name), 0.2, 0)
    out = {}

    def timed(fn):
        t = time.perf_counter()
        jax.block_until_ready(fn())
        first = time.perf_counter() - t
        runs = []
        for _ in range(repeat):
            t = time.perf_counter()
            jax.block_until_ready(fn())
            runs.append(time.perf_counter() - t)
        return {"first_s": round(first, 3), "steady_ms": round(1e3 * min(runs), 1)}

    for method, params in CASES:
        out[method] = timed(lambda: denoise_in_unit_frame(noisy, method, **params).vertices)
    copies = [jaxmesh.add_noise(noisy, 0.05, k) for k in range(16)]
    batch = noisy.with_vertices(jax.numpy.stack([m.vertices for m in copies]))
    run = jax.jit(lambda m: kernel_diffusion(m, 0.02, 5).vertices)
    out["kernel batch of 16"] = timed(lambda: run(batch))
    out["kernel loop of 16"] = timed(lambda: [run(m) for m in copies])
    return out


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--mesh", default="bunny")
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--child", action="store_true", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.child:
        print(json.dumps(measure(args.mesh, args.repeat)))
        return
    rows = {}
    for label, flags in (("XLA defaults", ""), ("fusion emitters off", FLAG)):
        env = {**os.environ, "XLA_FLAGS": flags, "JAXMESH_XLA_DEFAULTS": "1"}
        res = subprocess.run([sys.executable, __file__, "--child", "--mesh", args.mesh, "--repeat", str(args.repeat)],
                             env=env, capture_output=True, text=True)
        if res.returncode:
            sys.exit(f"{label}: failed\n{res.stderr[-2000:]}")
        rows[label] = json.loads(res.stdout.strip().splitlines()[-1])
    a, b = rows["XLA defaults"], rows["fusion emitters off"]
    print(f"{args.mesh}, float64, 2 settings in fresh processes (steady: best of {args.repeat})")
    print(f"{'':22s} {'first call (s)':>24s} {'steady (ms)':>26s}")
    print(f"{'':22s} {'default':>8s} {'off':>7s} {'ratio':>7s} {'default':>9s} {'off':>8s} {'ratio':>7s}")
    for name in a:
        fa, fb, sa, sb = a[name]["first_s"], b[name]["first_s"], a[name]["steady_ms"], b[name]["steady_ms"]
        print(f"{name:22s} {fa:8.2f} {fb:7.2f} {fa / fb:6.2f}x {sa:9.1f} {sb:8.1f} {sa / sb:6.2f}x")
    print("ratio = default / off: above 1, the flag is faster")


if __name__ == "__main__":
    main()
