"""Train the learned denoiser shipped with jaxmesh (``jaxmesh/data/learned.jxl``).

    .venv/bin/python experiments/learn/train_default.py [--steps N] [--seed S] [--force]
        [--shape plain|full] [--objective angle|log] [--output FILE] [--curve PNG]
    .venv/bin/python experiments/learn/train_default.py --verify 50   # rerun to step 50, compare

Training meshes: the shared scans cow, maxplanck, shark, human, and armadillo and igea
decimated to about 8k vertices, plus five synthetic CAD shapes (``shapes.py``).
Validation: fertility and eight.  Kept out of both for evaluation
(``evaluate.py``): fandisk, spot, camelhead, bunny.  Every mesh scaled to a unit
bounding-box diagonal.  Noise drawn on the fly (:class:`jaxmesh.learn.NoiseRange`):
isotropic and along-the-normals Gaussian, σ log-uniform in 0.05–0.8ℓ̄ with 0.35–0.45ℓ̄
held out, and impulsive.  Checkpoints go to ``experiments/results/learn/checkpoint.jxl``
(a killed run resumes from it; it is removed when the model is written).

Writes jaxmesh/data/learned.jxl, jaxmesh/data/learned.json (training meshes, noise,
seed, settings, validation history, the step kept (least validation error), the file's
SHA-256, wall time) and
docs/images/learn-validation.png (the validation curve).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import jax

jax.config.update("jax_enable_x64", True)

import jaxmesh  # noqa: E402
from jaxmesh.cli.train import progress_bar, write_curve  # noqa: E402
from jaxmesh.hashing.attacks import simplify  # noqa: E402
from jaxmesh.learn import (DEFAULT_MODEL, ModelConfig, NoiseRange, TrainConfig, example, file_sha256,  # noqa: E402
                           save_model, train)

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parent))
from shapes import SHAPES, shape  # noqa: E402
from shared_meshes import ROOT, load  # noqa: E402

RESULTS = ROOT / "experiments" / "results" / "learn"
#: scans used whole / decimated to about DECIMATED_VERTICES vertices
SCANS = ("cow", "maxplanck", "shark", "human")
DECIMATED = ("armadillo", "igea")
DECIMATED_VERTICES = 8000
VALIDATION = ("fertility", "eight")
EVALUATION = ("fandisk", "spot", "camelhead", "bunny")
NOISE = NoiseRange(holdout=(0.35, 0.45))
#: the model shapes: ``plain`` (the shipped model) and ``full`` (an impulse-repair stage of
#: 5 rounds, gated normal filtering, tail features), and the objectives (TrainConfig.objective)
SHAPES_OF_MODEL = {"plain": ModelConfig(), "full": ModelConfig(repair_rounds=5, gated=True, tail_features=True)}


def training_meshes() -> list[tuple[str, jaxmesh.Mesh]]:
    out = [(name, jaxmesh.normalize(load(name))) for name in SCANS]
    for name in DECIMATED:
        mesh = load(name)
        out.append((f"{name} (decimated)", jaxmesh.normalize(simplify(mesh, DECIMATED_VERTICES / mesh.num_vertices))))
    return out + [(f"{name} (synthetic)", shape(name)) for name in SHAPES]


class _Stop(Exception):
    pass


#: settings added after a record may have been written, at the values that mean "not used"
ADDED_SETTINGS = (", objective='angle'", ", repair_rounds=0, gated=False, tail_features=False")


def same_settings(config: TrainConfig, recorded: str) -> bool:
    """Whether ``config`` is the recorded settings; a setting the record predates counts as
    the same when ``config`` has it at its "not used" value (ADDED_SETTINGS)."""
    now = repr(config)
    for added in ADDED_SETTINGS:
        if added.split("=")[0] not in recorded:
            now = now.replace(added, "")
    return now == recorded


def verify(k: int, output: Path) -> None:
    """Rerun the shipped model's training (same settings and seed) up to step ``k`` and
    compare its validation figure with the one recorded at that step."""
    record = json.loads(output.with_suffix(".json").read_text())
    want = next((r["validation"] for r in record["history"] if r["step"] == k), None)
    if want is None:
        raise SystemExit(f"the record has no validation at step {k} (it has {[r['step'] for r in record['history']]})")
    config = TrainConfig(steps=int(record["settings"].split("steps=")[1].split(",")[0]), seed=record["seed"],
                         noise=NOISE)
    if not same_settings(config, record["settings"]):
        raise SystemExit("the recorded settings are not this script's: rerun the training instead")
    train_set = [example(name, mesh) for name, mesh in training_meshes()]
    validation = [example(name, jaxmesh.normalize(load(name))) for name in VALIDATION]
    got = {}

    def stop(step, loss, rec):
        if rec is not None and step == k:
            got["validation"] = rec["validation"]
            raise _Stop

    start = time.perf_counter()
    try:
        train(train_set, validation, config, report=stop)
    except _Stop:
        pass
    same = f"{got['validation']:.3g}" == f"{want:.3g}"
    print(f"step {k}: validation {got['validation']:.6f} deg now, {want:.6f} recorded: "
          f"{'the same' if same else 'DIFFERENT'} to 3 digits ({time.perf_counter() - start:.0f} s)")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--steps", type=int, default=TrainConfig.steps)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--output", type=Path, default=DEFAULT_MODEL)
    ap.add_argument("--curve", type=Path, default=ROOT / "docs" / "images" / "learn-validation.png",
                    help="where to draw the validation curve")
    ap.add_argument("--force", action="store_true", help="replace the output model")
    ap.add_argument("--shape", choices=sorted(SHAPES_OF_MODEL), default="plain",
                    help="the model's shape (default plain, the shipped model's)")
    ap.add_argument("--objective", choices=("angle", "log"), default="angle",
                    help="the training objective (default angle, the shipped model's)")
    ap.add_argument("--verify", type=int, metavar="K",
                    help="rerun the recorded training up to its K-th step (a multiple of 25) and compare the "
                         "validation there with the record (writes nothing)")
    args = ap.parse_args()
    if args.verify:
        return verify(args.verify, args.output)
    if args.output.exists() and not args.force:
        raise SystemExit(f"{args.output} exists: --force to replace it")
    RESULTS.mkdir(parents=True, exist_ok=True)
    config = TrainConfig(steps=args.steps, seed=args.seed, noise=NOISE, model=SHAPES_OF_MODEL[args.shape],
                         objective=args.objective)
    start = time.perf_counter()
    train_set = [example(name, mesh) for name, mesh in training_meshes()]
    validation = [example(name, jaxmesh.normalize(load(name))) for name in VALIDATION]
    checkpoint = RESULTS / "checkpoint.jxl"
    with progress_bar(config.steps) as report:
        result = train(train_set, validation, config, checkpoint=checkpoint, report=report)
    seconds = time.perf_counter() - start
    meta = {"training_meshes": [[ex.name, ex.clean.num_vertices] for ex in train_set],
            "validation_meshes": list(VALIDATION), "evaluation_meshes": list(EVALUATION),
            "noise": vars(NOISE), "seed": args.seed, "settings": repr(config), "history": result.history,
            "best_step": result.best_step,
            "train_seconds": round(seconds, 1), "script": "experiments/learn/train_default.py"}
    save_model(args.output, result.model, meta, overwrite=args.force)
    record = {**meta, "model_file": args.output.name, "sha256": file_sha256(args.output)}
    args.output.with_suffix(".json").write_text(json.dumps(record, indent=1) + "\n")
    write_curve(result.history, args.curve, overwrite=True)
    checkpoint.unlink(missing_ok=True)
    best = next(r for r in result.history if r["step"] == result.best_step)
    print(f"trained in {seconds / 60:.1f} min: validation {best['validation']:.3f} deg (step {result.best_step}); "
          f"sha256 {record['sha256'][:16]}; wrote {args.output}")


if __name__ == "__main__":
    main()
