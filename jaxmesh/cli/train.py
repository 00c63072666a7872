"""``jaxmesh train CLEAN_DIR [--noisy NOISY_DIR] -o MODEL``: train a learned denoiser
(:mod:`jaxmesh.learn`) on your own meshes.

Every mesh file in CLEAN_DIR (OBJ, PLY, OFF, STL) is a clean example.  With ``--noisy``,
NOISY_DIR holds a real noisy copy of each, with the same file name and the same
connectivity; otherwise noise is drawn on the fly (Gaussian, isotropic and along the
normals, σ in ``--sigma LO HI`` mean edge lengths, and impulsive).  ``--validate N``
meshes (default: one in five, none when there are fewer than three) are held out and
measured every ``--validate-every`` steps, and the model written is the one with the
least validation error; ``--curve PNG`` plots that curve.  A
checkpoint (``MODEL.ckpt``) is written as training goes and removed at the end: run the
same command again after a kill and it resumes.
"""

from __future__ import annotations

import contextlib
import io
import math
import sys
from pathlib import Path

from ._common import CLIError, check_output

__all__ = ["configure", "run", "progress_bar", "write_curve", "find_pairs"]

_SUFFIXES = (".obj", ".ply", ".off", ".stl")


def configure(p) -> None:
    p.add_argument("clean", metavar="CLEAN_DIR", help="folder of clean meshes")
    p.add_argument("--noisy", metavar="NOISY_DIR",
                   help="folder of real noisy copies, matched to CLEAN_DIR by file name (same connectivity)")
    p.add_argument("-o", "--output", required=True, metavar="MODEL", help="model file to write (e.g. model.jxl)")
    p.add_argument("--steps", type=int, default=300, help="optimiser steps (default 300)")
    p.add_argument("--batch", type=int, default=4, help="meshes per step (default 4)")
    p.add_argument("--learning-rate", type=float, default=0.02, help="Adam's step size (default 0.02)")
    p.add_argument("--sigma", type=float, nargs=2, default=(0.05, 0.8), metavar=("LO", "HI"),
                   help="synthetic Gaussian noise range, in mean edge lengths (default 0.05 0.8)")
    p.add_argument("--validate", type=int, default=None, metavar="N",
                   help="meshes held out for validation (default: one in five, 0 with fewer than 3)")
    p.add_argument("--validate-every", type=int, default=25, metavar="K", help="validate every K steps (default 25)")
    p.add_argument("--curve", metavar="PNG", help="write the validation curve as a PNG (needs matplotlib)")
    p.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    p.add_argument("--force", action="store_true", help="replace MODEL (and the curve) if they exist")


def _mesh_files(folder: str, what: str) -> dict[str, Path]:
    d = Path(folder)
    if not d.is_dir():
        raise CLIError(f"{what} {folder} is not a directory")
    files = {p.name: p for p in sorted(d.iterdir()) if p.is_file() and p.suffix.lower() in _SUFFIXES}
    if not files:
        raise CLIError(f"{what} {folder} holds no mesh file ({', '.join(_SUFFIXES)})")
    return files


def find_pairs(clean_dir: str, noisy_dir: str | None) -> list[tuple[str, Path, Path | None]]:
    """(name, clean file, noisy file or None) for each mesh file of ``clean_dir``, the noisy
    copy matched by file name in ``noisy_dir``; a file on one side only is an error naming it.

    Arguments:
        clean_dir: the folder of clean meshes.
        noisy_dir: the folder of noisy copies, or None (synthetic noise).

    Returns:
        The pairs, sorted by name."""
    clean = _mesh_files(clean_dir, "CLEAN_DIR")
    if noisy_dir is None:
        return [(name, path, None) for name, path in clean.items()]
    noisy = _mesh_files(noisy_dir, "NOISY_DIR")
    for name in clean:
        if name not in noisy:
            raise CLIError(f"{name}: in CLEAN_DIR but not in NOISY_DIR {noisy_dir} (pairs are matched by file name)")
    for name in noisy:
        if name not in clean:
            raise CLIError(f"{name}: in NOISY_DIR but not in CLEAN_DIR {clean_dir} (pairs are matched by file name)")
    return [(name, clean[name], noisy[name]) for name in clean]


@contextlib.contextmanager
def progress_bar(total: int):
    """A ``report(step, loss, record)`` callback for :func:`jaxmesh.learn.train` drawing a
    tqdm bar on stderr (shown on a terminal only) with the loss and the last validation.

    Arguments:
        total: the number of steps.

    Returns:
        A context manager giving the callback."""
    from tqdm.auto import tqdm

    bar = tqdm(total=total, desc="training", unit="step", file=sys.stderr, disable=None)
    state = {"validation": None}

    def report(step: int, loss: float, record: dict | None) -> None:
        if record is not None and record.get("validation") is not None:
            state["validation"] = record["validation"]
        bar.n = step
        post = {"loss": f"{loss:.3f}"}
        if state["validation"] is not None:
            post["validation"] = f"{state['validation']:.3f}°"
        bar.set_postfix(post, refresh=False)
        bar.refresh()

    try:
        yield report
    finally:
        bar.close()


def write_curve(history: list[dict], path: str | Path, overwrite: bool = False) -> None:
    """Plot the training loss and the validation error against the step as a PNG (atomically).

    Arguments:
        history: :attr:`jaxmesh.learn.TrainResult.history`.
        path: the PNG to write.
        overwrite: replace an existing file.

    Returns:
        None."""
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        raise CLIError("--curve needs matplotlib (pip install matplotlib)") from None
    from ..io import write_bytes_atomic

    steps = [r["step"] for r in history]
    fig, ax = plt.subplots(figsize=(6, 3.6), dpi=110)
    ax.plot(steps, [r["loss"] for r in history], "o-", label="training loss (angle° + position term)")
    val = [(r["step"], r["validation"]) for r in history if r.get("validation") is not None]
    if val:
        ax.plot(*zip(*val), "s-", label="validation: mean normal error (°)")
    ax.set_xlabel("step")
    ax.grid(alpha=0.3)
    ax.legend()
    fig.tight_layout()
    buf = io.BytesIO()
    fig.savefig(buf, format="png")
    plt.close(fig)
    write_bytes_atomic(path, buf.getvalue(), overwrite=overwrite)


def _examples(pairs, validate: int | None):
    from ..io import load
    from ..learn import example

    out = []
    for name, clean_path, noisy_path in pairs:
        clean = load(clean_path)
        noisy = None if noisy_path is None else load(noisy_path)
        out.append(example(name, clean, noisy))
    n = len(out)
    k = (n // 5 if n >= 3 else 0) if validate is None else validate
    if not 0 <= k < n:
        raise CLIError(f"--validate must leave at least one training mesh: 0 <= N < {n}, got {k}")
    held = set(range(n - 1, -1, -max(1, n // k))[:k]) if k else set()
    return [e for i, e in enumerate(out) if i not in held], [e for i, e in enumerate(out) if i in held]


def run(args) -> int:
    from ..learn import NoiseRange, TrainConfig, save_model, train

    check_output(args.output, args.force)
    if args.curve:
        check_output(args.curve, args.force)
    lo, hi = args.sigma
    if not (math.isfinite(lo) and math.isfinite(hi) and 0 < lo <= hi):
        raise CLIError(f"--sigma must be 0 < LO <= HI, got {lo} {hi}")
    config = TrainConfig(steps=args.steps, batch=args.batch, learning_rate=args.learning_rate, seed=args.seed,
                         validate_every=args.validate_every, noise=NoiseRange(sigma=(lo, hi)))
    config.check()
    pairs = find_pairs(args.clean, args.noisy)
    examples, validation = _examples(pairs, args.validate)
    checkpoint = Path(str(args.output) + ".ckpt")
    print(f"jaxmesh: training on {len(examples)} mesh(es), validating on {len(validation)}; checkpoint "
          f"{checkpoint}", file=sys.stderr)
    with progress_bar(config.steps) as report:
        result = train(examples, validation, config, checkpoint=checkpoint, report=report)
    meta = {"training_meshes": [e.name for e in examples], "validation_meshes": [e.name for e in validation],
            "noise": "given pairs" if args.noisy else vars(config.noise), "seed": args.seed,
            "settings": repr(config), "history": result.history, "best_step": result.best_step}
    save_model(args.output, result.model, meta, overwrite=args.force)
    if args.curve:
        write_curve(result.history, args.curve, overwrite=args.force)
    checkpoint.unlink(missing_ok=True)
    best = next((r for r in result.history if r["step"] == result.best_step), {})
    tail = (f", validation {best['validation']:.3f}° (the model of step {result.best_step}, the least validation "
            "error)" if best.get("validation") is not None else "")
    print(f"jaxmesh: wrote {args.output}: {config.steps} steps, loss {best.get('loss', float('nan')):.3f}{tail}",
          file=sys.stderr)
    return 0
