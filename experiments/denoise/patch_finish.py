"""Finishing the patch search on the whole mesh: does one look at the whole
surface bring the patches' choice to the whole-mesh search's, and at what cost?

    .venv/bin/python experiments/denoise/patch_finish.py [--mesh bunny] [--keys 0 1 2] [--draws 1]
        [--ranking-draws 2]

``choose_denoiser`` ranks a large mesh's candidates on patches
(:mod:`jaxmesh.tune.patches`) and runs only its choice on the whole mesh.  Two
ways to correct that choice with ``--draws`` recorruptions of the whole mesh (the
chooser's noise law and pilot, read on the whole mesh), each against the plain
patch choice:

* **count**: each search-path component of the choice (a Taubin or local
  bilateral setting, :mod:`jaxmesh.tune.paths`) gets its iteration count picked
  again: the blend's edge tilt with that component run 1, 2, … times and the
  others as chosen, the least summed squared tilt over the draws;
* **leaders**: the leaders of the patch ranking (the best row of each family:
  each fixed method, each path) are run on the whole mesh's recorruptions, and
  the winner and the best blend of two are chosen there by the chooser's own
  rule (:func:`~jaxmesh.tune.blend.best_mixture`,
  :func:`~jaxmesh.tune.blend.worth_blending`).

For each cell (the mesh at unit diagonal, σ ∈ {0.1, 0.3, 0.5}ℓ̄, isotropic or
along the clean normals, seed 0) and chooser key: the mean face-normal error of
each output over the whole-mesh search's, whose errors are read from
``patch_search_whole.json`` (``patch_search.py --whole-keys``; the mean over the
keys saved there), and the seconds each finish adds to the patch call (2 cores).
``--ranking-draws``: the patch ranking's recorruptions (``choose_denoiser(draws=)``,
default 2, the library's).  Writes experiments/results/denoise/patch_finish[_dN].md
(``_dN`` for N ranking draws other than 2).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import jax

jax.config.update("jax_enable_x64", True)

import numpy as np  # noqa: E402

import jaxmesh  # noqa: E402
from jaxmesh.geometry import mean_edge_length  # noqa: E402
from jaxmesh.host import HostMesh  # noqa: E402
from jaxmesh.metrics import mean_normal_angle_error  # noqa: E402
from jaxmesh.tune import PATHS, auto, choose_denoiser  # noqa: E402
from jaxmesh.tune.auto_result import Component  # noqa: E402
from jaxmesh.tune.blend import best_mixture, tilt_gram, worth_blending  # noqa: E402
from jaxmesh.tune.race import run_setting, setting_tilt  # noqa: E402
from jaxmesh.tune.recorrupt import edge_tilt, recorruptions  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from shared_meshes import load  # noqa: E402

#: the chooser as these figures were measured: the patches' rim free (``pin_rim`` came later)
MEASURED = {"pin_rim": False}
RESULTS = Path(__file__).resolve().parents[2] / "experiments" / "results" / "denoise"
CELLS = tuple((s, m) for s in (0.1, 0.3, 0.5) for m in ("iso", "nor"))
#: the recorruption strength of the chooser's default
A = 0.5
#: folded into the whole mesh's recorruption key (independent of the chooser's draws)
SALT = 11


def family(method: str, params: dict) -> tuple:
    """("path", i) for a setting of ``PATHS[i]`` at some count, else ("fixed", method)."""
    for i, path in enumerate(PATHS):
        fixed = dict(path.fixed)
        rest = {k: v for k, v in params.items() if k != "iterations" and k not in fixed}
        if (method == path.method and "iterations" in params and rest in [dict(s) for s in path.settings]
                and all(params.get(k) == v for k, v in fixed.items())):
            return ("path", i)
    return ("fixed", method)


class Whole:
    """The whole mesh's recorruptions (the chooser's law and pilot) and its filter runs."""

    def __init__(self, noisy, key: int, draws: int):
        self.noisy, self.host = noisy, HostMesh(noisy)
        self.ell = float(mean_edge_length(noisy))
        law = auto._noise_law(self.host, None, "auto")
        y = noisy.vertices
        pilot = noisy.with_vertices(run_setting(noisy, y, "guided_normal", {}, self.aux("guided_normal")))
        self.nu, n = auto._pilot_normals(pilot)
        zs, trace = recorruptions(noisy, self.nu, n, self.ell, law["vertex_sigma"], law["tangential"], draws, key,
                                  salt=SALT)
        self.inputs, self.targets = auto._recorrupted_pair(y, zs, A)
        self.constant = (1 + 1 / A**2) * trace

    def aux(self, method: str) -> dict:
        return self.host.aux(method)

    def tilts(self, c) -> np.ndarray:
        """A(f(ŷ_d) − ỹ_d) of one (method, params), (D, F, 3)."""
        counted = family(c.method, c.params)[0] == "path"
        return np.stack([np.asarray(setting_tilt(self.noisy, x, t, self.nu, self.ell, c.method, c.params,
                                                 self.aux(c.method), counted))
                         for x, t in zip(self.inputs, self.targets)])

    def curve(self, c, rest: np.ndarray) -> np.ndarray:
        """Σ_d ‖rest_d + w A(f_t(ŷ_d) − ỹ_d)‖² for t = 1 … the path's last count."""
        path = PATHS[family(c.method, c.params)[1]]
        one, out = {**c.params, "iterations": 1}, np.zeros(path.max_iterations)
        for d, (x, target) in enumerate(zip(self.inputs, self.targets)):
            for t in range(path.max_iterations):
                x = run_setting(self.noisy, x, c.method, one, self.aux(c.method), True)
                tilt = np.asarray(edge_tilt(self.noisy, self.nu, self.ell, x - target))
                out[t] += float(np.sum((rest[d] + c.weight * tilt) ** 2))
        return out


def refine_counts(whole: Whole, components) -> list:
    """*count* (module docstring): each path component's count picked again, in turn."""
    comps = list(components)
    tilts = [whole.tilts(c) for c in comps]
    for j, c in enumerate(comps):
        if family(c.method, c.params)[0] != "path":
            continue
        rest = sum((comps[i].weight * tilts[i] for i in range(len(comps)) if i != j), np.zeros_like(tilts[j]))
        comps[j] = c._replace(params={**c.params, "iterations": int(np.argmin(whole.curve(c, rest))) + 1})
        tilts[j] = whole.tilts(comps[j])
    return comps


def judge_leaders(whole: Whole, table) -> list:
    """*leaders* (module docstring): the patch ranking's best row of each family, judged on the whole mesh."""
    leaders = {}
    for row in table:                          # the rows raced to the end first, best first
        leaders.setdefault(family(row.method, row.params), row)
    rows = list(leaders.values())
    gram = tilt_gram(np.stack([whole.tilts(Component(r.method, r.params, 1.0)) for r in rows]))
    winner = int(np.argmin(np.diag(gram)))
    mix, total = best_mixture(gram, winner, 2)
    if len(mix) > 1 and worth_blending(gram, winner, total, whole.constant,
                                       whole.noisy.num_faces * len(whole.inputs)):
        return [Component(rows[i].method, rows[i].params, w) for i, w in mix]
    return [Component(rows[winner].method, rows[winner].params, 1.0)]


def output(whole: Whole, components):
    """The blend of ``components`` run on the noisy mesh."""
    runs = [np.asarray(run_setting(whole.noisy, whole.noisy.vertices, c.method, c.params, whole.aux(c.method),
                                   family(c.method, c.params)[0] == "path")) for c in components]
    return whole.noisy.with_vertices(sum(c.weight * x for c, x in zip(components, runs)))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--mesh", default="bunny")
    ap.add_argument("--keys", nargs="+", type=int, default=[0, 1, 2], help="the chooser's keys (default 0 1 2)")
    ap.add_argument("--draws", type=int, default=1, help="the whole mesh's recorruptions (default 1)")
    ap.add_argument("--ranking-draws", type=int, default=2, help="the patch ranking's recorruptions (default 2)")
    args = ap.parse_args()
    saved = RESULTS / "patch_search_whole.json"
    if not saved.is_file():
        raise SystemExit(f"{saved} not found: run experiments/denoise/patch_search.py first")
    whole_runs = json.loads(saved.read_text())
    clean = jaxmesh.normalize(load(args.mesh))
    suffix = "" if args.ranking_draws == 2 else f"_d{args.ranking_draws}"
    flags = "" if args.ranking_draws == 2 else f" --ranking-draws {args.ranking_draws}"
    lines = [f"# Finishing the patch search on the whole mesh ({args.mesh}, keys "
             f"{', '.join(map(str, args.keys))}, {args.ranking_draws} ranking draws, {args.draws} whole-mesh draw(s))",
             "", f"Regenerate: `.venv/bin/python experiments/denoise/patch_finish.py{flags}` (after `patch_search.py "
             "--whole-keys 0 1 2`). Errors over the whole-mesh search's (mean of its saved keys); mean over "
             "the chooser's keys, the worst key in brackets; seconds added to the patch call, mean.", "",
             "| σ/ℓ̄ | model | whole ° | patches | count | leaders | count s | leaders s |",
             "|---|---|---|---|---|---|---|---|"]
    summary = {"patches": [], "count": [], "leaders": []}
    for sigma, model in CELLS:
        noisy = jaxmesh.add_noise(clean, sigma, 0, along_normals=model == "nor")
        cell = f"{args.mesh} {sigma} {model}"
        e_whole = np.mean([v["normal_deg"] for k, v in whole_runs.items() if k == cell or k.startswith(cell + " key")])
        errs, secs = {name: [] for name in summary}, {"count": [], "leaders": []}
        for key in args.keys:
            r = choose_denoiser(noisy, key=key, draws=args.ranking_draws, **MEASURED)
            errs["patches"].append(float(mean_normal_angle_error(clean, r.mesh)))
            start = time.perf_counter()
            whole = Whole(noisy, key, args.draws)
            setup = time.perf_counter() - start
            for name, finish in (("count", lambda: refine_counts(whole, r.components)),
                                 ("leaders", lambda: judge_leaders(whole, r.table))):
                start = time.perf_counter()
                out = output(whole, finish())
                secs[name].append(setup + time.perf_counter() - start)
                errs[name].append(float(mean_normal_angle_error(clean, out)))
        cols = []
        for name in summary:
            ratios = np.asarray(errs[name]) / e_whole
            summary[name].append((ratios.mean(), ratios.max()))
            cols.append(f"{ratios.mean():.3f} ({ratios.max():.3f})")
        lines.append(f"| {sigma} | {model} | {e_whole:.3f} | {' | '.join(cols)} | {np.mean(secs['count']):.1f} | "
                     f"{np.mean(secs['leaders']):.1f} |")
        print(lines[-1], flush=True)
    lines.append("")
    for name, rows in summary.items():
        means = [m for m, _ in rows]
        lines.append(f"- {name}: mean ratio {np.mean(means):.3f}, worst cell {max(means):.3f}, within 1.02 in "
                     f"{sum(m <= 1.02 for m in means)} of {len(means)} cells, worst key {max(w for _, w in rows):.3f}")
    RESULTS.mkdir(parents=True, exist_ok=True)
    (RESULTS / f"patch_finish{suffix}.md").write_text("\n".join(lines) + "\n")


if __name__ == "__main__":
    main()
