"""Reading the noise law: does :func:`jaxmesh.tune.estimate_impulsive_noise`
call impulsive noise impulsive, and only that?

    .venv/bin/python experiments/denoise/impulsive_detection.py

On the twelve development meshes of ../shared/meshes (unit bounding-box
diagonal): the clean mesh; Gaussian noise σ ∈ {0.02, 0.1, 0.3, 0.5, 0.7}ℓ̄,
isotropic and along the normals (seed 0); impulsive noise σ = 0.5ℓ̄ with
p ∈ {0.1, 0.3, 0.5} (seed 1).  Each cell: the decision, and the law read
(σ̂₁ / σ̂₀ in ℓ̄, p̂).  Writes experiments/results/denoise/impulsive_detection.md.
"""

from __future__ import annotations

import sys
import warnings
from pathlib import Path

import jax

jax.config.update("jax_enable_x64", True)

import jaxmesh  # noqa: E402
from jaxmesh.geometry import mean_edge_length  # noqa: E402
from jaxmesh.tune.impulsive import estimate_impulsive_noise  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from shared_meshes import MESHES, load  # noqa: E402

RESULTS = Path(__file__).resolve().parents[2] / "experiments" / "results" / "denoise"
GAUSSIAN = tuple((s, m) for s in (0.02, 0.1, 0.3, 0.5, 0.7) for m in ("iso", "nrm"))
FRACTIONS = (0.1, 0.3, 0.5)


def reading(mesh, ell: float, expect: bool) -> tuple[str, bool]:
    law = estimate_impulsive_noise(mesh)
    word = "imp" if law.impulsive else "gauss"
    text = f"{word} {law.sigma / ell:.2f}/{law.sigma0 / ell:.2f}/{law.fraction:.2f}"
    return (text if law.impulsive == expect else f"**{text}**"), law.impulsive == expect


def main() -> None:
    warnings.simplefilter("ignore", jaxmesh.MeshWarning)
    head = ["clean"] + [f"{s} {m}" for s, m in GAUSSIAN] + [f"imp p={p}" for p in FRACTIONS]
    lines = ["# Reading the noise law (impulsive or Gaussian)", "",
             "Regenerate: `.venv/bin/python experiments/denoise/impulsive_detection.py` (needs ../shared/meshes).", "",
             "Each cell: the decision and the law read, σ̂₁/σ̂₀ in mean edge lengths and p̂. Gaussian noise σ in ℓ̄ "
             "(iso: isotropic, nrm: along the normals, seed 0); impulsive: σ = 0.5ℓ̄ along the normals on a "
             "fraction p of the vertices (seed 1). Bold: a wrong decision.", "",
             "| mesh | " + " | ".join(head) + " |", "|---" * (len(head) + 1) + "|"]
    wrong = total = 0
    for name in MESHES:
        clean = jaxmesh.normalize(load(name))
        ell = float(mean_edge_length(clean))
        cells = [reading(clean, ell, False)]
        for s, m in GAUSSIAN:
            cells.append(reading(jaxmesh.add_noise(clean, s, jax.random.PRNGKey(0), along_normals=m == "nrm"), ell,
                                 False))
        for p in FRACTIONS:
            cells.append(reading(jaxmesh.add_impulsive_noise(clean, 0.5, jax.random.PRNGKey(1), fraction=p), ell,
                                 True))
        wrong += sum(not ok for _, ok in cells)
        total += len(cells)
        lines.append(f"| {name} | " + " | ".join(t for t, _ in cells) + " |")
        print(lines[-1], flush=True)
    lines += ["", f"- wrong decisions: {wrong} of {total} cells"]
    RESULTS.mkdir(parents=True, exist_ok=True)
    (RESULTS / "impulsive_detection.md").write_text("\n".join(lines) + "\n")
    print(lines[-1])


if __name__ == "__main__":
    main()
