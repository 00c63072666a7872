"""How far a refit can go under impulsive noise when the displaced vertices are known.

    .venv/bin/python experiments/denoise/impulsive_bound.py [--meshes maxplanck bunny ...]

Impulse repair (and every method that keeps the untouched vertices and refits the
others) is bounded by what the untouched vertices say about the displaced ones.  This
script gives that bound an *oracle* reading: the displaced set D and the clean vertex
normals n are taken from the clean mesh, which no blind method has, and the displaced
vertices are refitted by the thin-plate energy of impulse repair,

* **3-D**: x = argmin Σ_{i∉D} ‖x_i − y_i‖² + 10⁻³ Σ_{i∈D} ‖x_i − y_i‖² + α ‖K x‖²,
* **along the normal**: the same, with x_i = y_i + t_i n_i (only the heights free; the
  noise model moves vertices along their normals, so the tangential positions are exact),

for α ∈ ALPHAS, solved exactly (scipy); and, as pure interpolation, the untouched
vertices held exactly and only the displaced heights t free (x_i = y_i + t_i n_i, i ∈ D),

* **held, membrane**: t = argmin ‖K x‖² (each displaced vertex at the umbrella mean of its
  neighbours, where those are displaced too, jointly),
* **held, thin plate**: t = argmin ‖K² x‖².

Noise and cells as in ``impulsive_table.py``
(σ = 0.5ℓ̄ along the normals, seed 0); the oracle-tuned Taubin column is read from its
saved table.  Mean face-normal angle error in degrees.

Writes experiments/results/denoise/impulsive_bound.md.
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
import scipy.sparse as sp  # noqa: E402
import scipy.sparse.linalg as sla  # noqa: E402

from jaxmesh.geometry import vertex_normals  # noqa: E402
from jaxmesh.sparse import umbrella_matrix  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parent))
from feature_table import errors  # noqa: E402
from impulsive_table import MESHES, RESULTS, noisy_pair  # noqa: E402

ALPHAS = (0.1, 0.3)
FRACTIONS = (0.5, 0.3)
#: the data weight of a displaced vertex (impulse repair's least weight)
LEAST = 1e-3


def refit(y: np.ndarray, w: np.ndarray, alpha: float, K: sp.csr_matrix, n: np.ndarray | None) -> np.ndarray:
    """The weighted thin-plate fit of the module docstring (along ``n`` when given)."""
    if n is None:
        H = (sp.diags(w) + alpha * (K.T @ K)).tocsc()
        return np.stack([sla.spsolve(H, w * y[:, c]) for c in range(3)], axis=1)
    B = sp.vstack([K @ sp.diags(n[:, c]) for c in range(3)]).tocsr()        # K x = K y + B t
    t = sla.spsolve((sp.diags(w) + alpha * (B.T @ B)).tocsc(), -alpha * (B.T @ (K @ y).T.ravel()))
    return y + n * t[:, None]


def interpolate(y: np.ndarray, displaced: np.ndarray, n: np.ndarray, M: sp.csr_matrix) -> np.ndarray:
    """The untouched vertices held, the displaced ones' heights along ``n`` by argmin ‖M x‖²."""
    idx = np.flatnonzero(displaced)
    cols = np.arange(idx.size)
    B = sp.vstack([M @ sp.csr_matrix((n[idx, c], (idx, cols)), shape=(len(y), idx.size)) for c in range(3)]).tocsc()
    r = np.concatenate([M @ y[:, c] for c in range(3)])
    t = sla.spsolve((B.T @ B).tocsc(), -(B.T @ r))
    out = y.copy()
    out[idx] += n[idx] * t[:, None]
    return out


def cell(name: str, fraction: float) -> dict:
    clean, noisy = noisy_pair(name, fraction, 0)
    y, x = np.asarray(noisy.vertices), np.asarray(clean.vertices)
    w = np.where(np.any(y != x, axis=1), LEAST, 1.0)
    K, n = umbrella_matrix(noisy), np.asarray(vertex_normals(clean, "area"))
    out = {}
    for kind, normals in (("3-D", None), ("along the normal", n)):
        fits = [errors(clean, noisy.with_vertices(jnp.asarray(refit(y, w, a, K, normals))))["normal_deg"]
                for a in ALPHAS]
        out[kind] = min(fits)
    displaced = np.any(y != x, axis=1)
    for kind, M in (("held, membrane", K.tocsr()), ("held, thin plate", (K @ K).tocsr())):
        out[kind] = errors(clean, noisy.with_vertices(jnp.asarray(interpolate(y, displaced, n, M))))["normal_deg"]
    return out


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--meshes", nargs="*", default=list(MESHES))
    args = ap.parse_args()
    saved = {(c["mesh"], c["fraction"], c["seed"]): c
             for c in json.loads((RESULTS / "impulsive_table.json").read_text())["cells"]}
    lines = ["# Impulsive noise: the bound of a refit with the displaced vertices known", "",
             "Regenerate: `.venv/bin/python experiments/denoise/impulsive_bound.py` (needs ../shared/meshes).", "",
             "Mean face-normal angle error in degrees, seed 0, σ = 0.5ℓ̄ along the normals. Oracle refits: the "
             "displaced set and the clean normals given (module docstring), best of α ∈ "
             f"{{{', '.join(map(str, ALPHAS))}}}; *held*: the untouched vertices kept exactly, the displaced "
             "ones interpolated along the normal (no data term). Taubin and impulse repair: oracle-tuned, from "
             "`impulsive_table.json`.", "",
             "| mesh | p | Taubin | impulse repair | known set, 3-D | known set, along the normal "
             "| known set held, membrane | known set held, thin plate | best known-set / Taubin |", "|---" * 9 + "|"]
    for name in args.meshes:
        for fraction in FRACTIONS:
            row = saved[(name, fraction, 0)]["oracle"]
            bound = cell(name, fraction)
            taubin = row["taubin"]["normal_deg"]
            lines.append(f"| {name} | {fraction} | {taubin:.2f} | {row['impulse_repair']['normal_deg']:.2f} | "
                         f"{bound['3-D']:.2f} | {bound['along the normal']:.2f} | "
                         f"{bound['held, membrane']:.2f} | {bound['held, thin plate']:.2f} | "
                         f"{min(bound.values()) / taubin:.2f} |")
            print(lines[-1], flush=True)
    (RESULTS / "impulsive_bound.md").write_text("\n".join(lines) + "\n")


if __name__ == "__main__":
    main()
