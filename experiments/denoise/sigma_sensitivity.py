"""How much the blind choice (``choose_denoiser``) depends on the noise estimate:
on a few scan cells of the feature table, auto with σ̂, with the true σ, with a
smaller recorruption (a = 0.25) and with four draws; mean face-normal error of
each choice against the oracle Taubin of ``feature_table.json``.

    .venv/bin/python experiments/denoise/sigma_sensitivity.py [--cells cow:0.1:normal ...] [--settings auto true_sigma]

Prints one JSON line per cell: for each setting (error in degrees, method,
parameters, σ̂/σ, seconds).  ``docs/guides/denoise.md`` quotes a run made
before the noise estimator's projection normals changed; the camelhead cell's
σ̂ has changed since (0.90σ then).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import jax

jax.config.update("jax_enable_x64", True)

import jaxmesh  # noqa: E402
from jaxmesh.geometry import mean_edge_length  # noqa: E402
from jaxmesh.metrics import mean_normal_angle_error  # noqa: E402
from jaxmesh.tune import choose_denoiser  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from shared_meshes import load as load_shared  # noqa: E402

RESULTS = Path(__file__).resolve().parents[2] / "experiments" / "results" / "denoise"
CELLS = (("cow", 0.1, "normal"), ("maxplanck", 0.3, "isotropic"), ("camelhead", 0.3, "normal"),
         ("spot", 0.1, "isotropic"), ("bunny", 0.1, "normal"))


SETTINGS = {"auto": {}, "true_sigma": {"sigma": None}, "a0.25": {"a": 0.25},
            "true_sigma_a0.25": {"sigma": None, "a": 0.25}, "draws4": {"draws": 4}}   # sigma None: the true σ


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--cells", nargs="*", default=[f"{m}:{s}:{n}" for m, s, n in CELLS], help="MESH:SIGMA:MODEL")
    ap.add_argument("--settings", nargs="*", default=list(SETTINGS), choices=list(SETTINGS))
    ap.add_argument("--out", help="also append the lines to this file")
    args = ap.parse_args()
    saved = json.loads((RESULTS / "feature_table.json").read_text())["cells"]
    for spec in args.cells:
        name, sigma, model = spec.split(":")
        sigma = float(sigma)
        clean = jaxmesh.normalize(load_shared(name))
        noisy = jaxmesh.add_noise(clean, sigma, jax.random.PRNGKey(0), along_normals=model == "normal")
        true = sigma * float(mean_edge_length(clean))
        row = next(r for r in saved if (r["mesh"], r["sigma"], r["model"]) == (name, sigma, model))
        out = {"oracle_taubin": round(row["oracle"]["taubin"]["normal_deg"], 2),
               "best_oracle": round(min(v["normal_deg"] for v in row["oracle"].values()), 2)}
        for label in args.settings:
            kw = {k: (true if k == "sigma" else v) for k, v in SETTINGS[label].items()}
            start = time.perf_counter()
            c = choose_denoiser(noisy, **kw)
            params = {k: (round(v, 3) if isinstance(v, float) else v) for k, v in c.params.items()}
            what = c.method if c.method != "blend" else " + ".join(f"{w:.2f} {m}" for m, _, w in c.components)
            out[label] = (round(float(mean_normal_angle_error(clean, c.mesh)), 2), what, params,
                          round(c.sigma / true, 2), round(time.perf_counter() - start, 1))
        line = f"{name} {sigma} {model} {json.dumps(out)}"
        print(line, flush=True)
        if args.out:
            with open(args.out, "a") as f:
                f.write(line + "\n")


if __name__ == "__main__":
    main()
