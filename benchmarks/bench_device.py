"""The library on 2 CPU cores and on the accelerator, in one run.

    .venv/bin/python benchmarks/bench_device.py [--json FILE] [--count 32]

Each platform runs in child processes of its own: ``JAX_PLATFORMS=cpu`` pinned to two
cores (``sched_setaffinity``, BLAS threads 2: the machine the other benchmarks report),
and the accelerator (``JAX_PLATFORMS=cuda,cpu``), skipped with a note when JAX sees none.
Every figure is a wall time on that platform; the table's last column is CPU / accelerator.

Workloads (the shipped bunny, 35k vertices, with Gaussian noise of 0.3 mean edge lengths;
"556k" is it subdivided twice, as ``bench_denoise.py --big`` builds it):

* the kernel flow (one-ring tiers) and the umbrella flow: per iteration of a jitted
  10-iteration call, median of 5 warm calls, float32;
* guided normal filtering at the registry's defaults, one warm jitted call, float32;
* the blind default (``choose_denoiser``) in float64 as the command line runs it: the first
  call in a fresh process (compiles included, no persistent cache) and a second call;
* the dataset runner (``denoise_files``, Taubin, padded batches of its default batch size:
  1 on CPU, 16 on an accelerator; then packed unions, its default for Taubin) over
  ``--count`` noisy copies of the shipped bunny and spot: meshes/s of a first run
  (compiles included) and of a second run in the same process.

The host's sparse solvers and eigensolvers run on the CPU on every platform.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _bunny(big: bool):
    """The shipped bunny (subdivided twice when ``big``), noisy at 0.3ℓ̄."""
    import jaxmesh
    from bench_denoise import load_mesh

    return jaxmesh.add_noise(load_mesh(big), 0.3, 0)


def child_flows(count: int) -> dict:
    """Float32 work: the flows, guided filtering, the dataset runner."""
    import jax

    import jaxmesh
    from jaxmesh.dataset import denoise_files
    from jaxmesh.denoise import METHODS, denoise
    from jaxmesh.denoise.kernel_flow import kernel_diffusion
    from jaxmesh.denoise.laplacian import umbrella_flow
    from jaxmesh.denoise.vertex_rings import vertex_rings
    from bench_denoise import median_time

    out = {"platform": jax.devices()[0].platform, "device": jax.devices()[0].device_kind}
    for label, big in (("bunny", False), ("556k", True)):
        mesh = _bunny(big)
        rings = vertex_rings(mesh)
        k10 = jax.jit(lambda m, r: kernel_diffusion(m, 0.4, 10, rings=r))
        l10 = jax.jit(lambda m: umbrella_flow(m, 0.5, 10))
        jax.block_until_ready(k10(mesh, rings).vertices)
        jax.block_until_ready(l10(mesh).vertices)
        out[f"kernel flow, {label}, per iteration"] = median_time(lambda: jax.block_until_ready(k10(mesh, rings).vertices), 5) / 10
        out[f"umbrella flow, {label}, per iteration"] = median_time(lambda: jax.block_until_ready(l10(mesh).vertices), 5) / 10
    mesh = _bunny(False)
    aux = METHODS["guided_normal"].prepare(mesh)
    guided = jax.jit(lambda m, a: denoise(m, "guided_normal", **a).vertices)     # mesh and graph as arguments
    jax.block_until_ready(guided(mesh, aux))
    out["guided filter, bunny"] = median_time(lambda: jax.block_until_ready(guided(mesh, aux)), 3)
    with tempfile.TemporaryDirectory() as tmp:
        samples = [jaxmesh.data.load_sample(name) for name in ("bunny", "spot")]
        paths = []
        for i in range(count):
            path = Path(tmp) / "in" / f"m{i:03d}.ply"
            path.parent.mkdir(exist_ok=True)
            jaxmesh.save(jaxmesh.add_noise(samples[i % 2], 0.3, i), path)
            paths.append(path)
        for pack, label in ((False, "dataset runner"), (True, "dataset runner, packed")):
            for run in ("first", "second"):
                summary = denoise_files(paths, Path(tmp) / f"{run}{pack}", "taubin", pack=pack)
                out[f"{label}, {run} run, meshes/s"] = count / summary.seconds
    return out


def child_auto() -> dict:
    """The blind default in float64 (the command line's dtype)."""
    import jax

    jax.config.update("jax_enable_x64", True)
    import jaxmesh
    from jaxmesh.tune import choose_denoiser

    mesh = jaxmesh.add_noise(jaxmesh.normalize(jaxmesh.data.load_sample("bunny", dtype="float64")), 0.3, 0)
    out = {}
    for run in ("first", "second"):
        t = time.perf_counter()
        choice = choose_denoiser(mesh)
        jax.block_until_ready(choice.mesh.vertices)
        out[f"blind auto, bunny, {run} call"] = time.perf_counter() - t
    out["blind auto chose"] = choice.method
    return out


def run_child(platform: str, part: str, count: int) -> dict | str:
    """One child's figures, or the reason it gave none."""
    # an accelerator run keeps "cpu" listed: the host callbacks (sparse solves, eigensolves) need it
    env = dict(os.environ, JAX_PLATFORMS=platform if platform == "cpu" else f"{platform},cpu", PYTHONUNBUFFERED="1",
               JAX_ENABLE_COMPILATION_CACHE="false")
    if platform == "cpu":
        env.update(OMP_NUM_THREADS="2", OPENBLAS_NUM_THREADS="2", MKL_NUM_THREADS="2")
    argv = [sys.executable, __file__, "--child", part, "--count", str(count)]
    pin = platform == "cpu" and hasattr(os, "sched_setaffinity") and len(os.sched_getaffinity(0)) > 2
    proc = subprocess.run(argv, env=env, capture_output=True, text=True,
                          preexec_fn=(lambda: os.sched_setaffinity(0, sorted(os.sched_getaffinity(0))[:2])) if pin
                          else None)
    if proc.returncode != 0:
        return "\n".join(proc.stderr.strip().splitlines()[-15:]) or f"exit {proc.returncode}"
    return json.loads(proc.stdout.strip().splitlines()[-1])


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--json", help="also write the figures to this file")
    ap.add_argument("--count", type=int, default=32, help="meshes in the dataset-runner run (default 32)")
    ap.add_argument("--child", choices=("flows", "auto"), help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.child:
        print(json.dumps(child_flows(args.count) if args.child == "flows" else child_auto()))
        return
    sys.path.insert(0, str(ROOT))
    import jax

    accelerator = next((p for p in ("cuda", "rocm", "tpu") if _has(p)), None)
    figures = {}
    for platform in ([accelerator] if accelerator else []) + ["cpu"]:
        figures[platform] = {}
        for part in ("flows", "auto"):
            got = run_child(platform, part, args.count)
            if isinstance(got, str):      # reported, and the other parts still run
                print(f"{platform} {part} failed: {got}", file=sys.stderr, flush=True)
                got = {f"{part} failed": got}
            figures[platform].update(got)
            if args.json:
                Path(args.json).write_text(json.dumps(figures, indent=1))
    cpu = figures["cpu"]
    other = figures.get(accelerator, {}) if accelerator else {}
    print(f"jax {jax.__version__}; CPU: 2 cores" + (f"; accelerator: {other.get('device')}" if other else
                                                      "; no accelerator seen by JAX: CPU only"))
    print("| workload | CPU, 2 cores | accelerator | CPU / accelerator |")
    print("|---|---|---|---|")
    for key, value in cpu.items():
        if key in ("platform", "device") or not isinstance(value, float):
            continue
        acc = other.get(key)
        rate = "meshes/s" in key
        fmt = (lambda x: f"{x:.2f}") if rate else (lambda x: f"{x * 1e3:.2f} ms" if x < 1 else f"{x:.2f} s")
        ratio = "" if acc is None else f"{(acc / value if rate else value / acc):.2f}×"
        print(f"| {key} | {fmt(value)} | {'' if acc is None else fmt(acc)} | {ratio} |")
    print(f"blind auto chose: CPU {cpu.get('blind auto chose')}"
          + (f", accelerator {other.get('blind auto chose')}" if other else ""))


def _has(platform: str) -> bool:
    """Whether JAX finds a device of ``platform`` (asked in a child: the parent stays backend-free)."""
    probe = "import jax, sys; sys.exit(0 if jax.devices() else 1)"
    env = dict(os.environ, JAX_PLATFORMS=platform)
    return subprocess.run([sys.executable, "-c", probe], env=env, capture_output=True).returncode == 0


if __name__ == "__main__":
    main()
