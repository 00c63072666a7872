"""First-call latency of eager library calls in a fresh process: noise, error metrics, geometry, denoising.

    .venv/bin/python benchmarks/bench_first_call.py [--sample spot]

In a fresh Python process (no compiled program cached, no persistent compilation cache):
two ``add_noise`` calls (isotropic, then impulsive along the normals); the four
error metrics of ``jaxmesh.metrics`` against the clean mesh; six geometry and operator
functions (face areas and normals, vertex normals, mean edge length, the umbrella operator,
``normalize``); ``denoise_in_unit_frame`` with Taubin and with the kernel flow; each
called eagerly once.
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
from jaxmesh.denoise import denoise_in_unit_frame  # noqa: E402


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
    t = time.perf_counter()
    for f in (jaxmesh.geometry.face_areas, jaxmesh.geometry.face_normals, jaxmesh.geometry.vertex_normals,
              jaxmesh.geometry.mean_edge_length):
        jax.block_until_ready(f(noisy))
    jax.block_until_ready(jaxmesh.operators.umbrella(noisy, noisy.vertices))
    jax.block_until_ready(jaxmesh.transforms.normalize(noisy).vertices)
    t_geometry = time.perf_counter() - t
    times = []
    for method in ("taubin", "kernel"):
        t = time.perf_counter()
        jax.block_until_ready(denoise_in_unit_frame(noisy, method).vertices)
        times.append(time.perf_counter() - t)
    print(f"{args.sample} (V={mesh.num_vertices}), float64, fresh process: two add_noise calls "
          f"{t_noise:.2f} s, four metrics {t_metrics:.2f} s, six geometry calls {t_geometry:.2f} s, "
          f"denoise_in_unit_frame taubin {times[0]:.2f} s, kernel {times[1]:.2f} s")


if __name__ == "__main__":
    main()
