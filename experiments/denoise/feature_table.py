"""Feature-preserving denoising on the shared meshes: oracle-tuned methods
against blind ``--method auto``, mean face-normal error and E.

    .venv/bin/python experiments/denoise/feature_table.py [--meshes fandisk bunny ...] [--resume]

Cells: {fandisk, bunny, camelhead, cow, spot, maxplanck} × σ ∈ {0.1, 0.3}ℓ̄ ×
both noise models (isotropic N(0, σ²I) per vertex; N(0, σ²) along the clean
mesh's area-weighted vertex normals), seed 0, meshes scaled to a unit
bounding-box diagonal.  Oracle: the tuner with the clean mesh in hand and
objective "normal" (mean face-normal angle), continuous parameters by BFGS
from a coarse grid; Taubin's iteration count chosen from (2, 5, 10, 20, 40);
L0's λ from a grid (its gradient in λ is zero); bilateral and guided
normal filtering tune σ_s and σ_r, the tangential relaxation at its default 0.1;
*bilateral_local* is bilateral normal filtering as Zheng et al.'s local
iterative scheme (one normal pass and five vertex updates per iteration, the
chooser's bilateral path), best of a σ_s × σ_r grid × every count up to 16.  Blind: ``choose_denoiser``
(no clean mesh, σ estimated).  Plus the fandisk with noise along the normals
at 0.3ℓ̄ on seeds 0, 1, 2 (the issue's headline case), where the oracle guided
filter also chooses its normal iteration count (20, 40) and tangential
relaxation (0, 0.05, 0.1) with the clean mesh (σ_s, σ_r tuned for each).

Writes experiments/results/denoise/feature_table.{md,json}; ``--second-pilot`` reruns the
blind column of the saved cells with the race winner as a second pilot
(``choose_denoiser(second_pilot=True)``) into feature_table_pilot2.{md,json}.
"""

from __future__ import annotations

import argparse
import itertools
import json
import sys
import time
from pathlib import Path

import jax

jax.config.update("jax_enable_x64", True)

import jaxmesh  # noqa: E402
from jaxmesh.denoise import METHODS  # noqa: E402
from jaxmesh.metrics import mean_normal_angle_error, visual_error  # noqa: E402
from jaxmesh.tune import choose_denoiser, tune  # noqa: E402
from jaxmesh.tune.blend import BLEND_DRAWS, BLEND_SIZE, SNAPSHOT_FACTORS  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from shared_meshes import load as load_shared  # noqa: E402

RESULTS = Path(__file__).resolve().parents[2] / "experiments" / "results" / "denoise"
MESHES = ("spot", "cow", "maxplanck", "fandisk", "camelhead", "bunny")   # small to large
SIGMAS = (0.1, 0.3)
MODELS = ("isotropic", "normal")
ORACLE = ("taubin", "bilateral_normal", "bilateral_local", "guided_normal", "l0")
#: the oracle grid of the local iterative bilateral scheme (one normal pass, five vertex updates per iteration)
LOCAL_GRID = {"sigma_s": (0.7, 1.0, 1.5, 2.5), "sigma_r": (0.35, 0.6, 1.0, 2.0, 5.0)}
LOCAL_MAX_ITERATIONS = 16


def errors(clean, mesh) -> dict:
    return {"normal_deg": float(mean_normal_angle_error(clean, mesh)), "E": float(visual_error(clean, mesh))}


HEADLINE_GRID = {"normal_iterations": (20, 40), "tangential": (0.0, 0.05, 0.1)}


def oracle(name: str, clean, noisy, grid: dict | None = None, **fixed) -> dict:
    start = time.perf_counter()
    if grid:
        keys = list(grid)
        rows = [oracle(name, clean, noisy, None, **dict(zip(keys, vals))) for vals in itertools.product(*grid.values())]
        best = min(rows, key=lambda r: r["normal_deg"])
        return {**best, "seconds": round(time.perf_counter() - start, 1)}
    if name == "bilateral_local":
        return {**local_oracle(clean, noisy), "seconds": round(time.perf_counter() - start, 1)}
    if name == "l0":
        m = METHODS["l0"]
        aux = m.prepare(noisy)
        run = jax.jit(lambda mesh, lam, aux: m(mesh, lam=lam, **aux))
        rows = [(lam, errors(clean, run(noisy, lam, aux))) for lam in (3.0, 10.0, 30.0)]
        lam, err = min(rows, key=lambda r: r[1]["normal_deg"])
        params = {"lam": lam}
    else:
        its = (2, 5, 10, 20, 40) if name == "taubin" else None
        names = None if name == "taubin" else ("sigma_s", "sigma_r")   # tangential at its default 0.1
        r = tune(noisy, clean, name, objective="normal", iterations=its, names=names, **fixed)
        err = errors(clean, r.mesh)
        params = {**{k: float(v) for k, v in r.params.items()}, **r.fixed}
    return {"params": params, **err, "seconds": round(time.perf_counter() - start, 1)}


def local_oracle(clean, noisy) -> dict:
    """bilateral_normal with one normal pass and five vertex updates per iteration (Zheng et al.'s
    local iterative scheme, the chooser's bilateral path): the best of LOCAL_GRID × every count up to
    LOCAL_MAX_ITERATIONS, by normal error."""
    m = METHODS["bilateral_normal"]
    aux = m.prepare(noisy)
    one = jax.jit(lambda mesh, ss, sr, aux: m(mesh, sigma_s=ss, sigma_r=sr, normal_iterations=1,
                                             vertex_iterations=5, iterations=1, **aux))
    best = None
    for ss, sr in itertools.product(*LOCAL_GRID.values()):
        x = noisy
        for k in range(1, LOCAL_MAX_ITERATIONS + 1):
            x = one(x, ss, sr, aux)
            err = errors(clean, x)
            if best is None or err["normal_deg"] < best["normal_deg"]:
                best = {"params": {"sigma_s": ss, "sigma_r": sr, "normal_iterations": 1, "vertex_iterations": 5,
                                   "iterations": k}, **err}
    return best


def blind(clean, noisy, draws: int = 2, blend_draws: int = BLEND_DRAWS, blend_size: int = BLEND_SIZE,
          snapshots=SNAPSHOT_FACTORS, antithetic: bool = False, second_pilot: bool = False) -> dict:
    start = time.perf_counter()
    c = choose_denoiser(noisy, draws=draws, blend_draws=blend_draws, blend_size=blend_size, snapshots=snapshots,
                        antithetic=antithetic, second_pilot=second_pilot)
    return {"method": c.method, "params": c.params, "components": [list(x) for x in c.components],
            "improved": c.improved, "sigma_hat": c.sigma,
            "tangential_sigma": c.tangential_sigma,
            **errors(clean, c.mesh), "seconds": round(time.perf_counter() - start, 1)}


def cell(name: str, sigma: float, model: str, seed: int = 0, methods=ORACLE, grid: dict | None = None) -> dict:
    clean = jaxmesh.normalize(load_shared(name))
    noisy = jaxmesh.add_noise(clean, sigma, jax.random.PRNGKey(seed), along_normals=model == "normal")
    out = {"mesh": name, "sigma": sigma, "model": model, "seed": seed, "noisy": errors(clean, noisy),
           "sigma_true": sigma * float(jaxmesh.geometry.mean_edge_length(clean))}
    out["oracle"] = {m: oracle(m, clean, noisy, grid) for m in methods}
    out["blind"] = blind(clean, noisy)
    return out


def choice(b: dict, params: bool = False) -> str:
    """The blind choice: its method (and parameters), or the blend's weighted components."""
    if b["method"] != "blend":
        return f"{b['method']} {b['params']}" if params else b["method"]
    return " + ".join(f"{w:.2f} {m}" + (f" {p}" if params else "") for m, p, w in b["components"])


def table(rows: list[dict], flags: str = "") -> str:
    lines = ["# Feature-preserving denoising: oracle-tuned vs blind `--method auto`", "",
             f"Regenerate: `.venv/bin/python experiments/denoise/feature_table.py{flags}` (needs ../shared/meshes).", "",
             "Mean face-normal angle error in degrees (E / E_noisy in brackets for the blind choice). "
             "Oracle: tuned with the clean mesh, objective = normal error. "
             "Noise models: *iso* = isotropic σ per coordinate, *nrm* = σ along the vertex normals; "
             "σ in mean edge lengths ℓ̄; seed 0 unless stated.", "",
             "*bilateral_local*: bilateral normal filtering as the local iterative scheme (one normal pass, "
             "five vertex updates per iteration; a σ_s × σ_r grid × every count up to 16). "
             "'–': not run (`--oracles` left it out; the best oracle is over the others).", "",
             "| mesh | σ | noise | noisy | " + " | ".join(ORACLE) + " | blind auto (choice) "
             "| auto / best oracle | auto < taubin |",
             "|---" * (7 + len(ORACLE)) + "|"]
    order = {m: i for i, m in enumerate(MESHES)}
    for r in sorted(rows, key=lambda r: (order.get(r["mesh"], len(order)), r["sigma"], r["model"])):
        o = r["oracle"]
        best = min(v["normal_deg"] for v in o.values())
        b = r["blind"]
        ratio = b["normal_deg"] / best
        lines.append(
            f"| {r['mesh']} | {r['sigma']} | {r['model'][:3]} | {r['noisy']['normal_deg']:.2f} | "
            + " | ".join(f"{o[m]['normal_deg']:.2f}" if m in o else "–" for m in ORACLE)
            + f" | {b['normal_deg']:.2f} ({choice(b)}, E {b['E'] / r['noisy']['E']:.2f}) | {ratio:.2f} | "
            + ("yes" if b["normal_deg"] < o["taubin"]["normal_deg"] else "**no**") + " |")
    return "\n".join(lines + [""] + tally(rows)) + "\n"


def tally(rows: list[dict]) -> list[str]:
    """The issue's counts, per noise level: blind below the oracle Taubin, within 1.25x of the best oracle."""
    out = []
    for sigma in sorted({r["sigma"] for r in rows}):
        rs = [r for r in rows if r["sigma"] == sigma]
        ratios = [r["blind"]["normal_deg"] / min(v["normal_deg"] for v in r["oracle"].values()) for r in rs]
        below = sum(r["blind"]["normal_deg"] < r["oracle"]["taubin"]["normal_deg"] for r in rs)
        out.append(f"- σ = {sigma}ℓ̄: blind below the oracle Taubin in {below} of {len(rs)} cells, within 1.25x of "
                   f"the best oracle in {sum(x <= 1.25 for x in ratios)} of {len(rs)} (mean ratio "
                   f"{sum(ratios) / len(ratios):.3f}, worst {max(ratios):.2f})")
    return out


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--meshes", nargs="*", default=list(MESHES))
    ap.add_argument("--resume", action="store_true")
    ap.add_argument("--sigmas", nargs="*", type=float, default=list(SIGMAS),
                    help="noise levels of new cells, in ℓ̄ (default 0.1 0.3); with --resume, added to the saved ones")
    ap.add_argument("--oracles", nargs="*", default=list(ORACLE), choices=ORACLE,
                    help="the oracle columns of new cells (default all; the table shows '–' for those left out)")
    ap.add_argument("--seeds", action="store_true", help="also run the headline case on seeds 0, 1, 2")
    ap.add_argument("--redo-seeds", action="store_true", help="rerun the headline case even if it is saved")
    ap.add_argument("--report-only", action="store_true", help="write the tables from the saved json")
    ap.add_argument("--blind-only", action="store_true",
                    help="recompute the blind column of the saved cells (after a change to the chooser)")
    ap.add_argument("--oracle-only", nargs="*", default=[], metavar="METHOD",
                    help="recompute these oracle columns of the saved cells of --meshes (after a change to the "
                         "tuner)")
    ap.add_argument("--missing", action="store_true",
                    help="with --oracle-only: only the cells that do not have the column yet")
    ap.add_argument("--draws", type=int, default=2,
                    help="the blind choice's recorruptions (default 2, the library's; other values read the saved "
                         "cells and write feature_table_draws{N}.{json,md}, with --blind-only)")
    ap.add_argument("--blend-draws", type=int, default=BLEND_DRAWS,
                    help=f"the blind choice's blend draws (default {BLEND_DRAWS}, the library's; 0: no blending; "
                         "other values work as --draws, writing feature_table_blend{N}.{json,md})")
    ap.add_argument("--blend-size", type=int, default=BLEND_SIZE,
                    help=f"the most denoisers one blend mixes (default {BLEND_SIZE}, the library's; other values "
                         "work as --draws, writing ..._size{N})")
    ap.add_argument("--snapshots", nargs="*", type=float, default=list(SNAPSHOT_FACTORS),
                    help=f"the path leaders' iteration multiples added to the blend (default "
                         f"{' '.join(map(str, SNAPSHOT_FACTORS)) or 'none'}, the library's; other values work as --draws, "
                         "writing ..._snap{F-G} or ..._snap0 for none)")
    ap.add_argument("--pairs", action="store_true",
                    help="antithetic recorruption pairs (choose_denoiser(antithetic=True)); works as --draws, "
                         "writing ..._pairs")
    ap.add_argument("--second-pilot", action="store_true",
                    help="the race winner as a second pilot (choose_denoiser(second_pilot=True)); works as --draws, "
                         "writing ..._pilot2")
    args = ap.parse_args()
    snaps = tuple(args.snapshots)
    RESULTS.mkdir(parents=True, exist_ok=True)
    other = (args.draws != 2 or args.blend_draws != BLEND_DRAWS or args.blend_size != BLEND_SIZE
             or snaps != SNAPSHOT_FACTORS or args.pairs or args.second_pilot)
    snap_name = "-".join(f"{f:g}" for f in snaps) or "0"
    stem = ("feature_table" + (f"_draws{args.draws}" if args.draws != 2 else "")
            + (f"_blend{args.blend_draws}" if args.blend_draws != BLEND_DRAWS else "")
            + (f"_size{args.blend_size}" if args.blend_size != BLEND_SIZE else "")
            + (f"_snap{snap_name}" if snaps != SNAPSHOT_FACTORS else "")
            + ("_pairs" if args.pairs else "") + ("_pilot2" if args.second_pilot else ""))
    path = RESULTS / f"{stem}.json"
    if other and not (args.report_only and path.exists()):     # the saved cells, with another blind column
        done = json.loads((RESULTS / "feature_table.json").read_text())
    else:
        again = args.resume or args.blind_only or args.oracle_only or args.report_only   # these read the saved cells
        if again and not path.exists():
            raise SystemExit(f"{path} not found: run without --blind-only/--oracle-only/--report-only first")
        done = json.loads(path.read_text()) if again else {"cells": [], "seeds": []}
    have = {(r["mesh"], r["sigma"], r["model"]) for r in done["cells"]}
    if args.blind_only:
        for r in done["cells"] + ([] if args.redo_seeds else done["seeds"]):
            if r["mesh"] not in args.meshes:
                continue
            clean = jaxmesh.normalize(load_shared(r["mesh"]))
            noisy = jaxmesh.add_noise(clean, r["sigma"], jax.random.PRNGKey(r["seed"]),
                                      along_normals=r["model"] == "normal")
            r["blind"] = blind(clean, noisy, args.draws, args.blend_draws, args.blend_size, snaps, args.pairs,
                               args.second_pilot)
            print(f"{r['mesh']} {r['sigma']} {r['model']} seed {r['seed']}: auto {r['blind']['method']} "
                  f"{r['blind']['normal_deg']:.2f}", flush=True)
            path.write_text(json.dumps(done, indent=1))
    for r in done["cells"] if args.oracle_only else []:
        todo = [m for m in args.oracle_only if not (args.missing and m in r["oracle"])]
        if r["mesh"] not in args.meshes or not todo:
            continue
        clean = jaxmesh.normalize(load_shared(r["mesh"]))
        noisy = jaxmesh.add_noise(clean, r["sigma"], jax.random.PRNGKey(r["seed"]), along_normals=r["model"] == "normal")
        for m in todo:
            before = r["oracle"].get(m, {}).get("normal_deg", float("nan"))
            r["oracle"][m] = oracle(m, clean, noisy)
            print(f"{r['mesh']} {r['sigma']} {r['model']}: oracle {m} {before:.2f} -> {r['oracle'][m]['normal_deg']:.2f}",
                  flush=True)
        path.write_text(json.dumps(done, indent=1))
    for name in ([] if args.report_only else args.meshes):
        for sigma in args.sigmas:
            for model in MODELS:
                if (name, sigma, model) in have:
                    continue
                r = cell(name, sigma, model, methods=tuple(args.oracles))
                done["cells"].append(r)
                print(f"{name} {sigma} {model}: noisy {r['noisy']['normal_deg']:.2f} "
                      + " ".join(f"{m} {v['normal_deg']:.2f}" for m, v in r["oracle"].items())
                      + f" | auto {r['blind']['method']} {r['blind']['normal_deg']:.2f}", flush=True)
                path.write_text(json.dumps(done, indent=1))
    if args.redo_seeds:
        done["seeds"] = []
    if (args.seeds or args.redo_seeds) and not args.report_only and not done["seeds"]:
        for seed in (0, 1, 2):
            r = cell("fandisk", 0.3, "normal", seed, methods=("guided_normal",), grid=HEADLINE_GRID)
            done["seeds"].append(r)
            print(f"fandisk 0.3 normal seed {seed}: guided oracle {r['oracle']['guided_normal']['normal_deg']:.2f} "
                  f"auto {r['blind']['normal_deg']:.2f}", flush=True)
            path.write_text(json.dumps(done, indent=1))
    flags = ("" if not other else " --blind-only" + (f" --draws {args.draws}" if args.draws != 2 else "")
             + (f" --blend-draws {args.blend_draws}" if args.blend_draws != BLEND_DRAWS else "")
             + (f" --blend-size {args.blend_size}" if args.blend_size != BLEND_SIZE else "")
             + (" --snapshots" + "".join(f" {f:g}" for f in snaps) if snaps != SNAPSHOT_FACTORS else "")
             + (" --pairs" if args.pairs else "") + (" --second-pilot" if args.second_pilot else ""))
    text = table(done["cells"], flags)
    text += ("\n## The headline case: fandisk, noise along the normals, σ = 0.3ℓ̄\n\n"
             "Oracle guided_normal: σ_s, σ_r tuned for each normal iteration count (20, 40) and tangential "
             "relaxation (0, 0.05, 0.1), the best kept (its setting in brackets).\n\n"
             "| seed | noisy | oracle guided_normal | blind auto (choice) |\n|---|---|---|---|\n")
    for r in done["seeds"]:
        g = r["oracle"]["guided_normal"]
        setting = {k: (round(v, 3) if isinstance(v, float) else v) for k, v in g["params"].items()
                   if k in ("normal_iterations", "tangential", "sigma_s", "sigma_r")}
        text += (f"| {r['seed']} | {r['noisy']['normal_deg']:.2f} | {g['normal_deg']:.2f} ({setting}) "
                 f"| {r['blind']['normal_deg']:.2f} ({choice(r['blind'], params=True)}) |\n")
    (RESULTS / f"{stem}.md").write_text(text)
    print(text)


if __name__ == "__main__":
    main()
