"""What a learned model's gates read: the repair gate g_r, its α, the stages' steps g_s and
Taubin's λ_s, per mesh and noise, for a model with the optional parts (``ModelConfig``'s
``repair_rounds``, ``gated``, ``tail_features``).

    .venv/bin/python experiments/learn/gates.py [--model FILE] [--meshes camelhead spot fandisk]

Noise as in ``evaluate.py`` (seed 0): impulsive (p = 0.5, σ = 0.5ℓ̄ along the normals) and
isotropic Gaussian at 0.1 and 0.5ℓ̄.  Prints a Markdown table.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import jax
import numpy as np

jax.config.update("jax_enable_x64", True)

import jaxmesh  # noqa: E402
from jaxmesh.learn import load_model, repair_parameters, roughness_features, stage_parameters  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parent))
from evaluate import noisy_copy  # noqa: E402
from shared_meshes import ROOT, load  # noqa: E402

DEFAULT = ROOT / "experiments" / "results" / "learn" / "models" / "full-angle.jxl"
NOISES = [(0.5, "impulsive"), (0.1, "isotropic"), (0.5, "isotropic")]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--model", type=Path, default=DEFAULT)
    ap.add_argument("--meshes", nargs="+", default=["camelhead", "spot", "fandisk"])
    args = ap.parse_args()
    model = load_model(args.model)
    cfg = model.config
    if not (cfg.repair_rounds and cfg.gated):
        raise SystemExit(f"{args.model}: the model has no repair stage or no stage gates ({cfg})")
    print("| mesh | noise | σ | repair gate g_r | α | stage steps g_s | Taubin λ_s |")
    print("|---|---|---|---|---|---|---|")
    for name in args.meshes:
        clean = jaxmesh.normalize(load(name))
        for sigma, kind in NOISES:
            noisy = noisy_copy(clean, sigma, kind, 0)
            z = roughness_features(noisy, noisy.vertices, cfg.tail_features)
            r, t = repair_parameters(model, z), stage_parameters(model, z)
            fmt = lambda a: ", ".join(f"{v:.2f}" for v in np.asarray(a))  # noqa: E731
            print(f"| {name} | {kind} | {sigma} | {float(r['gate']):.2f} | {float(r['alpha']):.2f} | "
                  f"{fmt(t['step'])} | {fmt(t['lam'])} |")


if __name__ == "__main__":
    main()
