"""How well each noise estimator reads σ from a noisy mesh alone.

    .venv/bin/python experiments/denoise/noise_estimate.py [--meshes cow fandisk ...]

σ̂/σ for every estimator of :func:`jaxmesh.tune.estimate_noise` on the shared
meshes (scaled to a unit bounding-box diagonal), σ ∈ {0.02, 0.1, 0.3} mean edge
lengths, both noise models (isotropic N(0, σ²I) per vertex; N(0, σ²) along the
clean mesh's vertex normals), seed 0; and each estimator's reading of the
clean mesh itself, in mean edge lengths: the roughness it cannot tell from
noise, which bounds how well any σ at or below it can be read.  Plus the
noise within the surface, :func:`jaxmesh.tune.estimate_tangential_noise`
(row *tangential*: σ̂_t/σ, near 1 for isotropic noise and near 0 along the
normals; its clean column is the sampling irregularity it reads as noise).

Writes experiments/results/denoise/noise_estimate.md.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import jax

jax.config.update("jax_enable_x64", True)

import jaxmesh  # noqa: E402
from jaxmesh.tune import NOISE_ESTIMATORS, estimate_noise, estimate_tangential_noise  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from shared_meshes import load as load_shared  # noqa: E402

OUT = Path(__file__).resolve().parents[2] / "experiments" / "results" / "denoise" / "noise_estimate.md"
MESHES = ("cow", "fertility", "maxplanck", "fandisk", "human", "spot", "bunny", "camelhead")
SIGMAS = (0.02, 0.1, 0.3)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--meshes", nargs="*", default=list(MESHES))
    args = ap.parse_args()
    cols = [(s, m) for m in ("isotropic", "normal") for s in SIGMAS]
    lines = ["# Noise estimation: σ̂/σ", "",
             "Regenerate: `.venv/bin/python experiments/denoise/noise_estimate.py` (needs ../shared/meshes).", "",
             "σ in mean edge lengths ℓ̄ of the unit-diagonal mesh, seed 0. *iso*: isotropic noise; *nrm*: along "
             "the normals. *clean*: the estimate on the clean mesh, in ℓ̄ (its own roughness read as noise). "
             "Target band at 0.02ℓ̄: [0.8, 1.25].", "",
             "| mesh | estimator | clean (ℓ̄) | " + " | ".join(f"{m[:3]} {s}" for s, m in cols) + " |",
             "|---|---|---|" + "---|" * len(cols)]
    for name in args.meshes:
        clean = jaxmesh.normalize(load_shared(name))
        ell = float(jaxmesh.mean_edge_length(clean))
        noisy = {(s, m): jaxmesh.add_noise(clean, s, jax.random.PRNGKey(0), along_normals=m == "normal")
                 for s, m in cols}
        for est in NOISE_ESTIMATORS:
            ratios = [estimate_noise(noisy[c], est) / (c[0] * ell) for c in cols]
            row = (f"| {name} | {est} | {estimate_noise(clean, est) / ell:.4f} | "
                   + " | ".join(f"{r:.2f}" for r in ratios) + " |")
            lines.append(row)
            print(row, flush=True)
        ratios = [estimate_tangential_noise(noisy[c]) / (c[0] * ell) for c in cols]
        row = (f"| {name} | tangential | {estimate_tangential_noise(clean) / ell:.4f} | "
               + " | ".join(f"{r:.2f}" for r in ratios) + " |")
        lines.append(row)
        print(row, flush=True)
    OUT.write_text("\n".join(lines) + "\n")
    print(f"wrote {OUT}")


if __name__ == "__main__":
    main()
