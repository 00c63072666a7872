"""``jaxmesh demo``: noise the shipped bunny, denoise it with the kernel flow, Taubin
smoothing and the blind default (``jaxmesh denoise`` without ``--method``), print the
errors before and after, write the meshes."""

from __future__ import annotations

import time
from pathlib import Path

from .. import data
from ..denoise import METHODS
from ..io import save
from ..noise import add_noise
from ..transforms import normalize
from ..metrics import error_summary as errors
from ._common import CLIError, check_output

NAMES = {"clean": "bunny_clean.ply", "noisy": "bunny_noisy.ply", "kernel": "bunny_kernel.ply",
         "taubin": "bunny_taubin.ply", "auto": "bunny_auto.ply"}


def configure(p) -> None:
    p.add_argument("--out", default="jaxmesh-demo", help="directory for the meshes (default ./jaxmesh-demo)")
    p.add_argument("--sigma", type=float, default=0.3, help="noise, in mean edge lengths (default 0.3)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--force", action="store_true", help="replace existing output files")
    p.add_argument("--no-auto", action="store_true",
                   help="leave out the blind default (its search takes most of the demo's time)")


def _auto(noisy):
    """The blind default's result and its label."""
    import warnings

    from ..tune import BlindTuningWarning, choose_denoiser

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", BlindTuningWarning)     # the demo prints its errors
        choice = choose_denoiser(noisy)
    what = choice.method if choice.method != "blend" else " + ".join(m for m, _, _ in choice.components)
    return f"auto, blind ({what})", choice.mesh


def _output_folder(out: Path, files, force: bool) -> None:
    """Refuse, before any work, outputs that could not be written; make the folder (and its
    parents) when it does not exist yet, as ``mkdir -p`` does."""
    if out.exists() and not out.is_dir():
        raise CLIError(f"{out} exists and is not a directory; name a folder with --out")
    if not out.exists():
        try:
            out.mkdir(parents=True)
        except OSError as err:
            raise CLIError(f"{out}: cannot create the folder ({err.strerror or type(err).__name__})") from None
    for f in files:
        check_output(str(out / f), force)


def run(args) -> int:
    out = Path(args.out)
    names = {k: v for k, v in NAMES.items() if not (args.no_auto and k == "auto")}
    _output_folder(out, names.values(), args.force)
    clean = normalize(data.load_sample("bunny", dtype="float64"))
    noisy = add_noise(clean, args.sigma, args.seed)
    rows = [("noisy input", noisy, 0.0)]
    for name in ("kernel", "taubin"):
        t = time.perf_counter()
        res = METHODS[name](noisy)
        res.vertices.block_until_ready()
        ps = " ".join(f"{k}={v}" for k, v in METHODS[name].defaults().items() if k in ("lam", "mu", "iterations"))
        rows.append((f"{name} ({ps})", res, time.perf_counter() - t))
    if not args.no_auto:
        t = time.perf_counter()
        label, res = _auto(noisy)
        rows.append((label, res, time.perf_counter() - t))
    for key, mesh in zip(names, (clean, noisy, *(r[1] for r in rows[1:]))):
        save(mesh, out / names[key], overwrite=args.force)
    print(f"Stanford bunny ({clean.num_vertices} vertices, unit bounding-box diagonal), "
          f"Gaussian noise sigma = {args.sigma:g} mean edge lengths, seed {args.seed}")
    width = max(36, *(len(r[0]) for r in rows))
    print(f"{'mesh':<{width}} {'visual error E':>15} {'normal error':>13} {'time':>7}")
    base = errors(clean, noisy)
    for label, mesh, sec in rows:
        e = errors(clean, mesh)
        print(f"{label:<{width}} {e['visual_error']:>9.3e} {e['visual_error'] / base['visual_error']:>4.2f}x "
              f"{e['normal_angle_deg']:>11.2f}° {sec:>6.2f}s")
    print(f"wrote {', '.join(str(out / n) for n in names.values())}")
    return 0
