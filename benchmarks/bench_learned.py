"""First-call (compile) and warm time of the shipped learned denoiser, forward and gradient.

    .venv/bin/python benchmarks/bench_learned.py [--sample spot] [--sigma 0.3]

The shipped model (``jaxmesh.learn.default_model``) on a sample mesh with Gaussian noise of
``sigma`` mean edge lengths, in float64: the first call of the jitted denoiser (trace +
compile + run), the median of five warm calls, and the same for the gradient of Σ‖x_out‖² in the noisy
positions.  Prints a digest of the output so that two versions of the library can be
compared for the same result.  One process, no persistent compilation cache.
"""
from __future__ import annotations

import argparse
import hashlib
import statistics
import time

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

jax.config.update("jax_enable_x64", True)

from jaxmesh.data import load_sample  # noqa: E402
from jaxmesh.denoise import face_graph  # noqa: E402
from jaxmesh.geometry import mean_edge_length  # noqa: E402
from jaxmesh.learn import default_model, learned_denoising  # noqa: E402
from jaxmesh.noise import add_noise  # noqa: E402


def timed(fn, x) -> tuple[float, jax.Array]:
    t = time.perf_counter()
    out = jax.block_until_ready(fn(x))
    return time.perf_counter() - t, out


def warm(fn, x, repeat: int = 5) -> float:
    """Median time of ``repeat`` calls after the first."""
    return statistics.median(timed(fn, x)[0] for _ in range(repeat))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sample", default="spot")
    ap.add_argument("--sigma", type=float, default=0.3, help="noise, in mean edge lengths")
    args = ap.parse_args()
    clean = load_sample(args.sample)
    noisy = add_noise(clean, args.sigma * float(mean_edge_length(clean)), jax.random.PRNGKey(0))
    model, graph = default_model(), face_graph(noisy)
    # the mesh, the model's weights and the face graph are arguments, not constants baked into the program
    run = eqx.filter_jit(lambda m, g, mesh, x: learned_denoising(mesh.with_vertices(x), m, g).vertices)
    loss_grad = eqx.filter_jit(jax.grad(lambda x, m, g, mesh: jnp.sum(
        learned_denoising(mesh.with_vertices(x), m, g).vertices ** 2)))
    forward = lambda x: run(model, graph, noisy, x)  # noqa: E731
    grad = lambda x: loss_grad(x, model, graph, noisy)  # noqa: E731
    f1, out = timed(forward, noisy.vertices)
    f2 = warm(forward, noisy.vertices)
    g1, g = timed(grad, noisy.vertices)
    g2 = warm(grad, noisy.vertices)
    print(f"{args.sample} (V={noisy.num_vertices}), shipped model, float64, {jax.default_backend()}")
    print(f"  forward: first call {f1:.2f} s, warm {f2 * 1e3:.1f} ms")
    print(f"  gradient: first call {g1:.2f} s, warm {g2 * 1e3:.1f} ms")
    digest = hashlib.sha256(np.asarray(out).tobytes()).hexdigest()[:16]
    print(f"  output digest {digest}, sum |gradient| {float(jnp.abs(g).sum()):.10g}")


if __name__ == "__main__":
    main()
