"""Why blind auto stops Taubin early under heavy isotropic noise: the edge length
that scales the recorrupted estimate's tilt.

    .venv/bin/python experiments/denoise/tilt_lengths.py

The chooser ranks denoisers by ‖A u‖²/F with (A u)_{f,e} = ν_f · (u_b − u_c) / ℓ̄
(:mod:`jaxmesh.tune.recorrupt`): one length, the mean ℓ̄, for every edge.  Here the
estimate's noise is taken out of the question: each cell's Taubin path (its λ from
the chooser's grid, μ = −λ, counts 1..120) is scored with the clean mesh in hand,
by the mean face-normal angle itself and by the tilt ‖A(x_k − x)‖²/F with A built
five ways: the clean face normals with ℓ̄, with each edge's clean length, with the
edge lengths of the chooser's pilot (guided filtering at its defaults; each at
least 0.3ℓ̄), of the noisy mesh (same floor) and of the output x_k itself.  The
table gives each score's least count and the mean angle there: a score whose
least count is far below the angle's stops the path early.

Writes experiments/results/denoise/tilt_lengths.md.
"""

from __future__ import annotations

import sys
from pathlib import Path

import jax

jax.config.update("jax_enable_x64", True)

import jax.numpy as jnp  # noqa: E402
import numpy as np  # noqa: E402

import jaxmesh  # noqa: E402
from jaxmesh.denoise import METHODS  # noqa: E402
from jaxmesh.geometry import face_normals, mean_edge_length  # noqa: E402
from jaxmesh.host import HostMesh  # noqa: E402
from jaxmesh.tune.race import run_setting  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from shared_meshes import load  # noqa: E402

RESULTS = Path(__file__).resolve().parents[2] / "experiments" / "results" / "denoise"
#: (mesh, σ in ℓ̄, noise model, Taubin's λ): the feature table's cells where auto exceeds 1.02× the tuned
#: Taubin, and three where it does not
CELLS = (("spot", 0.5, "isotropic", 0.5), ("cow", 0.5, "isotropic", 0.35), ("spot", 0.3, "isotropic", 0.5),
         ("cow", 0.3, "isotropic", 0.2), ("cow", 0.1, "normal", 0.35), ("fandisk", 0.3, "normal", 0.35),
         ("bunny", 0.3, "isotropic", 0.35), ("maxplanck", 0.3, "normal", 0.35))
COUNTS = 120
FLOOR = 0.3
SCORES = ("mean angle", "ℓ̄", "clean edges", "pilot edges", "noisy edges", "output edges")


def edge_lengths(x, faces):
    """|x_b − x_c| for the edge opposite each corner, (F, 3)."""
    p = x[faces]
    return jnp.linalg.norm(p[:, [2, 0, 1]] - p[:, [1, 2, 0]], axis=-1)


def tilt(u, nu, faces, lengths) -> float:
    """‖A u‖²/F with (A u)_{f,e} = ν_f · (u_b − u_c) / ℓ_{f,e}."""
    h = jnp.sum(u[faces] * nu[:, None, :], axis=-1)
    d = (h[:, [1, 2, 0]] - h[:, [2, 0, 1]]) / lengths
    return float(jnp.mean(jnp.sum(d * d, axis=-1)))


def cell(name: str, sigma: float, model: str, lam: float) -> dict:
    clean = jaxmesh.normalize(load(name))
    noisy = jaxmesh.add_noise(clean, sigma, jax.random.PRNGKey(0), along_normals=model == "normal")
    faces, nu = noisy.faces, face_normals(clean)
    ell = float(mean_edge_length(noisy))
    pilot = run_setting(noisy, noisy.vertices, "guided_normal", {}, HostMesh(noisy).aux("guided_normal"))
    fixed = {"ℓ̄": ell, "clean edges": edge_lengths(clean.vertices, faces),
             "pilot edges": jnp.maximum(edge_lengths(pilot, faces), FLOOR * ell),
             "noisy edges": jnp.maximum(edge_lengths(noisy.vertices, faces), FLOOR * ell)}
    taubin = METHODS["taubin"]
    aux = taubin.prepare(noisy)
    step = jax.jit(lambda x: taubin(noisy.with_vertices(x), lam=lam, mu=-lam, iterations=1, **aux).vertices)
    angle = jax.jit(lambda x: jnp.mean(jnp.degrees(jnp.arccos(jnp.clip(
        jnp.sum(face_normals(noisy.with_vertices(x)) * nu, axis=-1), -1, 1)))))
    x, rows = noisy.vertices, []
    for _ in range(COUNTS):
        x = step(x)
        u = x - clean.vertices
        rows.append([float(angle(x))] + [tilt(u, nu, faces, v) for v in fixed.values()]
                    + [tilt(u, nu, faces, edge_lengths(x, faces))])
    scores = np.asarray(rows)
    least = scores.argmin(axis=0)
    return {"mesh": name, "sigma": sigma, "model": model, "lam": lam,
            "least": {s: (int(k) + 1, float(scores[k, 0])) for s, k in zip(SCORES, least)}}


def main() -> None:
    rows = [cell(*c) for c in CELLS]
    lines = ["# The tilt's edge lengths: each score's least Taubin count", "",
             "Regenerate: `.venv/bin/python experiments/denoise/tilt_lengths.py` (needs ../shared/meshes).", "",
             "Seed 0, meshes at unit diagonal. Taubin with λ from the chooser's grid, μ = −λ, counts 1.."
             f"{COUNTS}, scored with the clean mesh in hand: the mean face-normal angle, and the tilt "
             "‖A(x_k − x)‖²/F (clean face normals) with each edge's length taken as the mean ℓ̄, the clean "
             f"edge's, the pilot's, the noisy mesh's (each at least {FLOOR}ℓ̄) or the output's own. "
             "Each cell: the least count, and the mean angle (degrees) there.", "",
             "| mesh | σ | noise | λ | " + " | ".join(SCORES) + " |", "|" + "---|" * (4 + len(SCORES))]
    for r in rows:
        cells = " | ".join(f"{k} ({e:.3f}°)" for k, e in (r["least"][s] for s in SCORES))
        lines.append(f"| {r['mesh']} | {r['sigma']} | {r['model'][:3]} | {r['lam']} | {cells} |")
    RESULTS.mkdir(parents=True, exist_ok=True)
    (RESULTS / "tilt_lengths.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
