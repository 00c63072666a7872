"""Thesis figs 2.6-2.13: shaded renders of the original, the noisy mesh and
every method at its E-optimal parameters (read from best_table.csv, so run
best_table.py first).

    .venv/bin/python experiments/denoise/renders.py [--mesh fandisk --sigma 0.3]

writes experiments/results/denoise/renders_<mesh>_<sigma>.png.
"""

from __future__ import annotations

import argparse
import ast
import csv

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

from common import METHODS, RESULTS, load, noisy_copy, rings_for, visual_error  # noqa: E402
from jaxmesh.metrics import mean_normal_angle_error  # noqa: E402
from jaxmesh.render import render  # noqa: E402

VIEWS = {"fandisk": (30, -40), "bunny": (15, 20), "cow": (10, 20)}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--mesh", default="fandisk")
    ap.add_argument("--sigma", type=float, default=0.3)
    ap.add_argument("--optimum", choices=("E", "angle"), default="angle",
                    help="which optimum's parameters to show (default: best normal error)")
    args = ap.parse_args()
    table = list(csv.DictReader(open(RESULTS / "best_table.csv")))
    best = {r["method"][len("jaxmesh "):]: ast.literal_eval(r[f"params_best_{args.optimum}"
                                                              if args.optimum == "angle" else "params_best_E"])
            for r in table if r["mesh"] == args.mesh and float(r["sigma"]) == args.sigma
            and r["method"].startswith("jaxmesh ")}
    if not best:
        raise SystemExit(f"no rows for {args.mesh} at sigma {args.sigma} in best_table.csv")
    clean = load(args.mesh)
    noisy = noisy_copy(clean, args.sigma)
    rings = rings_for(noisy)
    panels = [("original", clean), (f"noisy σ={args.sigma} mean edge", noisy)]
    for name, params in best.items():
        aux = {"graph": rings} if "graph" in METHODS[name].params else {}
        out = METHODS[name](noisy, **{k: (int(v) if METHODS[name].params[k].kind == "int" else v)
                                      for k, v in params.items()}, **aux)
        e = float(visual_error(clean, out)) / float(visual_error(clean, noisy))
        a = float(mean_normal_angle_error(clean, out))
        panels.append((f"{name}\nE×{e:.3f}, normals {a:.1f}°", out))
    cols = 4
    rows = -(-len(panels) // cols)
    fig, axes = plt.subplots(rows, cols, figsize=(3.2 * cols, 3.2 * rows))
    elev, azim = VIEWS.get(args.mesh, (15, 20))
    for ax, (title, m) in zip(axes.ravel(), panels):
        render(m, ax, elev=elev, azim=azim, title=title)
    for ax in axes.ravel()[len(panels):]:
        ax.axis("off")
    fig.suptitle(f"{args.mesh}: each method at its best-{args.optimum} parameters", fontsize=10)
    fig.tight_layout()
    out_path = RESULTS / f"renders_{args.mesh}_{args.sigma}.png"
    fig.savefig(out_path, dpi=110)
    print(f"wrote {out_path}")


if __name__ == "__main__":
    main()
