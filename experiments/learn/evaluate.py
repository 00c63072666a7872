"""The shipped learned denoiser against blind ``--method auto`` and the oracle-tuned
methods, on meshes it was never trained or validated on.

    .venv/bin/python experiments/learn/evaluate.py [--meshes fandisk spot ...] [--seeds 0 1 2]
        [--model FILE] [--skip-auto | --blind-only]

Grid: {fandisk, spot, camelhead, bunny} × σ ∈ {0.1, 0.3, 0.5, 0.7}ℓ̄ × {isotropic, along
the normals} plus impulsive noise (p = 0.5 of the vertices moved along their normals,
σ = 0.5ℓ̄), seeds 0, 1, 2; the noisy copies are made exactly as in
``experiments/denoise/feature_table.py`` (unit-diagonal mesh, ``add_noise(clean, σ,
PRNGKey(seed))``), so its oracle-tuned errors (seed 0, σ ≤ 0.5ℓ̄, and the fandisk at
0.7ℓ̄) are the oracle column here.  Unseen by training: σ = 0.4ℓ̄ (held out of the training
noise) on every mesh, and the bunny decimated to a quarter of its vertices at 0.3ℓ̄.
Timing: the learned denoiser on the 35k-vertex bunny against one guided normal filtering
run of 20 iterations (both compiled, median of 3 runs, same process).

Writes experiments/results/learn/evaluation.{json,md}.  The blind runs (the slow part,
and independent of the model) are kept in experiments/results/learn/blind.json and
reused; ``--blind-only`` fills that file alone, ``--skip-auto`` leaves them out.
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import time
from pathlib import Path

import jax

jax.config.update("jax_enable_x64", True)

import jaxmesh  # noqa: E402
from jaxmesh.denoise import METHODS  # noqa: E402
from jaxmesh.hashing.attacks import simplify  # noqa: E402
from jaxmesh.learn import default_model, learned_denoising  # noqa: E402
from jaxmesh.metrics import mean_normal_angle_error  # noqa: E402
from jaxmesh.tune import choose_denoiser  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from shared_meshes import ROOT, load  # noqa: E402

RESULTS = ROOT / "experiments" / "results" / "learn"
BLIND_FILE = RESULTS / "blind.json"
FEATURE_TABLE = ROOT / "experiments" / "results" / "denoise" / "feature_table.json"
MESHES = ("fandisk", "spot", "camelhead", "bunny")
NOISES = [(s, m) for s in (0.1, 0.3, 0.5, 0.7) for m in ("isotropic", "normal")] + [(0.5, "impulsive")]
UNSEEN = [(0.4, "isotropic"), (0.4, "normal")]


def noisy_copy(clean, sigma: float, model: str, seed: int):
    key = jax.random.PRNGKey(seed)
    if model == "impulsive":
        return jaxmesh.add_noise(clean, sigma, key, along_normals=True, fraction=0.5)
    return jaxmesh.add_noise(clean, sigma, key, along_normals=model == "normal")


def oracle_table() -> dict:
    """(mesh, σ, model, seed) → (best oracle error, its method) from the feature table."""
    if not FEATURE_TABLE.is_file():
        return {}
    out = {}
    for c in json.loads(FEATURE_TABLE.read_text())["cells"]:
        name, err = min(((m, r["normal_deg"]) for m, r in c["oracle"].items()), key=lambda t: t[1])
        out[(c["mesh"], c["sigma"], c["model"], c["seed"])] = (err, name)
    return out


class Learned:
    """The learned denoiser compiled once per mesh (connectivity)."""

    def __init__(self, model):
        self.model = model
        self.run = jax.jit(lambda mesh, graph: learned_denoising(mesh, model, graph))

    def __call__(self, noisy, graph):
        t = time.perf_counter()
        out = jax.block_until_ready(self.run(noisy, graph))
        return out, time.perf_counter() - t


class Blind:
    """The blind choices, kept in BLIND_FILE by (mesh label, σ, model, seed)."""

    def __init__(self, skip: bool):
        self.skip = skip
        self.rows = json.loads(BLIND_FILE.read_text()) if BLIND_FILE.is_file() else {}

    def __call__(self, label: str, clean, noisy, sigma, model, seed) -> dict:
        key = f"{label}|{sigma}|{model}|{seed}"
        if key not in self.rows and not self.skip:
            t = time.perf_counter()
            c = choose_denoiser(noisy)
            self.rows[key] = {"auto": float(mean_normal_angle_error(clean, c.mesh)),
                              "auto_seconds": round(time.perf_counter() - t, 1),
                              "auto_choice": c.method if c.method != "blend"
                              else "+".join(m for m, _, _ in c.components)}
            BLIND_FILE.write_text(json.dumps(self.rows, indent=1) + "\n")
        return self.rows.get(key, {})


def cell(learned, blind: Blind, label: str, clean, graph, sigma, model, seed) -> dict:
    noisy = noisy_copy(clean, sigma, model, seed)
    row = {"sigma": sigma, "model": model, "seed": seed, "noisy": float(mean_normal_angle_error(clean, noisy))}
    if learned is not None:
        out, seconds = learned(noisy, graph)
        row.update(learned=float(mean_normal_angle_error(clean, out)), learned_seconds=round(seconds, 3))
    return {**row, **blind(label, clean, noisy, sigma, model, seed)}


def timing(learned: Learned, clean) -> dict:
    graph = jaxmesh.denoise.face_graph(clean)
    noisy = noisy_copy(clean, 0.3, "normal", 0)
    guided = METHODS["guided_normal"]
    run_guided = jax.jit(lambda mesh, graph: guided(mesh, graph=graph))

    def median(f):
        jax.block_until_ready(f())
        ts = []
        for _ in range(3):
            t = time.perf_counter()
            jax.block_until_ready(f())
            ts.append(time.perf_counter() - t)
        return statistics.median(ts)

    tl = median(lambda: learned.run(noisy, graph).vertices)
    tg = median(lambda: run_guided(noisy, graph).vertices)
    return {"mesh": "bunny", "vertices": clean.num_vertices, "learned_s": round(tl, 3), "guided20_s": round(tg, 3),
            "ratio": round(tl / tg, 2)}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--meshes", nargs="+", default=list(MESHES))
    ap.add_argument("--seeds", nargs="+", type=int, default=[0, 1, 2])
    ap.add_argument("--model", default=None, help="model file (default: the shipped one)")
    ap.add_argument("--skip-auto", action="store_true", help="the learned model only (no new blind runs)")
    ap.add_argument("--blind-only", action="store_true", help="fill blind.json alone (no model needed)")
    ap.add_argument("--tag", default=None,
                    help="write evaluation-TAG.{json,md} (another model's figures) instead of evaluation.*")
    args = ap.parse_args()
    RESULTS.mkdir(parents=True, exist_ok=True)
    learned = None if args.blind_only else Learned(default_model(args.model))
    blind = Blind(args.skip_auto)
    data = {"model": str(args.model or "default"), "cells": [], "unseen": []}
    for name in args.meshes:
        clean = jaxmesh.normalize(load(name))
        graph = jaxmesh.denoise.face_graph(clean)
        for seed in args.seeds:
            for sigma, model in NOISES:
                data["cells"].append({"mesh": name, **cell(learned, blind, name, clean, graph, sigma, model, seed)})
                print(json.dumps(data["cells"][-1]), flush=True)
        for sigma, model in UNSEEN:
            data["unseen"].append({"mesh": name, **cell(learned, blind, name, clean, graph, sigma, model, 0)})
            print(json.dumps(data["unseen"][-1]), flush=True)
    bunny = jaxmesh.normalize(load("bunny"))
    quarter = jaxmesh.normalize(simplify(bunny, 0.25))
    qgraph = jaxmesh.denoise.face_graph(quarter)
    label = f"bunny (decimated to {quarter.num_vertices} vertices)"
    for model in ("isotropic", "normal"):
        data["unseen"].append({"mesh": label, **cell(learned, blind, label, quarter, qgraph, 0.3, model, 0)})
        print(json.dumps(data["unseen"][-1]), flush=True)
    if learned is None:
        return
    data["timing"] = timing(learned, bunny)
    print(json.dumps(data["timing"]), flush=True)
    stem = "evaluation" if args.tag is None else f"evaluation-{args.tag}"
    (RESULTS / f"{stem}.json").write_text(json.dumps(data, indent=1) + "\n")
    (RESULTS / f"{stem}.md").write_text(report(data, args))
    print(report(data, args))


def report(data: dict, args=None) -> str:
    oracle = oracle_table()
    tagged = args is not None and args.tag is not None
    how = (f"evaluate.py --model {args.model} --tag {args.tag}` (the model: `train_default.py` with the "
           f"settings in its record)" if tagged else "evaluate.py` (needs ../shared/meshes; the model: "
           "`experiments/learn/train_default.py`)")
    lines = ["# The learned denoiser on unseen meshes" + (f": {args.tag}" if tagged else ""), "",
             f"Regenerate: `.venv/bin/python experiments/learn/{how}.", "",
             "Mean face-normal angle error in degrees; σ in mean edge lengths ℓ̄; blind auto = `choose_denoiser` "
             "(the default of `jaxmesh denoise`); oracle = the best oracle-tuned method of "
             "`experiments/results/denoise/feature_table.json` (seed 0 only; '–' where it has no cell).", "",
             "| mesh | noise | σ | seeds | noisy | learned | blind auto | learned / auto | best oracle (method) |",
             "|---|---|---|---|---|---|---|---|---|"]
    groups: dict = {}
    for c in data["cells"]:
        groups.setdefault((c["mesh"], c["model"], c["sigma"]), []).append(c)
    ratios, vs_oracle = [], []
    for (mesh, model, sigma), cs in groups.items():
        mean = lambda k: statistics.fmean(c[k] for c in cs if k in c)  # noqa: E731
        has_auto = all("auto" in c for c in cs)
        ratio = mean("learned") / mean("auto") if has_auto else None
        if ratio is not None:
            ratios.append(ratio)
        o = oracle.get((mesh, sigma, model, 0))
        seed0 = next((c for c in cs if c["seed"] == 0), None)
        if o is not None and seed0 is not None:
            vs_oracle.append((seed0["learned"], o[0]))
        lines.append(f"| {mesh} | {model} | {sigma} | {len(cs)} | {mean('noisy'):.2f} | {mean('learned'):.2f} | "
                     + (f"{mean('auto'):.2f} | {ratio:.2f}" if has_auto else "– | –")
                     + f" | {f'{o[0]:.2f} ({o[1]})' if o else '–'} |")
    lines.append("")
    if ratios:
        lines.append(f"learned / auto: mean {statistics.fmean(ratios):.3f}, worst {max(ratios):.3f} over "
                     f"{len(ratios)} cells ({sum(r <= 1 for r in ratios)} at or below 1.0).")
    if vs_oracle:
        lo, hi = statistics.fmean(a for a, _ in vs_oracle), statistics.fmean(b for _, b in vs_oracle)
        lines.append(f"Against the best oracle (seed 0, the {len(vs_oracle)} cells the feature table has): learned "
                     f"{lo:.2f}°, oracle {hi:.2f}° on average.")
    lines += ["", "## Not seen in training (seed 0)", "",
              "| mesh | noise | σ | noisy | learned | blind auto |", "|---|---|---|---|---|---|"]
    for c in data.get("unseen", []):
        lines.append(f"| {c['mesh']} | {c['model']} | {c['sigma']} | {c['noisy']:.2f} | {c['learned']:.2f} | "
                     + (f"{c['auto']:.2f} |" if "auto" in c else "– |"))
    beat = [c["learned"] <= c["auto"] for c in data.get("unseen", []) if "auto" in c]
    if beat:
        lines.append(f"\nlearned ≤ blind auto in {sum(beat)} of {len(beat)} unseen cells.")
    t = data.get("timing")
    if t:
        lines += ["", f"Inference on the bunny ({t['vertices']} vertices), compiled, median of 3: learned "
                      f"{t['learned_s']} s, one guided normal filtering run of 20 iterations {t['guided20_s']} s "
                      f"(ratio {t['ratio']})."]
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    main()
