"""Why the choice ranked on patches strays from the whole mesh's: the noise the
patches' cores hold, against the choices made there.

    .venv/bin/python experiments/denoise/patch_bias.py [--mesh bunny] [--cells 0.3:nor 0.5:nor] [--keys 0 1 2]

The recorrupted estimate (:mod:`jaxmesh.tune.recorrupt`) is unbiased over the
noise n and the draws z, not given them: for a filter that keeps a share ρ of
its input's noise (f(ŷ) − x ≈ b + ρ(n + a z)) it exceeds its mean by
(1 − ρ)² (‖An‖² − tr AᵀAΣ) + (ρa + 1/a)² (‖Az‖² − tr AᵀAΣ).  More draws shrink
the second part, not the first: where the counted faces hold less noise than
expected, filters that remove more of it are estimated better than they are.
On the whole mesh the realized noise is close to σ; on the cores of the patches
(about ``SEARCH_VERTICES`` vertices) it is not.  This script puts the two side
by side.  For each cell (mesh at unit diagonal, σ in ℓ̄, noise isotropic or
along the clean normals, seed 0) and each chooser key: the realized RMS noise of
the core vertices (per noise dimension) over σ, the noise estimate read on the
patch mesh over the one read on the whole mesh, the least estimated risk of the
ranking (its draws) and of the choice (the blend's draws), the choice's true
mean normal error and the choice; then the same on the whole mesh (key 0).
A second table says where each key's extra error lies: the faces in bands of
hop distance from the mesh's boundary (its holes), each band's share of the
faces and of the summed excess angle Σ_f (θ_f(patch choice) − θ_f(whole choice)).
Writes experiments/results/denoise/patch_bias.md.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import jax

jax.config.update("jax_enable_x64", True)

import numpy as np  # noqa: E402
from scipy.sparse import csgraph  # noqa: E402

import jaxmesh  # noqa: E402
from jaxmesh._private import PATCH_STREAM, library_key  # noqa: E402
from jaxmesh.geometry import face_normals, mean_edge_length  # noqa: E402
from jaxmesh.metrics import mean_normal_angle_error  # noqa: E402
from jaxmesh.tune import choose_denoiser, estimate_noise, sample_patches  # noqa: E402
from jaxmesh.sparse import adjacency_matrix  # noqa: E402
from jaxmesh.topology import boundary_edges  # noqa: E402
from jaxmesh.tune.patches import SEARCH_VERTICES  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from shared_meshes import load  # noqa: E402

#: the chooser as these figures were measured: the patches' rim free (``pin_rim`` came later)
MEASURED = {"pin_rim": False}
RESULTS = Path(__file__).resolve().parents[2] / "experiments" / "results" / "denoise"
#: the bands of hop distance from the mesh's boundary of the second table
BANDS = ((0, 3), (3, 10), (10, 30), (30, None))


def boundary_hops(mesh) -> np.ndarray:
    """Each face's least hop distance (over its vertices) from a boundary vertex; inf without a boundary."""
    ends = np.unique(boundary_edges(mesh))
    if not len(ends):
        return np.full(mesh.num_faces, np.inf)
    hops = csgraph.dijkstra(adjacency_matrix(mesh), directed=False, unweighted=True, indices=ends, min_only=True)
    return hops[np.asarray(mesh.faces)].min(axis=1)


def face_angles(clean, mesh) -> np.ndarray:
    """θ_f: each face's normal angle to the clean one, degrees."""
    dots = np.sum(np.asarray(face_normals(clean)) * np.asarray(face_normals(mesh)), axis=1)
    return np.degrees(np.arccos(np.clip(dots, -1.0, 1.0)))


def describe(result) -> str:
    """The choice: each component's method, its searched count (if any) and weight."""
    parts = []
    for c in result.components:
        extra = {k: v for k, v in c.params.items() if k in ("sigma_s", "sigma_r", "lam", "iterations")}
        parts.append(f"{c.weight:.2f} {c.method} {extra}")
    return " + ".join(parts)


def core_noise(noisy, clean, key: int, dims: int) -> tuple[float, object]:
    """(the realized RMS noise per dimension on the patches' core vertices, the patches) for ``key``,
    drawn as :func:`~jaxmesh.tune.choose_denoiser` draws them."""
    seed = int(jax.random.randint(library_key(key, PATCH_STREAM), (), 0, np.iinfo(np.int32).max))
    patches = sample_patches(noisy, SEARCH_VERTICES, seed=seed)
    core = np.unique(np.asarray(patches.mesh.faces)[np.asarray(patches.core_faces)])
    vertices = np.asarray(patches.vertices)[core]
    n = np.asarray(noisy.vertices - clean.vertices)[vertices]
    return float(np.sqrt(np.sum(n ** 2) / (len(n) * dims))), patches


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--mesh", default="bunny")
    ap.add_argument("--cells", nargs="*", default=["0.3:nor", "0.5:nor"], help="SIGMA:MODEL, MODEL iso or nor")
    ap.add_argument("--keys", nargs="*", type=int, default=[0, 1, 2])
    args = ap.parse_args()
    clean = jaxmesh.normalize(load(args.mesh))
    ell = float(mean_edge_length(clean))
    lines = [f"# The noise on the patches' cores, and the choice ranked there ({args.mesh})", "",
             "Regenerate: `.venv/bin/python experiments/denoise/patch_bias.py` (needs ../shared/meshes).", "",
             "| σ/ℓ̄ | model | ranked on | core noise RMS / σ | σ̂ patches / σ̂ whole | ranking's least risk | "
             "choice's risk | error ° | choice |", "|---|---|---|---|---|---|---|---|---|"]
    hops = boundary_hops(clean)
    bands = [(hops >= lo) & (hops < (np.inf if hi is None else hi)) for lo, hi in BANDS]
    names = [f"{lo}–{hi}" if hi is not None else f"{lo}+" for lo, hi in BANDS]
    where = ["", "Where each key's extra error lies, by the faces' hop distance from the mesh's boundary: each band's "
             "share of the faces, then of the summed excess angle of the patch choice over the whole mesh's.", "",
             "| σ/ℓ̄ | model | key | excess ° (mean) | "
             + " | ".join(f"{n} rings: faces / excess" for n in names) + " |",
             "|---|---|---|---|" + "---|" * len(names)]
    for spec in args.cells:
        sigma, model = float(spec.split(":")[0]), spec.split(":")[1]
        noisy = jaxmesh.add_noise(clean, sigma, 0, along_normals=model == "nor")
        dims = 1 if model == "nor" else 3
        whole_sigma = estimate_noise(noisy)
        everywhere = float(np.sqrt(np.sum(np.asarray(noisy.vertices - clean.vertices) ** 2)
                                   / (noisy.num_vertices * dims)))
        whole = choose_denoiser(noisy, search_vertices=None, **MEASURED)
        whole_angles = face_angles(clean, whole.mesh)
        for key in args.keys:
            rms, patches = core_noise(noisy, clean, key, dims)
            r = choose_denoiser(noisy, key=key, **MEASURED)
            e = float(mean_normal_angle_error(clean, r.mesh))
            lines.append(f"| {sigma} | {model} | patches, key {key} | {rms / (sigma * ell):.3f} | "
                         f"{estimate_noise(patches.mesh) / whole_sigma:.3f} | {r.table[0].risk:.4f} | {r.risk:.4f} | "
                         f"{e:.3f} | {describe(r)} |")
            print(lines[-1], flush=True)
            excess = face_angles(clean, r.mesh) - whole_angles
            shares = [f"{b.mean():.3f} / {excess[b].sum() / excess.sum():.3f}" for b in bands]
            where.append(f"| {sigma} | {model} | {key} | {excess.mean():.3f} | " + " | ".join(shares) + " |")
        e = float(mean_normal_angle_error(clean, whole.mesh))
        lines.append(f"| {sigma} | {model} | whole mesh | {everywhere / (sigma * ell):.3f} | 1 | "
                     f"{whole.table[0].risk:.4f} | {whole.risk:.4f} | {e:.3f} | {describe(whole)} |")
        print(lines[-1], flush=True)
    RESULTS.mkdir(parents=True, exist_ok=True)
    (RESULTS / "patch_bias.md").write_text("\n".join(lines + where) + "\n")


if __name__ == "__main__":
    main()
