"""Impulsive noise on the shared meshes: oracle-tuned methods against blind
``--method auto``, mean face-normal error.

    .venv/bin/python experiments/denoise/impulsive_table.py [--meshes fandisk ...] [--resume] [--blind-only]

Noise (:func:`jaxmesh.add_impulsive_noise`): each vertex, with probability p,
moved along its clean area-weighted normal by N(0, σ²), σ = 0.5ℓ̄; the others
untouched; meshes scaled to a unit bounding-box diagonal.  Cells:
{fandisk, camelhead, maxplanck, bunny} × p = 0.5 on seeds 0, 1, 2 and
p ∈ {0.1, 0.3} on seed 0.  Oracles as in ``feature_table.py`` (the tuner with
the clean mesh in hand, objective "normal"; L0's λ from a grid), and impulse
repair's best of ``REPAIR_GRID``.  Blind:
``choose_denoiser`` with its defaults (no clean mesh, the noise law read from
the mesh).  The targets: blind ≤ 1.25× the best oracle and ≤ 0.5× the
oracle Taubin in every cell.

Writes experiments/results/denoise/impulsive_table.{md,json}.
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
from jaxmesh.tune import choose_denoiser  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parent))
from feature_table import ORACLE as FEATURE_ORACLE, choice, errors, oracle as feature_oracle  # noqa: E402
from shared_meshes import load as load_shared  # noqa: E402

RESULTS = Path(__file__).resolve().parents[2] / "experiments" / "results" / "denoise"
MESHES = ("fandisk", "camelhead", "maxplanck", "bunny")
SIGMA = 0.5
ORACLE = FEATURE_ORACLE + ("impulse_repair",)
#: the impulse-repair oracle's grid: α × rounds (α₀ at its default)
REPAIR_GRID = {"alpha": (0.1, 0.3, 1.0, 3.0), "iterations": (5, 10)}
#: (fraction, seed) of every cell of a mesh
SETTINGS = ((0.5, 0), (0.5, 1), (0.5, 2), (0.3, 0), (0.1, 0))


def noisy_pair(name: str, fraction: float, seed: int):
    clean = jaxmesh.normalize(load_shared(name))
    return clean, jaxmesh.add_impulsive_noise(clean, SIGMA, jax.random.PRNGKey(seed), fraction=fraction)


def blind(clean, noisy) -> dict:
    start = time.perf_counter()
    c = choose_denoiser(noisy)
    ell = float(mean_edge_length(clean))
    return {"method": c.method, "params": c.params, "components": [list(x) for x in c.components],
            "noise_law": c.noise_law, "fraction_hat": c.fraction, "sigma_hat_ell": c.sigma / ell,
            **errors(clean, c.mesh), "seconds": round(time.perf_counter() - start, 1)}


def oracle(name: str, clean, noisy) -> dict:
    """feature_table's oracles, and impulse repair's: the best of REPAIR_GRID by normal error."""
    if name != "impulse_repair":
        return feature_oracle(name, clean, noisy)
    start = time.perf_counter()
    rows = [({"alpha": a, "iterations": k}, errors(clean, jaxmesh.denoise.denoise(noisy, name, alpha=a, iterations=k)))
            for a in REPAIR_GRID["alpha"] for k in REPAIR_GRID["iterations"]]
    params, err = min(rows, key=lambda r: r[1]["normal_deg"])
    return {"params": params, **err, "seconds": round(time.perf_counter() - start, 1)}


def cell(name: str, fraction: float, seed: int, methods) -> dict:
    clean, noisy = noisy_pair(name, fraction, seed)
    out = {"mesh": name, "fraction": fraction, "seed": seed, "noisy": errors(clean, noisy)}
    out["oracle"] = {m: oracle(m, clean, noisy) for m in methods}
    out["blind"] = blind(clean, noisy)
    return out


def table(rows: list[dict]) -> str:
    lines = ["# Impulsive noise: oracle-tuned vs blind `--method auto`", "",
             "Regenerate: `.venv/bin/python experiments/denoise/impulsive_table.py` (needs ../shared/meshes).", "",
             f"Mean face-normal angle error in degrees. A fraction p of the vertices moved along their normals by "
             f"N(0, ({SIGMA}ℓ̄)²), the rest untouched. Oracle: tuned with the clean mesh (objective: normal error). "
             "Blind: `choose_denoiser` defaults; its reading of the noise law (p̂, σ̂₁ in ℓ̄) in brackets.", "",
             "| mesh | p | seed | noisy | " + " | ".join(ORACLE) + " | blind auto (choice) | law read | seconds "
             "| auto / best oracle | auto / taubin |", "|---" * (10 + len(ORACLE)) + "|"]
    order = {m: i for i, m in enumerate(MESHES)}
    worst_best, worst_taubin = 0.0, 0.0
    for r in sorted(rows, key=lambda r: (order.get(r["mesh"], 99), -r["fraction"], r["seed"])):
        o, b = r["oracle"], r["blind"]
        best = min(v["normal_deg"] for v in o.values())
        ratio, vs_taubin = b["normal_deg"] / best, b["normal_deg"] / o["taubin"]["normal_deg"]
        worst_best, worst_taubin = max(worst_best, ratio), max(worst_taubin, vs_taubin)
        law = f"{b['noise_law']} {b['fraction_hat']:.2f}, {b['sigma_hat_ell']:.2f}"
        lines.append(f"| {r['mesh']} | {r['fraction']} | {r['seed']} | {r['noisy']['normal_deg']:.2f} | "
                     + " | ".join(f"{o[m]['normal_deg']:.2f}" if m in o else "–" for m in ORACLE)
                     + f" | {b['normal_deg']:.2f} ({choice(b)}) | {law} | {b['seconds']:.0f} | {ratio:.2f} | "
                     f"{vs_taubin:.2f} |")
    lines += ["", f"- worst auto / best oracle: {worst_best:.2f} (target ≤ 1.25); worst auto / oracle Taubin: "
                  f"{worst_taubin:.2f} (target ≤ 0.5); {len(rows)} cells"]
    if any(m not in r["oracle"] for r in rows for m in ORACLE):
        lines.append("- –: that oracle was not run for the cell (`--oracles`, to save time on the larger meshes); "
                     "its best oracle is the best of the columns shown")
    return "\n".join(lines) + "\n"


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--meshes", nargs="*", default=list(MESHES))
    ap.add_argument("--resume", action="store_true", help="keep the saved cells, run the missing ones")
    ap.add_argument("--blind-only", action="store_true", help="recompute the blind column of the saved cells")
    ap.add_argument("--oracles", nargs="*", default=list(ORACLE), choices=ORACLE)
    ap.add_argument("--fractions", nargs="*", type=float, default=None,
                    help="only the settings with these fractions (default: all of SETTINGS)")
    args = ap.parse_args()
    path = RESULTS / "impulsive_table.json"
    done = json.loads(path.read_text()) if (args.resume or args.blind_only) and path.exists() else {"cells": []}
    if args.blind_only:
        for r in done["cells"]:
            if args.meshes and r["mesh"] not in args.meshes:
                continue
            r["blind"] = blind(*noisy_pair(r["mesh"], r["fraction"], r["seed"]))
            print(r["mesh"], r["fraction"], r["seed"], "auto", r["blind"]["normal_deg"], flush=True)
            path.write_text(json.dumps(done, indent=1))
    for r in done["cells"]:                     # oracle columns added since the cell was run
        missing = [m for m in args.oracles if m not in r["oracle"]]
        if missing:
            clean, noisy = noisy_pair(r["mesh"], r["fraction"], r["seed"])
            r["oracle"].update({m: oracle(m, clean, noisy) for m in missing})
            print(r["mesh"], r["fraction"], r["seed"], "oracle", missing, flush=True)
            path.write_text(json.dumps(done, indent=1))
    have = {(r["mesh"], r["fraction"], r["seed"]) for r in done["cells"]}
    for name in args.meshes:
        for fraction, seed in SETTINGS:
            if (name, fraction, seed) in have or args.blind_only or (args.fractions and fraction not in args.fractions):
                continue
            r = cell(name, fraction, seed, tuple(args.oracles))
            done["cells"].append(r)
            print(f"{name} p={fraction} seed {seed}: noisy {r['noisy']['normal_deg']:.2f} "
                  + " ".join(f"{m} {v['normal_deg']:.2f}" for m, v in r["oracle"].items())
                  + f" | auto {r['blind']['normal_deg']:.2f} ({r['blind']['seconds']} s)", flush=True)
            RESULTS.mkdir(parents=True, exist_ok=True)
            path.write_text(json.dumps(done, indent=1))
    text = table(done["cells"])
    (RESULTS / "impulsive_table.md").write_text(text)
    print(text)


if __name__ == "__main__":
    main()
