"""Is a clean scan's own vertex-scale roughness distinguishable from noise by its
spatial correlation?  For z_i = n_i · (K² y)_i / ‖row_i(K²)‖ (the umbrella
estimator's residual, ``jaxmesh.tune.noise_level``) this prints, per mesh, the
correlation of z between neighbours (lag 1) and between vertices two edges
apart (lag 2), on the clean mesh and for independent unit noise along its
normals.  The ``noise_level`` docstring quotes it.

    .venv/bin/python experiments/denoise/roughness_correlation.py
"""

from __future__ import annotations

import sys
from pathlib import Path

import jax

jax.config.update("jax_enable_x64", True)

import numpy as np  # noqa: E402

from jaxmesh.geometry import mean_edge_length, vertex_normals  # noqa: E402
from jaxmesh.sparse import adjacency_matrix  # noqa: E402
from jaxmesh.tune.noise_level import _normal_high_pass, umbrella_square_row_norms  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from shared_meshes import load as load_shared  # noqa: E402

MESHES = ("cow", "maxplanck", "fertility", "human", "fandisk", "bunny")


def lag_covariances(mesh, z: np.ndarray) -> tuple[float, float, float]:
    """Mean z², mean z_i z_j over neighbours, mean over vertices two edges apart."""
    a = adjacency_matrix(mesh).tocsr()
    a.data[:] = 1
    a2 = (a @ a).tocsr()
    a2.setdiag(0)
    a2 = (a2 - a.multiply(a2 > 0)).tocsr()
    a2.data[:] = 1
    a2.eliminate_zeros()
    return float(np.mean(z * z)), float(z @ (a @ z)) / a.nnz, float(z @ (a2 @ z)) / a2.nnz


def main() -> None:
    print("mesh | clean: sqrt(C0)/ℓ̄, lag-1, lag-2 correlation | independent noise: lag-1, lag-2")
    for name in MESHES:
        clean = load_shared(name)
        ell = float(mean_edge_length(clean))
        g = umbrella_square_row_norms(clean)
        normals = vertex_normals(clean, "area")
        noise = np.random.default_rng(1).standard_normal((len(g), 1)) * np.asarray(normals)
        c = lag_covariances(clean, _normal_high_pass(clean, clean.vertices, normals) / g / ell)
        n = lag_covariances(clean, _normal_high_pass(clean, noise, normals) / g)
        print(f"{name} | {np.sqrt(c[0]):.4f}, {c[1] / c[0]:+.3f}, {c[2] / c[0]:+.3f} | "
              f"{n[1] / n[0]:+.3f}, {n[2] / n[0]:+.3f}")


if __name__ == "__main__":
    main()
