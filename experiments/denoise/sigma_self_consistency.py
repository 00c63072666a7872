"""Can the blind chooser's own output tell the surface's detail from the noise?

At low noise every estimator of ``jaxmesh.tune.noise_level`` reads
√(σ² + r²), r the surface's own vertex-scale roughness (0.055ℓ̄ on the clean
cow).  If a denoiser D_s run at an assumed noise level s kept the surface and
removed the noise, the estimate of its output would read r alone, and

    f(s) = √( σ̂(y)² − σ̂(D_s(y))² )

would equal the true σ at s = σ: the true level is a fixed point f(σ) = σ.
This script prints f(s)/s on a grid of s for noise along the normals (seed 0),
with D_s = ``choose_denoiser(y, sigma=s, draws=1, blend_draws=0)`` (the blind
chooser without its blend, at a given σ).  σ̂ is the default "min" estimator.
It is a measurement, not an estimator: it answers whether the fixed point is
unique and lies near σ, i.e. whether a refined σ̂ could be built on it.

    .venv/bin/python experiments/denoise/sigma_self_consistency.py [--meshes cow ...]

Writes experiments/results/denoise/sigma_self_consistency.md.
"""

from __future__ import annotations

import argparse
import sys
import time
import warnings
from pathlib import Path

import jax

jax.config.update("jax_enable_x64", True)

import numpy as np  # noqa: E402

import jaxmesh  # noqa: E402
from jaxmesh.tune import BlindTuningWarning, choose_denoiser, estimate_noise  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from shared_meshes import load as load_shared  # noqa: E402

OUT = Path(__file__).resolve().parents[2] / "experiments" / "results" / "denoise" / "sigma_self_consistency.md"
MESHES = ("cow", "maxplanck", "fandisk")
SIGMA = 0.02                                            # the low-noise level, in ℓ̄
GRID = (0.005, 0.01, 0.015, 0.02, 0.03, 0.045)         # assumed levels s, in ℓ̄


def f_over_s(noisy, e0: float, ell: float, s: float) -> float:
    """f(s)/s of the module docstring (s in ℓ̄; ``e0`` = σ̂(noisy), in mesh units)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", BlindTuningWarning)   # every s here is below LOW_NOISE
        out = choose_denoiser(noisy, sigma=s * ell, draws=1, blend_draws=0).mesh
    ed = estimate_noise(out)
    return float(np.sqrt(max(e0**2 - ed**2, 0.0))) / ell / s


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--meshes", nargs="*", default=list(MESHES))
    args = ap.parse_args()
    lines = ["# Self-consistency of σ at low noise: f(s)/s", "",
             "Regenerate: `.venv/bin/python experiments/denoise/sigma_self_consistency.py` (needs ../shared/meshes).",
             "", f"Noise along the normals, σ = {SIGMA}ℓ̄, seed 0. f(s) = √(σ̂(y)² − σ̂(D_s(y))²), D_s the blind "
             "chooser without blends at the given noise level s (script docstring). A fixed point is where "
             "f(s)/s = 1; the true level is s = σ (column " + f"{SIGMA}" + "). σ̂/σ: the default estimate.", "",
             "| mesh | σ̂/σ | " + " | ".join(f"s = {s}" for s in GRID) + " | seconds |",
             "|---|---|" + "---|" * len(GRID) + "---|"]
    for name in args.meshes:
        clean = jaxmesh.normalize(load_shared(name))
        ell = float(jaxmesh.mean_edge_length(clean))
        noisy = jaxmesh.add_noise(clean, SIGMA, jax.random.PRNGKey(0), along_normals=True)   # σ in ℓ̄
        t = time.perf_counter()
        e0 = estimate_noise(noisy)
        ratios = [f_over_s(noisy, e0, ell, s) for s in GRID]
        cells = [f"{e0 / ell / SIGMA:.2f}", *(f"{r:.2f}" for r in ratios),
                 f"{time.perf_counter() - t:.0f}"]
        lines.append(f"| {name} | " + " | ".join(cells) + " |")
        print(lines[-1], flush=True)
    OUT.write_text("\n".join(lines) + "\n")
    print("wrote", OUT)


if __name__ == "__main__":
    main()
