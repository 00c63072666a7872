"""Should blind ``--method auto`` consider the learned model?  ``choose_denoiser`` with the
shipped model added to its fixed candidates, against the default chooser (the blind runs
of ``evaluate.py``, blind.json) and the learned model alone, on the evaluation meshes.

    .venv/bin/python experiments/learn/auto_candidate.py [--meshes fandisk ...] [--seeds 0]

Writes experiments/results/learn/auto_candidate.{json,md} (run ``evaluate.py`` first).
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
from jaxmesh.metrics import mean_normal_angle_error  # noqa: E402
from jaxmesh.tune import choose_denoiser  # noqa: E402
from jaxmesh.tune.auto import CANDIDATES, Candidate  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parent))
from evaluate import MESHES, NOISES, RESULTS, noisy_copy  # noqa: E402
from shared_meshes import load  # noqa: E402

WITH_LEARNED = (*CANDIDATES, Candidate("learned", {}))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--meshes", nargs="+", default=list(MESHES))
    ap.add_argument("--seeds", nargs="+", type=int, default=[0])
    args = ap.parse_args()
    evaluation = json.loads((RESULTS / "evaluation.json").read_text())
    base = {(c["mesh"], c["sigma"], c["model"], c["seed"]): c for c in evaluation["cells"]}
    rows = []
    for name in args.meshes:
        clean = jaxmesh.normalize(load(name))
        for seed in args.seeds:
            for sigma, model in NOISES:
                noisy = noisy_copy(clean, sigma, model, seed)
                t = time.perf_counter()
                c = choose_denoiser(noisy, candidates=WITH_LEARNED)
                row = {"mesh": name, "sigma": sigma, "model": model, "seed": seed,
                       "auto_with_learned": float(mean_normal_angle_error(clean, c.mesh)),
                       "seconds": round(time.perf_counter() - t, 1),
                       "choice": c.method if c.method != "blend" else "+".join(m for m, _, _ in c.components)}
                ref = base.get((name, sigma, model, seed), {})
                row.update(auto=ref.get("auto"), learned=ref.get("learned"))
                rows.append(row)
                print(json.dumps(row), flush=True)
    (RESULTS / "auto_candidate.json").write_text(json.dumps(rows, indent=1) + "\n")
    lines = ["# Blind auto with the learned model as a candidate", "",
             "Regenerate: `.venv/bin/python experiments/learn/auto_candidate.py` (after `evaluate.py`).", "",
             "Mean face-normal angle error in degrees.", "",
             "| mesh | noise | σ | seed | auto | learned | auto + learned candidate (choice) |", "|---|---|---|---|---|---|---|"]
    for r in rows:
        fmt = lambda v: "–" if v is None else f"{v:.2f}"  # noqa: E731
        lines.append(f"| {r['mesh']} | {r['model']} | {r['sigma']} | {r['seed']} | {fmt(r['auto'])} | "
                     f"{fmt(r['learned'])} | {r['auto_with_learned']:.2f} ({r['choice']}) |")
    both = [r for r in rows if r["auto"] is not None and r["learned"] is not None]
    if both:
        mean = lambda k: statistics.fmean(r[k] for r in both)  # noqa: E731
        lines += ["", f"Means over {len(both)} cells: auto {mean('auto'):.3f}°, learned {mean('learned'):.3f}°, "
                      f"auto with the learned candidate {mean('auto_with_learned'):.3f}°."]
    (RESULTS / "auto_candidate.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
