"""The blind chooser's recorruption under each noise model: the tangential part
σ_t of the recorruption set to 0 ("normal"), σ ("isotropic") or estimated from
the mesh ("auto", the default), on the cells of feature_table.py.

    .venv/bin/python experiments/denoise/noise_model.py [--meshes spot cow ...]

(``--meshes`` reruns those meshes and keeps the other saved rows.)

Mean face-normal error of ``choose_denoiser``'s result, seed 0, with the
oracle-tuned Taubin's error beside it (from feature_table.json), and σ̂_t/σ̂,
the mesh's reading of its noise within the surface (1 for isotropic noise, 0
along the normals).  Writes experiments/results/denoise/noise_model.{md,json}.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
import warnings
from pathlib import Path

import jax

jax.config.update("jax_enable_x64", True)

import jaxmesh  # noqa: E402
from jaxmesh.metrics import mean_normal_angle_error  # noqa: E402
from jaxmesh.tune import NOISE_MODELS, choose_denoiser, estimate_noise, estimate_tangential_noise  # noqa: E402
from jaxmesh.tune.blend import BLEND_DRAWS  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from shared_meshes import load as load_shared  # noqa: E402

RESULTS = Path(__file__).resolve().parents[2] / "experiments" / "results" / "denoise"


def row(cell: dict, blend_draws: int = BLEND_DRAWS) -> dict:
    clean = jaxmesh.normalize(load_shared(cell["mesh"]))
    noisy = jaxmesh.add_noise(clean, cell["sigma"], jax.random.PRNGKey(cell["seed"]),
                              along_normals=cell["model"] == "normal")
    out = {k: cell[k] for k in ("mesh", "sigma", "model", "seed")}
    out["taubin_oracle"] = cell["oracle"]["taubin"]["normal_deg"]
    out["tangential_ratio"] = estimate_tangential_noise(noisy) / estimate_noise(noisy)
    for model in NOISE_MODELS:
        start = time.perf_counter()
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            c = choose_denoiser(noisy, noise_model=model, blend_draws=blend_draws)
        out[model] = {"normal_deg": float(mean_normal_angle_error(clean, c.mesh)), "method": c.method,
                      "params": c.params, "seconds": round(time.perf_counter() - start, 1)}
    return out


def table(rows: list[dict], blend_draws: int = BLEND_DRAWS) -> str:
    flag = "" if blend_draws == BLEND_DRAWS else f" --blend-draws {blend_draws}"
    lines = ["# The blind chooser's noise model", "",
             f"Regenerate: `.venv/bin/python experiments/denoise/noise_model.py{flag}` (after feature_table.py).", "",
             "Mean face-normal error (degrees) of `choose_denoiser` with the recorruption's tangential part "
             "σ_t = 0 (*normal*), σ (*isotropic*) or estimated (*auto*, the default: "
             "min(σ̂_t, σ̂)); σ̂_t/σ̂ is the mesh's reading. Seed 0; noise *iso* = isotropic, *nor* = along the "
             "normals; oracle Taubin from feature_table.json.", "",
             "| mesh | σ | noise | σ̂_t/σ̂ | oracle taubin | normal | isotropic | auto |", "|---|---|---|---|---|---|---|---|"]
    for r in rows:
        best = min(r[m]["normal_deg"] for m in ("normal", "isotropic"))
        cells = [f"**{r[m]['normal_deg']:.2f}**" if r[m]["normal_deg"] <= best + 1e-9 else f"{r[m]['normal_deg']:.2f}"
                 for m in ("normal", "isotropic", "auto")]
        lines.append(f"| {r['mesh']} | {r['sigma']} | {r['model'][:3]} | {r['tangential_ratio']:.2f} | "
                     f"{r['taubin_oracle']:.2f} | " + " | ".join(cells) + " |")
    for m in ("normal", "isotropic", "auto"):
        mean = sum(r[m]["normal_deg"] / r["taubin_oracle"] for r in rows) / max(len(rows), 1)
        below = sum(r[m]["normal_deg"] < r["taubin_oracle"] for r in rows)
        lines.append(f"\n*{m}*: mean error / oracle Taubin {mean:.3f}, below oracle Taubin in {below} of {len(rows)}")
    return "\n".join(lines) + "\n"


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--meshes", nargs="*", default=None)
    ap.add_argument("--blend-draws", type=int, default=BLEND_DRAWS,
                    help=f"the chooser's blend draws (default {BLEND_DRAWS}, the library's; 0: no blending)")
    args = ap.parse_args()
    cells = json.loads((RESULTS / "feature_table.json").read_text())["cells"]
    saved = RESULTS / "noise_model.json"
    keep = {(r["mesh"], r["sigma"], r["model"]): r for r in json.loads(saved.read_text())} \
        if args.meshes and saved.exists() else {}                   # --meshes reruns those, keeps the rest
    rows = []
    for cell in cells:
        if args.meshes and cell["mesh"] not in args.meshes:
            if (cell["mesh"], cell["sigma"], cell["model"]) in keep:
                rows.append(keep[cell["mesh"], cell["sigma"], cell["model"]])
            continue
        rows.append(row(cell, args.blend_draws))
        r = rows[-1]
        print(f"{r['mesh']} {r['sigma']} {r['model']}: " + " ".join(
            f"{m} {r[m]['normal_deg']:.2f}" for m in NOISE_MODELS), flush=True)
        (RESULTS / "noise_model.json").write_text(json.dumps(rows, indent=1))
    text = table(rows, args.blend_draws)
    (RESULTS / "noise_model.md").write_text(text)
    print(text)


if __name__ == "__main__":
    main()
