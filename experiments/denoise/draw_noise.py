"""How precisely two recorruption draws pick an iteration count, and what more draws give.

    .venv/bin/python experiments/denoise/draw_noise.py [--cells spot:0.5:iso cow:0.1:nor ...]

The blind chooser ranks every setting by the recorrupted estimate on two draws
(``choose_denoiser(draws=2)``, the race's finalists on both).  For a linear filter the
estimate's curve over the iteration count is smooth, but its minimum moves from draw to
draw.  This script takes one search path, Taubin smoothing at λ = 0.5, μ = −0.5 (the
chooser's own setting), on the feature table's cells (noise seed 0, meshes in the unit
frame) and reports:

* the count minimising the mean face-normal angle error (the tables' measure), and the
  count minimising the mean squared edge tilt against the clean mesh (what the estimate
  estimates, at the input's noise level), with the clean mesh in hand;
* the count the estimate picks from each of eight independent pairs of draws (as the
  chooser draws them: independent fields along the pilot's normals at σ̂, the tangential
  part at the chooser's σ_t), from each of eight antithetic pairs (z, −z), and from all
  sixteen draws together;
* the angle error at those counts.

The recorrupted estimate targets the error at the noise level σ√(1 + a²) (a = 0.5), with
the tilts measured against the pilot's normals; so its least count may differ from both
clean-mesh counts even with many draws.

Writes experiments/results/denoise/draw_noise.md.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import jax

jax.config.update("jax_enable_x64", True)

import jax.numpy as jnp  # noqa: E402
import numpy as np  # noqa: E402

import jaxmesh  # noqa: E402
from jaxmesh.denoise import taubin_smoothing  # noqa: E402
from jaxmesh.geometry import face_normals, mean_edge_length, vertex_normals  # noqa: E402
from jaxmesh.host import HostMesh  # noqa: E402
from jaxmesh.metrics import mean_normal_angle_error  # noqa: E402
from jaxmesh.tune import estimate_noise, estimate_tangential_noise  # noqa: E402
from jaxmesh.tune.race import run_setting  # noqa: E402
from jaxmesh.tune.recorrupt import edge_tilt  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from shared_meshes import load  # noqa: E402

RESULTS = Path(__file__).resolve().parents[2] / "experiments" / "results" / "denoise"
CELLS = ("spot:0.3:iso", "spot:0.5:iso", "cow:0.1:nor", "cow:0.5:iso", "camelhead:0.3:nor")
LAM = 0.5
COUNT = 120
PAIRS = 8
A = 0.5


@jax.jit
def _path(noisy, x0):
    """Positions after 1..COUNT Taubin iterations from x0, one program: (COUNT, V, 3)."""
    def step(x, _):
        x = taubin_smoothing(noisy.with_vertices(x), lam=LAM, mu=-LAM, iterations=1).vertices
        return x, x
    return jax.lax.scan(step, x0, None, length=COUNT)[1]


def _sums(noisy, nu, ell, outputs, target) -> np.ndarray:
    """Σ_f ‖A_f(x_t − target)‖² / F for every count t, (COUNT,)."""
    return np.asarray(jnp.sum(edge_tilt(noisy, nu, ell, outputs - target[None]) ** 2, axis=(-2, -1))) / noisy.num_faces


def cell(name: str, sigma: float, model: str) -> dict:
    clean = jaxmesh.normalize(load(name))
    noisy = jaxmesh.add_noise(clean, sigma, jax.random.PRNGKey(0), along_normals=model == "nor")
    host = HostMesh(noisy)
    s = float(estimate_noise(host))
    s_t = min(float(estimate_tangential_noise(host)), s)
    pilot = noisy.with_vertices(run_setting(noisy, noisy.vertices, "guided_normal", {}, host.aux("guided_normal")))
    nu, n = face_normals(pilot), vertex_normals(pilot, "area")
    ell = float(mean_edge_length(noisy))
    y = noisy.vertices
    clean_path = _path(noisy, y)
    angle = np.array([float(mean_normal_angle_error(clean, noisy.with_vertices(x))) for x in clean_path])
    tilt = _sums(noisy, face_normals(clean), ell, clean_path, clean.vertices)

    def field(k):
        key = jax.random.PRNGKey(1000 + k)
        normal = s * jax.random.normal(key, (y.shape[0], 1), y.dtype) * n
        xi = jax.random.normal(jax.random.fold_in(key, 1), y.shape, y.dtype)
        return normal + s_t * (xi - jnp.sum(xi * n, axis=-1, keepdims=True) * n)

    def estimate(z):
        return _sums(noisy, nu, ell, _path(noisy, y + A * z), y - z / A)
    singles = [estimate(field(k)) for k in range(2 * PAIRS)]
    anti = [(singles[k] + estimate(-field(k))) / 2 for k in range(PAIRS)]      # z_k's own run reused
    pairs = [int(np.argmin(singles[2 * i] + singles[2 * i + 1])) + 1 for i in range(PAIRS)]
    antithetic = [int(np.argmin(a)) + 1 for a in anti]
    every = int(np.argmin(np.sum(singles, axis=0))) + 1
    return {"cell": f"{name} {sigma} {model}", "sigma_hat": s / float(mean_edge_length(clean)),
            "best_angle": int(np.argmin(angle)) + 1, "best_tilt": int(np.argmin(tilt)) + 1,
            "pairs": pairs, "antithetic": antithetic, "every": every, "angle": angle}


def _err(angle: np.ndarray, counts) -> str:
    values = [angle[c - 1] for c in counts]
    return f"{min(values):.2f}–{max(values):.2f}" if len(values) > 1 else f"{values[0]:.2f}"


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--cells", nargs="*", default=list(CELLS), help="mesh:sigma:model (model iso or nor)")
    args = ap.parse_args()
    lines = ["# The iteration count picked by two recorruption draws (Taubin, λ = 0.5)", "",
             "Regenerate: `.venv/bin/python experiments/denoise/draw_noise.py` (needs ../shared/meshes).", "",
             "Noise seed 0, σ in ℓ̄ of the clean mesh; σ̂: the chooser's estimate. Counts picked from eight "
             "independent pairs of draws (the chooser's two), eight antithetic pairs (z, −z), and all sixteen "
             "draws; the mean face-normal angle error (°) at those counts, against the least over every count "
             f"up to {COUNT} (the best angle) and at the count of least squared edge tilt against the clean mesh.",
             "", "| cell | σ̂/ℓ̄ | best angle: count, ° | least tilt: count, ° | independent pairs: counts, ° "
             "| antithetic pairs: counts, ° | 16 draws: count, ° |", "|---" * 7 + "|"]
    for spec in args.cells:
        name, sigma, model = spec.split(":")
        r = cell(name, float(sigma), model)
        a = r["angle"]
        lines.append(f"| {r['cell']} | {r['sigma_hat']:.3f} | {r['best_angle']}, {a[r['best_angle'] - 1]:.2f} "
                     f"| {r['best_tilt']}, {a[r['best_tilt'] - 1]:.2f} | {min(r['pairs'])}–{max(r['pairs'])}, "
                     f"{_err(a, r['pairs'])} | {min(r['antithetic'])}–{max(r['antithetic'])}, "
                     f"{_err(a, r['antithetic'])} | {r['every']}, {a[r['every'] - 1]:.2f} |")
        print(lines[-1], flush=True)
    (RESULTS / "draw_noise.md").write_text("\n".join(lines) + "\n")


if __name__ == "__main__":
    main()
