"""The search paths' early stop: how much of each path it runs, and whether it ever
moves a risk curve's least point.

    .venv/bin/python experiments/denoise/path_stopping.py

Runs the blind chooser (every setting on every draw, ``race_keep=None``) on five
noisy meshes, recording every search-path setting's full risk curve (the stop
turned off), then applies the stop of :mod:`jaxmesh.tune.paths` to each curve
offline (a plain loop written from its rule) for a few (factor, patience) pairs.
Writes experiments/results/denoise/path_stopping.md.
"""

from __future__ import annotations

import sys
from pathlib import Path

import jax

jax.config.update("jax_enable_x64", True)

import numpy as np  # noqa: E402

import jaxmesh  # noqa: E402
import jaxmesh.tune.race as race_module  # noqa: E402
from jaxmesh.geometry import mean_edge_length  # noqa: E402
from jaxmesh.tune.paths import PATH_STOP_FACTOR, PATH_STOP_PATIENCE  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from shared_meshes import load  # noqa: E402

RESULTS = Path(__file__).resolve().parents[2] / "experiments" / "results" / "denoise"
#: (mesh, σ in ℓ̄, along the normals)
CELLS = (("bunny", 0.3, False), ("fandisk", 0.3, True), ("fandisk", 0.7, False), ("camelhead", 0.1, True),
         ("cow", 0.5, False))
RULES = ((PATH_STOP_FACTOR, PATH_STOP_PATIENCE), (1.1, 3), (1.05, 5), (1.5, 3))


def stop_count(risks: np.ndarray, factor: float, patience: int) -> int:
    """The iterations the stop runs: after iteration t (0-based), stop once t + 1 > best + patience
    and the risk of t exceeds factor × the least so far."""
    best = 0
    for t in range(len(risks)):
        if risks[t] < risks[best]:
            best = t
        if t + 1 > best + patience and risks[t] > factor * risks[best]:
            return t + 1
    return len(risks)


def curves() -> list[tuple]:
    recorded = []
    full = race_module.path_risks

    def every_count(mesh, path, setting, *args, **kwargs):
        kwargs["stop"] = None
        r = full(mesh, path, setting, *args, **kwargs)
        recorded.append((path.method, dict(setting), r))
        return r

    race_module.path_risks = every_count
    out = []
    try:
        for name, level, along in CELLS:
            clean = jaxmesh.normalize(load(name))
            noisy = jaxmesh.add_noise(clean, level * float(mean_edge_length(clean)), 0, along_normals=along)
            recorded.clear()
            jaxmesh.tune.choose_denoiser(noisy, race_keep=None)
            out += [((name, level, along), *r) for r in recorded]
            print(name, level, along, len(recorded), "curves", flush=True)
    finally:
        race_module.path_risks = full
    return out


def main() -> None:
    rows = curves()
    lines = ["# The search paths' early stop", "",
             "Regenerate: `.venv/bin/python experiments/denoise/path_stopping.py` (needs ../shared/meshes).", "",
             f"{len(rows)} risk curves (every search-path setting, summed over the draws) on "
             + ", ".join(f"{n} {s}ℓ̄ {'along the normals' if a else 'isotropic'}" for n, s, a in CELLS)
             + f". The default rule is factor {PATH_STOP_FACTOR}, patience {PATH_STOP_PATIENCE}.", "",
             "| factor | patience | iterations run (share of all) | curves whose least point moved | worst least ratio |",
             "|---|---|---|---|---|"]
    for factor, patience in RULES:
        run = total = moved = 0
        worst = 1.0
        for _, _, _, r in rows:
            n = stop_count(r, factor, patience)
            run, total = run + n, total + len(r)
            if np.argmin(r[:n]) != np.argmin(r):
                moved, worst = moved + 1, max(worst, float(r[:n].min() / r.min()))
        lines.append(f"| {factor} | {patience} | {run / total:.3f} | {moved} | {worst:.4f} |")
    text = "\n".join(lines) + "\n"
    RESULTS.mkdir(parents=True, exist_ok=True)
    (RESULTS / "path_stopping.md").write_text(text)
    print(text)


if __name__ == "__main__":
    main()
