"""Ranking the blind chooser's candidates on patches of a large mesh: is the
choice the whole mesh's, and what does it save?

    .venv/bin/python experiments/denoise/patch_search.py [--meshes bunny] [--search-vertices 2000]
        [--draws independent|pairs] [--ranking-draws 2]
        [--keys 0 1 2] [--whole-keys 0 1 2] [--margin 2] [--free-rim] [--reuse-whole]

For each mesh (unit bounding-box diagonal) × σ ∈ {0.1, 0.3, 0.5}ℓ̄ × both noise
models (isotropic; along the clean normals), seed 0: ``choose_denoiser`` ranked
on the whole mesh (``search_vertices=None``) and on patches (the default,
:mod:`jaxmesh.tune.patches`), each in a process-warm call; the mean
face-normal error of each output against the clean mesh, their ratio, and the
wall-clock time of each call (2 CPU cores here; the first cell's times include
compiling).  ``--draws`` sets the recorruptions of the patch ranking:
independent (the library's default) or antithetic pairs; ``--ranking-draws``
their number (``choose_denoiser(draws=)``, default 2, the library's).
``--margin``: the rings around each core
(:data:`~jaxmesh.tune.patches.PATCH_MARGIN`, which ``choose_denoiser`` does not
take: the script hands it to the chooser's ``sample_patches``).  ``--free-rim``:
the patches' rim is left free through the search paths' iterations
(``choose_denoiser(pin_rim=False)``) instead of held at the pilot's positions.
``--keys``: the
chooser's keys for the patch ranking (each draws its own patches and
recorruptions): with several, each cell gives the mean error over the keys and
the worst key's ratio, since one draw of the patches moves the ratio by a few
percent.  ``--whole-keys``: the keys of the whole-mesh ranking (default 0); with
several, the whole column is the mean over them (its own draws move it too) and
the table adds the whole keys' range.
The whole-mesh results are saved to ``patch_search_whole.json`` (one entry per key);
``--reuse-whole`` reads them from there instead of recomputing them (they do
not depend on the patch ranking's options; rerun without it after a change to
the chooser).  Writes
experiments/results/denoise/patch_search[_DRAWS][_dN][_mN][_freerim][_svN][_keysK][_wholeK].md
(``_dN`` for N ranking draws other than 2, ``_mN`` for N margin rings other
than the library's, ``_svN`` for a ``--search-vertices`` other than the
library's, ``_keysK`` for K keys, ``_wholeK`` for K whole-mesh keys).
"""

from __future__ import annotations

import argparse
import functools
import json
import sys
import time
from pathlib import Path

import jax
import numpy as np

jax.config.update("jax_enable_x64", True)

import jaxmesh  # noqa: E402
from jaxmesh.metrics import mean_normal_angle_error  # noqa: E402
from jaxmesh.tune import auto, choose_denoiser  # noqa: E402
from jaxmesh.tune.patches import PATCH_MARGIN, SEARCH_VERTICES, sample_patches  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from shared_meshes import load  # noqa: E402

RESULTS = Path(__file__).resolve().parents[2] / "experiments" / "results" / "denoise"
CELLS = tuple((s, m) for s in (0.1, 0.3, 0.5) for m in ("iso", "nor"))
DRAWS = {"independent": False, "pairs": True}


def whole_name(cell: str, key: int) -> str:
    """The whole-mesh result's name in the saved json (key 0's is the cell's own name)."""
    return cell if key == 0 else f"{cell} key {key}"


def run(noisy, clean, **kw):
    t = time.perf_counter()
    r = choose_denoiser(noisy, **kw)
    return float(mean_normal_angle_error(clean, r.mesh)), time.perf_counter() - t, r.search_vertices


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--meshes", nargs="*", default=["bunny"])
    ap.add_argument("--search-vertices", type=int, default=SEARCH_VERTICES)
    ap.add_argument("--draws", choices=sorted(DRAWS), default="independent")
    ap.add_argument("--ranking-draws", type=int, default=2, help="the patch ranking's recorruptions (default 2)")
    ap.add_argument("--margin", type=int, default=PATCH_MARGIN, help=f"rings around each core (default {PATCH_MARGIN})")
    ap.add_argument("--free-rim", action="store_true", help="leave the patches' rim free (pin_rim=False)")
    ap.add_argument("--keys", nargs="+", type=int, default=[0], help="the patch ranking's keys (default 0)")
    ap.add_argument("--whole-keys", nargs="+", type=int, default=[0],
                    help="the whole-mesh ranking's keys (default 0); the whole column is their mean")
    ap.add_argument("--reuse-whole", action="store_true", help="read the whole-mesh results from the last full run")
    args = ap.parse_args()
    if args.margin != PATCH_MARGIN:      # the chooser draws its patches through this name
        auto.sample_patches = functools.partial(sample_patches, margin=args.margin)
    saved = RESULTS / "patch_search_whole.json"
    whole = json.loads(saved.read_text()) if args.reuse_whole else {}
    keys = f"keys {', '.join(map(str, args.keys))}"
    whole_keys = f"whole-mesh keys {', '.join(map(str, args.whole_keys))}"
    rim = "free rim" if args.free_rim else "rim held"
    lines = [f"# Patch search (search_vertices={args.search_vertices}, margin {args.margin}, {rim}, {args.ranking_draws} "
             f"{args.draws} draws, {keys}) against the whole-mesh search ({whole_keys})", "",
             "| mesh | σ/ℓ̄ | model | whole ° (mean) | whole keys' range ° | patches ° (mean) | ratio (mean) | "
             "worst key's ratio | whole s (mean) | patches s (mean) | searched V |",
             "|---|---|---|---|---|---|---|---|---|---|---|"]
    ratios, worst = [], []
    for name in args.meshes:
        clean = jaxmesh.normalize(load(name))
        for sigma, model in CELLS:
            noisy = jaxmesh.add_noise(clean, sigma, 0, along_normals=model == "nor")
            cell = f"{name} {sigma} {model}"
            for k in args.whole_keys:
                if whole_name(cell, k) not in whole:
                    e_k, t_k, _ = run(noisy, clean, search_vertices=None, key=k)
                    whole[whole_name(cell, k)] = {"normal_deg": e_k, "seconds": t_k}
            by_key = [whole[whole_name(cell, k)] for k in args.whole_keys]
            e_each = [w["normal_deg"] for w in by_key]
            e_w, t_w = np.mean(e_each), np.mean([w["seconds"] for w in by_key])
            runs = [run(noisy, clean, search_vertices=args.search_vertices, antithetic=DRAWS[args.draws], key=k,
                        draws=args.ranking_draws, pin_rim=not args.free_rim)
                    for k in args.keys]
            e_p, t_p = np.mean([r[0] for r in runs]), np.mean([r[1] for r in runs])
            ratios.append(e_p / e_w)
            worst.append(max(r[0] for r in runs) / e_w)
            lines.append(f"| {name} | {sigma} | {model} | {e_w:.3f} | {min(e_each):.3f}–{max(e_each):.3f} | "
                         f"{e_p:.3f} | {e_p / e_w:.3f} | {worst[-1]:.3f} | "
                         f"{t_w:.1f} | {t_p:.1f} | {runs[0][2]} |")
            print(lines[-1], flush=True)
    lines += ["", f"Ratio patches / whole (mean over the keys): mean {np.mean(ratios):.3f}, worst {max(ratios):.3f}; "
              f"within 1.02 in {sum(r <= 1.02 for r in ratios)} of {len(ratios)} cells; the worst single key: "
              f"{max(worst):.3f}."]
    RESULTS.mkdir(parents=True, exist_ok=True)
    saved.write_text(json.dumps(whole, indent=1))
    suffix = (("" if args.draws == "independent" else f"_{args.draws}")
              + ("" if args.ranking_draws == 2 else f"_d{args.ranking_draws}")
              + ("" if args.margin == PATCH_MARGIN else f"_m{args.margin}")
              + ("_freerim" if args.free_rim else "")
              + ("" if args.search_vertices == SEARCH_VERTICES else f"_sv{args.search_vertices}")
              + ("" if args.keys == [0] else f"_keys{len(args.keys)}")
              + ("" if args.whole_keys == [0] else f"_whole{len(args.whole_keys)}"))
    (RESULTS / f"patch_search{suffix}.md").write_text("\n".join(lines) + "\n")


if __name__ == "__main__":
    main()
