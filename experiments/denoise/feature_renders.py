"""Renders of the feature table's cells: the clean mesh, the noisy one, the
oracle-tuned Taubin, the best oracle-tuned method and the blind
``--method auto`` choice, each at the parameters saved in feature_table.json
(run feature_table.py first).

    .venv/bin/python experiments/denoise/feature_renders.py [--cells fandisk:0.3:normal bunny:0.1:normal ...]

Writes experiments/results/denoise/feature_renders.png (one row per cell).
"""

from __future__ import annotations

import argparse
import json
import sys
import warnings
from pathlib import Path

import jax

jax.config.update("jax_enable_x64", True)

import matplotlib  # noqa: E402

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

import jaxmesh  # noqa: E402
from jaxmesh.denoise import METHODS  # noqa: E402
from jaxmesh.metrics import mean_normal_angle_error  # noqa: E402
from jaxmesh.render import render  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from shared_meshes import load as load_shared  # noqa: E402

RESULTS = Path(__file__).resolve().parents[2] / "experiments" / "results" / "denoise"
VIEWS = {"fandisk": (30, -40), "bunny": (15, 20), "cow": (10, 20), "spot": (15, 30), "maxplanck": (10, 0),
         "camelhead": (15, 20)}
DEFAULT_CELLS = ("fandisk:0.3:normal", "fandisk:0.3:isotropic", "bunny:0.1:normal", "maxplanck:0.3:isotropic")


def blind_output(b: dict, noisy):
    """The saved blind choice: its method, or the weighted sum of the blend's components."""
    if b["method"] != "blend":
        return run(b["method"], b["params"], noisy)
    return noisy.with_vertices(sum(w * run(m, p, noisy).vertices for m, p, w in b["components"]))


def run(name: str, params: dict, noisy):
    """``name`` with the saved ``params`` (the oracle's "bilateral_local" is bilateral_normal)."""
    method = METHODS["bilateral_normal" if name == "bilateral_local" else name]
    params = {k: v for k, v in params.items() if k in method.params and method.params[k].kind != "aux"}
    return method(noisy, **params, **method.prepare(noisy))


def panels(cell: dict) -> list:
    clean = jaxmesh.normalize(load_shared(cell["mesh"]))
    noisy = jaxmesh.add_noise(clean, cell["sigma"], jax.random.PRNGKey(cell["seed"]),
                              along_normals=cell["model"] == "normal")
    oracle = cell["oracle"]
    best = min(oracle, key=lambda m: oracle[m]["normal_deg"])
    shown = [("clean", clean), (f"noisy {cell['sigma']}ℓ̄ {cell['model'][:3]}", noisy)]
    for label, name, params in (("oracle taubin", "taubin", oracle["taubin"]["params"]),
                                (f"oracle {best}", best, oracle[best]["params"]),
                                (f"blind auto: {cell['blind']['method']}", None, None)):
        out = run(name, params, noisy) if name else blind_output(cell["blind"], noisy)
        shown.append((f"{label}\n{float(mean_normal_angle_error(clean, out)):.2f}°", out))
    return shown


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--cells", nargs="*", default=list(DEFAULT_CELLS), help="MESH:SIGMA:MODEL")
    args = ap.parse_args()
    saved = json.loads((RESULTS / "feature_table.json").read_text())["cells"]
    index = {(c["mesh"], c["sigma"], c["model"]): c for c in saved}
    wanted = []
    for spec in args.cells:
        mesh, sigma, model = spec.split(":")
        if (mesh, float(sigma), model) not in index:
            raise SystemExit(f"{spec}: not in feature_table.json")
        wanted.append(index[mesh, float(sigma), model])
    fig, axes = plt.subplots(len(wanted), 5, figsize=(16, 3.2 * len(wanted)), squeeze=False)
    for row, cell in zip(axes, wanted):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            shown = panels(cell)
        elev, azim = VIEWS.get(cell["mesh"], (15, 20))
        for ax, (title, mesh) in zip(row, shown):
            render(mesh, ax, elev=elev, azim=azim, title=title)
        print(f"{cell['mesh']} {cell['sigma']} {cell['model']}: " + ", ".join(t.replace("\n", " ") for t, _ in shown[2:]),
              flush=True)
    fig.tight_layout()
    out = RESULTS / "feature_renders.png"
    fig.savefig(out, dpi=90)
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
