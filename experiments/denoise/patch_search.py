"""Ranking the blind chooser's candidates on patches of a large mesh: is the
choice the whole mesh's, and what does it save?

    .venv/bin/python experiments/denoise/patch_search.py [--meshes bunny] [--search-vertices 2000]

For each mesh (unit bounding-box diagonal) × σ ∈ {0.1, 0.3, 0.5}ℓ̄ × both noise
models (isotropic; along the clean normals), seed 0: ``choose_denoiser`` ranked
on the whole mesh (``search_vertices=None``) and on patches
(:mod:`jaxmesh.tune.patches`), each in a fresh-key process-warm call; the mean
face-normal error of each output against the clean mesh, their ratio, and the
wall-clock time of each call (2 CPU cores here; the first cell's times include
compiling).  Writes experiments/results/denoise/patch_search.md.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import jax

jax.config.update("jax_enable_x64", True)

import jaxmesh  # noqa: E402
from jaxmesh.metrics import mean_normal_angle_error  # noqa: E402
from jaxmesh.tune import choose_denoiser  # noqa: E402
from jaxmesh.tune.patches import SEARCH_VERTICES  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from shared_meshes import load  # noqa: E402

RESULTS = Path(__file__).resolve().parents[2] / "experiments" / "results" / "denoise"
CELLS = tuple((s, m) for s in (0.1, 0.3, 0.5) for m in ("iso", "nor"))


def run(noisy, clean, search_vertices):
    t = time.perf_counter()
    r = choose_denoiser(noisy, search_vertices=search_vertices)
    return float(mean_normal_angle_error(clean, r.mesh)), time.perf_counter() - t, r.search_vertices


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--meshes", nargs="*", default=["bunny"])
    ap.add_argument("--search-vertices", type=int, default=SEARCH_VERTICES)
    args = ap.parse_args()
    lines = [f"# Patch search (search_vertices={args.search_vertices}) against the whole-mesh search", "",
             "| mesh | σ/ℓ̄ | model | whole ° | patches ° | ratio | whole s | patches s | searched V |",
             "|---|---|---|---|---|---|---|---|---|"]
    for name in args.meshes:
        clean = jaxmesh.normalize(load(name))
        for sigma, model in CELLS:
            noisy = jaxmesh.add_noise(clean, sigma, 0, along_normals=model == "nor")
            e_w, t_w, _ = run(noisy, clean, None)
            e_p, t_p, v_p = run(noisy, clean, args.search_vertices)
            lines.append(f"| {name} | {sigma} | {model} | {e_w:.3f} | {e_p:.3f} | {e_p / e_w:.3f} | {t_w:.1f} | "
                         f"{t_p:.1f} | {v_p} |")
            print(lines[-1], flush=True)
    RESULTS.mkdir(parents=True, exist_ok=True)
    (RESULTS / "patch_search.md").write_text("\n".join(lines) + "\n")


if __name__ == "__main__":
    main()
