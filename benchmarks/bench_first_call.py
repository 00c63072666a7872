"""First-call latency of eager library calls in a fresh process: noise and error metrics.

    .venv/bin/python benchmarks/bench_first_call.py [--sample spot]

In a fresh Python process (no compiled program cached, no persistent compilation cache):
two ``add_noise`` calls (isotropic, then impulsive along the normals) and the four
error metrics of ``jaxmesh.metrics`` against the clean mesh, each called eagerly once.
What it measures is mostly XLA compiling: one program per call when the body is jitted,
one per primitive when it is not.
"""
from __future__ import annotations

import argparse
import time

import jax
import numpy as np

jax.config.update("jax_enable_x64", True)

import jaxmesh  # noqa: E402
from jaxmesh import metrics as M  # noqa: E402
from jaxmesh.data import load_sample  # noqa: E402


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sample", default="spot")
    args = ap.parse_args()
    mesh = load_sample(args.sample, dtype=np.float64)
    t = time.perf_counter()
    noisy = jaxmesh.add_noise(mesh, 0.3, 1)
    jax.block_until_ready(jaxmesh.add_noise(mesh, 0.3, 2, along_normals=True, fraction=0.5).vertices)
    t_noise = time.perf_counter() - t
    t = time.perf_counter()
    for f in (M.visual_error, M.nonlinear_visual_error, M.rms_vertex_error, M.mean_normal_angle_error):
        float(f(mesh, noisy))
    t_metrics = time.perf_counter() - t
    print(f"{args.sample} (V={mesh.num_vertices}), float64, fresh process: two add_noise calls "
          f"{t_noise:.2f} s, four metrics {t_metrics:.2f} s")


if __name__ == "__main__":
    main()
