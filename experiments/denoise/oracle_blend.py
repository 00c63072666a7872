"""How much a convex blend of two denoisers can gain, with the clean mesh in hand:
the oracle-tuned Taubin filter and the oracle-tuned local bilateral normal
scheme (``feature_table.py``'s columns *taubin* and *bilateral_local*, their
saved parameters), blended as w·Taubin + (1 − w)·local for w = 0, 0.1, .., 1,
mean face-normal error of each.  The headroom of ``jaxmesh.tune.blend``
where those two are the leaders.

    .venv/bin/python experiments/denoise/oracle_blend.py [--meshes spot cow ...]

Reads experiments/results/denoise/feature_table.json (run feature_table.py
first); writes experiments/results/denoise/oracle_blend.md.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import jax

jax.config.update("jax_enable_x64", True)

import jax.numpy as jnp  # noqa: E402
import numpy as np  # noqa: E402

import jaxmesh  # noqa: E402
from jaxmesh.denoise import METHODS  # noqa: E402
from jaxmesh.metrics import mean_normal_angle_error  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from shared_meshes import load as load_shared  # noqa: E402

RESULTS = Path(__file__).resolve().parents[2] / "experiments" / "results" / "denoise"
WEIGHTS = np.linspace(0.0, 1.0, 11)


def oracle_output(noisy, name: str, params: dict):
    """The oracle's saved setting run again (the local scheme one iteration at a time, as it was tuned)."""
    m = METHODS["bilateral_normal" if name == "bilateral_local" else name]
    aux = m.prepare(noisy)
    if name != "bilateral_local":
        return m(noisy, **params, **aux).vertices
    p = dict(params)
    x = noisy
    for _ in range(p.pop("iterations")):
        x = m(x, **p, iterations=1, **aux)
    return x.vertices


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--meshes", nargs="*", default=None)
    args = ap.parse_args()
    cells = json.loads((RESULTS / "feature_table.json").read_text())["cells"]
    lines = ["# A convex blend of the oracle Taubin and the oracle local bilateral scheme", "",
             "Regenerate: `.venv/bin/python experiments/denoise/oracle_blend.py` (reads feature_table.json).", "",
             "Mean face-normal error (degrees) of w·Taubin + (1 − w)·local, both at their oracle settings; "
             "seed 0.", "",
             "| mesh | σ | noise | local (w=0) | taubin (w=1) | best blend (w) | gain over the better |",
             "|---|---|---|---|---|---|---|"]
    for r in cells:
        if args.meshes and r["mesh"] not in args.meshes or "bilateral_local" not in r["oracle"]:
            continue
        clean = jaxmesh.normalize(load_shared(r["mesh"]))
        noisy = jaxmesh.add_noise(clean, r["sigma"], jax.random.PRNGKey(r["seed"]),
                                  along_normals=r["model"] == "normal")
        a = np.asarray(oracle_output(noisy, "taubin", r["oracle"]["taubin"]["params"]))
        b = np.asarray(oracle_output(noisy, "bilateral_local", r["oracle"]["bilateral_local"]["params"]))
        errs = [float(mean_normal_angle_error(clean, noisy.with_vertices(jnp.asarray(w * a + (1 - w) * b))))
                for w in WEIGHTS]
        k = int(np.argmin(errs))
        row = (f"| {r['mesh']} | {r['sigma']} | {r['model'][:3]} | {errs[0]:.2f} | {errs[-1]:.2f} | "
               f"{errs[k]:.2f} ({WEIGHTS[k]:.1f}) | {1 - errs[k] / min(errs[0], errs[-1]):.1%} |")
        lines.append(row)
        print(row, flush=True)
    (RESULTS / "oracle_blend.md").write_text("\n".join(lines) + "\n")
    print(f"wrote {RESULTS / 'oracle_blend.md'}")


if __name__ == "__main__":
    main()
