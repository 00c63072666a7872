"""``jaxmesh noise``, ``jaxmesh denoise`` and ``jaxmesh demo`` (see :mod:`jaxmesh.cli`)."""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path
from typing import Callable

__all__ = ["NOISE", "DENOISE", "DEMO"]


class CLIError(ValueError):
    """Reported by :func:`jaxmesh.cli.main` as ``jaxmesh: error: ...`` (exit 1)."""


def _load_input(args):
    """The mesh named by IN or --sample, in float64 (files must not be rounded)."""
    import jax

    from . import data
    from .io import load

    jax.config.update("jax_enable_x64", True)
    if args.sample and args.input:
        raise CLIError("give either IN or --sample, not both")
    if args.sample:
        return f"sample:{args.sample}", data.load_sample(args.sample, dtype="float64")
    if not args.input:
        raise CLIError("no input mesh: name IN or use --sample NAME")
    return args.input, load(args.input)


def _mesh_source(args) -> list[tuple[str, Callable]]:
    """(label, loader) for each mesh named by MESH arguments or --sample."""
    from . import data
    from .io import load

    out = []
    for name in args.sample or []:
        out.append((f"sample:{name}", lambda name=name: data.load_sample(name)))
    for path in args.mesh or []:
        out.append((path, lambda path=path: load(path)))
    if not out:
        raise CLIError("no mesh given: name a MESH file or --sample NAME "
                       f"(samples: {', '.join(sorted(data.SAMPLES))})")
    return out


def _check_output(path: str, force: bool) -> None:
    if Path(path).exists() and not force:
        raise CLIError(f"{path} exists; use --force to replace it")


def _io_arguments(p: argparse.ArgumentParser) -> None:
    from . import data

    p.add_argument("input", nargs="?", metavar="IN", help="mesh file to read (or use --sample)")
    p.add_argument("output", nargs="?", metavar="OUT", help="mesh file to write (format from the suffix)")
    p.add_argument("--sample", choices=sorted(data.SAMPLES), help="read a sample mesh shipped with jaxmesh")
    p.add_argument("--force", action="store_true", help="replace OUT if it exists")


def _positional_output(args) -> str:
    # with --sample the single positional argument is OUT
    if args.sample and args.input and not args.output:
        args.output, args.input = args.input, None
    if not args.output:
        raise CLIError("no output file: name OUT")
    return args.output


# ---------------------------------------------------------------- noise


def _configure_noise(p: argparse.ArgumentParser) -> None:
    _io_arguments(p)
    p.add_argument("--sigma", type=float, default=0.1,
                   help="noise standard deviation, in mean edge lengths (default 0.1)")
    p.add_argument("--absolute", action="store_true", help="--sigma is in the mesh's own units")
    p.add_argument("--along-normals", action="store_true", help="displace along vertex normals only")
    p.add_argument("--seed", type=int, default=0, help="random seed (default 0)")


def _run_noise(args) -> int:
    from .io import save
    from .noise import add_noise

    out = _positional_output(args)
    label, mesh = _load_input(args)
    _check_output(out, args.force)
    if not args.sigma >= 0:
        raise CLIError(f"--sigma must be >= 0, got {args.sigma}")
    noisy = add_noise(mesh, args.sigma, args.seed, along_normals=args.along_normals,
                      relative=not args.absolute)
    save(noisy, out, overwrite=args.force)
    unit = "" if args.absolute else " mean edge lengths"
    print(f"jaxmesh: wrote {out}: {label} + Gaussian noise sigma={args.sigma:g}{unit}, seed {args.seed}",
          file=sys.stderr)
    return 0


NOISE = ("add Gaussian noise to a mesh (thesis ch.2 eq.1)", _configure_noise, _run_noise)


# ---------------------------------------------------------------- denoise


def _bool(text: str) -> bool:
    t = text.lower()
    if t in ("1", "true", "yes", "on"):
        return True
    if t in ("0", "false", "no", "off"):
        return False
    raise argparse.ArgumentTypeError(f"expected yes/no, got {text!r}")


def _float_or_auto(text: str):
    if text == "auto":
        return "auto"
    try:
        return float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number or 'auto', got {text!r}") from None


def _parameter_flags() -> dict[str, tuple[str, object]]:
    """--flag -> (parameter name, type) over every registered method."""
    from .denoise import METHODS

    flags = {}
    for method in METHODS.values():
        for name, p in method.params.items():
            if p.kind == "aux" or name in flags:
                continue
            kind = {"int": int, "continuous": _float_or_auto}.get(p.kind)
            if kind is None:
                kind = _bool if isinstance(p.default, bool) else str
            flags[name] = kind
    return flags


def _configure_denoise(p: argparse.ArgumentParser) -> None:
    _io_arguments(p)
    p.add_argument("--method", default="auto",
                   help="denoising method, or 'auto' (default): choose the method and its parameters "
                        "blind, by a recorrupted estimate of the normal error (see --list-methods)")
    p.add_argument("--list-methods", action="store_true", help="list methods and their parameters, then exit")
    for name, kind in _parameter_flags().items():
        p.add_argument("--" + name.replace("_", "-"), dest="p_" + name, type=kind, default=None,
                       metavar=name.upper(), help=argparse.SUPPRESS)
    p.add_argument("--reference", metavar="CLEAN", help="clean mesh (same connectivity): print the errors")
    p.add_argument("--raw-units", action="store_true",
                   help="run in the file's units (default: scaled to a unit bounding-box diagonal and "
                        "back, so that kernel λ means the same for every mesh)")
    p.add_argument("--tune", action="store_true",
                   help="tune every continuous parameter of the method (as if each were 'auto')")
    p.add_argument("--noise-sigma", type=float, metavar="S",
                   help="noise standard deviation in the file's units, for blind tuning "
                        "(default: estimated from the mesh)")
    p.add_argument("--json", action="store_true", help="print the summary as one JSON object")
    p.epilog = ("Method parameters are flags named after them (--lam, --iterations, --mu, ...). "
                "A continuous parameter given as 'auto' (e.g. --lam auto) is tuned: against "
                "--reference if given (supervised), else blind (Stein's unbiased risk estimate "
                "of the visual error, noise from --noise-sigma or estimated).")


def _list_methods() -> int:
    from .denoise import METHODS

    print("auto: choose the method and its parameters blind (default) [jaxmesh.tune.choose_denoiser]")
    for name, m in METHODS.items():
        print(f"{name}: {m.summary} [{m.reference}]")
        for pname, p in m.params.items():
            if p.kind == "aux":
                continue
            print(f"    --{pname.replace('_', '-'):<18} {p.default!s:<12} {p.help}")
    return 0


def _errors(reference, mesh) -> dict[str, float]:
    from .metrics import mean_normal_angle_error, visual_error

    return {"visual_error": float(visual_error(reference, mesh)),
            "normal_angle_deg": float(mean_normal_angle_error(reference, mesh))}


def _load_pair(args):
    """(label, mesh, reference or None, output path), refusing a reference of another connectivity."""
    import jax.numpy as jnp

    from .io import load

    out = _positional_output(args)
    label, mesh = _load_input(args)
    _check_output(out, args.force)
    reference = load(args.reference) if args.reference else None
    if reference is not None and (reference.num_vertices != mesh.num_vertices
                                  or not bool(jnp.all(reference.faces == mesh.faces))):
        raise CLIError(f"--reference {args.reference} does not have the connectivity of {label}")
    return label, mesh, reference, out


def _blind(fn, *args, **kwargs):
    """(fn(...), caveats): every warning raised inside is printed as a
    ``jaxmesh: warning:`` line; the blind-tuning caveats are also returned for the report."""
    import warnings

    from .tune import BlindTuningWarning

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        out = fn(*args, **kwargs)
    for w in caught:
        print(f"jaxmesh: warning: {w.message}", file=sys.stderr)
    return out, [str(w.message) for w in caught if issubclass(w.category, BlindTuningWarning)]


def _run_auto(args) -> int:
    """--method auto: jaxmesh.tune.choose_denoiser, then the same report as a named method."""
    from .io import save
    from .tune import choose_denoiser

    given = sorted(k[2:] for k, v in vars(args).items() if k.startswith("p_") and v is not None)
    if given or args.tune:
        flags = ", ".join("--" + k.replace("_", "-") for k in given) or "--tune"
        raise CLIError(f"{flags} needs a named method (--method NAME); --method auto chooses its own parameters")
    if args.noise_sigma is not None and not (args.noise_sigma > 0):
        raise CLIError(f"--noise-sigma must be > 0, got {args.noise_sigma}")
    label, mesh, reference, out = _load_pair(args)
    start = time.perf_counter()
    choice, caveats = _blind(choose_denoiser, mesh, sigma=args.noise_sigma)
    seconds = time.perf_counter() - start
    save(choice.mesh, out, overwrite=args.force)
    summary = {"input": label, "output": out, "method": choice.method, "params": choice.params,
               "seconds": round(seconds, 3), "auto": choice.summary(), "warnings": caveats}
    if reference is not None:
        summary["before"] = _errors(reference, mesh)
        summary["after"] = _errors(reference, choice.mesh)
    if args.json:
        print(json.dumps(summary))
        return 0
    ps = " ".join(f"{k}={v:g}" for k, v in choice.params.items())
    print(f"{label} -> {out}: auto chose {choice.method} {ps} ({seconds:.2f} s)")
    print(f"  noise sigma {choice.sigma:.4g} ({'estimated' if choice.estimated else 'given'}); estimated RMS "
          f"normal error {choice.rms_tilt_degrees:.2f}° vs {summary['auto']['noisy_rms_normal_error_deg']:.2f}° "
          "for the input (recorrupted estimate, both at 1.12x the noise)")
    runner = next((r for r in choice.table if r[0] != choice.method), None)
    if runner is not None:
        print(f"  best other method: {runner[0]} {runner[1]} (estimate {runner[2]:.3g} vs {choice.risk:.3g})")
    if reference is not None:
        for key in ("visual_error", "normal_angle_deg"):
            b, a = summary["before"][key], summary["after"][key]
            print(f"  {key:<17} before {b:.6g}  after {a:.6g}" + (f"  ({a / b:.3f}x)" if b else ""))
    return 0


def _run_denoise(args) -> int:
    if args.list_methods:
        return _list_methods()
    if args.method == "auto":
        return _run_auto(args)
    from .denoise import METHODS, denoise_in_unit_frame, diverged
    from .io import save

    if args.method not in METHODS:
        raise CLIError(f"unknown method {args.method!r}; choose auto or one of {', '.join(sorted(METHODS))}")
    method = METHODS[args.method]
    given = {k[2:]: v for k, v in vars(args).items() if k.startswith("p_") and v is not None}
    auto = [k for k, v in given.items() if v == "auto"]
    if args.tune:
        auto += [k for k in method.continuous if k not in given]
    for k in auto:
        if k not in method.params:
            raise CLIError(f"method {args.method!r} has no parameter {k!r}; it takes {sorted(method.params)}")
        if method.params[k].kind != "continuous":
            raise CLIError(f"{args.method}: --{k.replace('_', '-')} cannot be 'auto' (not continuous)")
        given.pop(k, None)
    params = method.resolve(**given, **{k: method.params[k].default for k in auto})
    if auto and args.raw_units:
        raise CLIError("tuning runs in the unit-diagonal frame; drop --raw-units")
    if args.noise_sigma is not None and not (args.noise_sigma > 0):
        raise CLIError(f"--noise-sigma must be > 0, got {args.noise_sigma}")
    label, mesh, reference, out = _load_pair(args)

    tuned, caveats = None, []
    if auto:
        from .tune import tune

        start = time.perf_counter()
        fixed = {k: v for k, v in params.items() if k not in auto and method.params[k].kind != "aux"}
        tuned, caveats = _blind(tune, mesh, reference, args.method, names=auto, sigma=args.noise_sigma,
                                **fixed)
        params.update({k: float(v) for k, v in tuned.params.items()})
    # the tuned values are re-run through the same call as given ones: --lam auto and
    # --lam <the λ it reports> write the same file
    run = (lambda: METHODS[args.method](mesh, **params)) if args.raw_units else \
        (lambda: denoise_in_unit_frame(mesh, args.method, **params))
    try:
        result, seconds = _run_method(args, run, params)
    except FloatingPointError as err:
        raise CLIError(f"{err}; nothing written") from None
    if args.raw_units and bool(diverged(mesh, result)):
        raise CLIError(f"{args.method} diverged (non-finite or exploding coordinates) with {params}; "
                       "nothing written. Use a larger --lam, fewer --iterations or a smaller step")
    if tuned is not None:
        seconds = time.perf_counter() - start  # tuning and the final run
    save(result, out, overwrite=args.force)

    summary = {"input": label, "output": out, "method": args.method,
               "params": {k: v for k, v in params.items() if method.params[k].kind != "aux"},
               "seconds": round(seconds, 3)}
    if tuned is not None:
        summary["tuned"] = {"names": auto, "mode": "blind" if reference is None else "supervised",
                            "evaluations": int(tuned.evaluations), "converged": bool(tuned.converged),
                            "relative_loss": float(tuned.loss)}
        if reference is None:
            summary["tuned"]["noise_sigma"] = float(tuned.sigma)
            summary["tuned"]["estimated_visual_error"] = float(tuned.error)
            summary["tuned"]["estimated_relative_error"] = float(tuned.loss)
            summary["warnings"] = caveats
    if reference is not None:
        summary["before"] = _errors(reference, mesh)
        summary["after"] = _errors(reference, result)
    if args.json:
        print(json.dumps(summary))
    else:
        ps = " ".join(f"{k}={v!r}" if isinstance(v, float) else f"{k}={v}"
                      for k, v in summary["params"].items())
        print(f"{label} -> {out}: {args.method} {ps} ({seconds:.2f} s)")
        if tuned is not None:
            t = summary["tuned"]
            how = (f"blind, noise sigma {t['noise_sigma']:.4g} "
                   f"({'given' if args.noise_sigma else 'estimated'}), "
                   f"estimated visual error {t['estimated_visual_error']:.6g}" if reference is None
                   else "supervised against the reference")
            print(f"  tuned {', '.join(auto)} ({how}; {t['evaluations']} flow evaluations"
                  f"{'' if t['converged'] else ', NOT converged'})")
        if reference is not None:
            for key in ("visual_error", "normal_angle_deg"):
                b, a = summary["before"][key], summary["after"][key]
                print(f"  {key:<17} before {b:.6g}  after {a:.6g}  ({a / b:.3f}x)" if b else
                      f"  {key:<17} before {b:.6g}  after {a:.6g}")
    return 0


def _run_method(args, run, params):
    """``run()`` with a progress bar; (result, seconds)."""
    from .denoise import progress

    start = time.perf_counter()
    total = params.get("iterations", 1)
    try:
        from tqdm.auto import tqdm
        bar = tqdm(total=total, desc=args.method, unit="it", file=sys.stderr, disable=None, leave=False)
    except ImportError:  # the bar is a convenience
        bar = None
    with progress(lambda i: bar.update(1) if bar is not None else None):
        result = run()
        result.vertices.block_until_ready()
    if bar is not None:
        bar.close()
    return result, time.perf_counter() - start


DENOISE = ("denoise a mesh with any registered method", _configure_denoise, _run_denoise)


# ---------------------------------------------------------------- demo


def _configure_demo(p: argparse.ArgumentParser) -> None:
    p.add_argument("--out", default="jaxmesh-demo", help="directory for the meshes (default ./jaxmesh-demo)")
    p.add_argument("--sigma", type=float, default=0.3, help="noise, in mean edge lengths (default 0.3)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--force", action="store_true", help="replace existing output files")


def _run_demo(args) -> int:
    import jax

    jax.config.update("jax_enable_x64", True)
    from . import data
    from .denoise import METHODS
    from .io import save
    from .noise import add_noise
    from .transforms import normalize

    out = Path(args.out)
    names = {"clean": "bunny_clean.ply", "noisy": "bunny_noisy.ply", "kernel": "bunny_kernel.ply",
             "taubin": "bunny_taubin.ply"}
    for f in names.values():
        _check_output(str(out / f), args.force)
    out.mkdir(parents=True, exist_ok=True)
    clean = normalize(data.load_sample("bunny", dtype="float64"))
    noisy = add_noise(clean, args.sigma, args.seed)
    rows = [("noisy input", noisy, 0.0)]
    for name in ("kernel", "taubin"):
        t = time.perf_counter()
        res = METHODS[name](noisy)
        res.vertices.block_until_ready()
        ps = " ".join(f"{k}={v}" for k, v in METHODS[name].defaults().items() if k in ("lam", "mu", "iterations"))
        rows.append((f"{name} ({ps})", res, time.perf_counter() - t))
    for key, mesh in zip(names, (clean, noisy, rows[1][1], rows[2][1])):
        save(mesh, out / names[key], overwrite=args.force)
    print(f"Stanford bunny ({clean.num_vertices} vertices, unit bounding-box diagonal), "
          f"Gaussian noise sigma = {args.sigma:g} mean edge lengths, seed {args.seed}")
    print(f"{'mesh':<36} {'visual error E':>15} {'normal error':>13} {'time':>7}")
    base = _errors(clean, noisy)
    for label, mesh, sec in rows:
        e = _errors(clean, mesh)
        print(f"{label:<36} {e['visual_error']:>9.3e} {e['visual_error'] / base['visual_error']:>4.2f}x "
              f"{e['normal_angle_deg']:>11.2f}° {sec:>6.2f}s")
    print(f"wrote {', '.join(str(out / n) for n in names.values())}")
    return 0


DEMO = ("denoise the shipped bunny and print the errors before and after", _configure_demo, _run_demo)
