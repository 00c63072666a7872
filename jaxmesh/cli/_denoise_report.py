"""What ``jaxmesh denoise`` prints: a summary line (or one JSON object), how the
parameters were chosen, and the errors against ``--reference``."""

from __future__ import annotations

import json

from ..metrics import error_summary as errors


def _errors_lines(summary: dict) -> None:
    for key in ("visual_error", "normal_angle_deg"):
        b, a = summary["before"][key], summary["after"][key]
        print(f"  {key:<17} before {b:.6g}  after {a:.6g}" + (f"  ({a / b:.3f}x)" if b else ""))


def _add_errors(summary: dict, mesh, reference, result) -> None:
    if reference is not None:
        summary["before"], summary["after"] = errors(reference, mesh), errors(reference, result)


def report_run(args, label, out, mesh, reference, run, caveats, seconds) -> int:
    summary = {"input": label, "output": out, "method": run.method, "params": run.params,
               "seconds": round(seconds, 3)}
    t = run.tuning
    if t is not None:
        summary["tuned"] = {"names": list(run.tuned), "mode": "blind" if reference is None else "supervised",
                            "evaluations": int(t.evaluations), "converged": bool(t.converged),
                            "relative_loss": float(t.loss)}
        if reference is None:
            summary["tuned"].update(noise_sigma=float(t.sigma), estimated_visual_error=float(t.error),
                                    estimated_relative_error=float(t.loss))
            summary["warnings"] = caveats
    _add_errors(summary, mesh, reference, run.mesh)
    if args.json:
        print(json.dumps(summary))
        return 0
    ps = " ".join(f"{k}={v!r}" if isinstance(v, float) else f"{k}={v}" for k, v in run.params.items())
    print(f"{label} -> {out}: {run.method} {ps} ({seconds:.2f} s)")  # every digit: rerunnable
    if t is not None:
        s = summary["tuned"]
        how = (f"blind, noise sigma {s['noise_sigma']:.4g} ({'given' if args.noise_sigma else 'estimated'}), "
               f"estimated visual error {s['estimated_visual_error']:.6g}" if reference is None
               else "supervised against the reference")
        print(f"  tuned {', '.join(run.tuned)} ({how}; {s['evaluations']} flow evaluations"
              f"{'' if s['converged'] else ', NOT converged'})")
    if reference is not None:
        _errors_lines(summary)
    return 0


def _settings(params: dict) -> str:
    return " ".join(f"{k}={v:g}" for k, v in params.items())


def _estimate(choice) -> str:
    """The chosen denoiser's estimated RMS normal error, or why there is none (a negative
    estimate, which clamping would print as 0.00°)."""
    if choice.risk < 0:
        return (f"unknown (the estimate is negative, {choice.risk:.3g} rad²: the noise level is likely "
                "overestimated)")
    return f"{choice.rms_tilt_degrees:.2f}°"


def report_auto(args, label, out, mesh, reference, choice, caveats, seconds) -> int:
    summary = {"input": label, "output": out, "method": choice.method, "params": choice.params,
               "seconds": round(seconds, 3), "auto": choice.summary(), "warnings": caveats}
    _add_errors(summary, mesh, reference, choice.mesh)
    if args.json:
        print(json.dumps(summary))
        return 0
    if choice.method == "none":
        print(f"{label} -> {out}: written unchanged, the mesh reads as noise-free ({seconds:.2f} s)")
        if reference is not None:
            _errors_lines(summary)
        return 0
    if choice.method == "blend":
        what = "a blend, " + " + ".join(f"{w:.3g} x {m} {_settings(p)}" for m, p, w in choice.components)
    else:
        what = f"{choice.method} {_settings(choice.params)}"
    print(f"{label} -> {out}: auto chose {what} ({seconds:.2f} s)")
    if choice.search_vertices < mesh.num_vertices:
        print(f"  ranked on patches of {choice.search_vertices} of the {mesh.num_vertices} vertices "
              "(--search-vertices all: on the whole mesh)")
    if choice.noise_law == "impulsive":
        print(f"  impulsive noise: {choice.fraction:.0%} of the vertices displaced along their normals, sigma "
              f"{choice.sigma:.4g} ({'estimated' if choice.estimated else 'given'}); "
              + (f"estimated RMS normal error {_estimate(choice)} vs "
                 f"{summary['auto']['noisy_rms_normal_error_deg']:.2f}° for the input (held-out estimate on the "
                 "vertices read as untouched)" if choice.estimator == "held_out" else
                 f"recorrupted estimate under that law {choice.risk:.3g} vs {choice.noisy_risk:.3g} for the input "
                 "(a ranking: its level is biased)"))
    else:
        model = {"auto": "estimated", "normal": "noise along the normals", "isotropic": "isotropic noise"}[
            args.noise_model or "auto"]
        print(f"  noise sigma {choice.sigma:.4g} ({'estimated' if choice.estimated else 'given'}), "
              f"{choice.tangential_sigma:.4g} within the surface ({model}); estimated RMS "
              f"normal error {_estimate(choice)} vs {summary['auto']['noisy_rms_normal_error_deg']:.2f}° "
              "for the input (recorrupted estimate, both at 1.12x the noise)")
    if choice.method == "blend":
        best = choice.table[0]
        print(f"  best single setting: {best.method} {_settings(best.params)} (estimate {best.risk:.3g}; the blend's, on "
              f"fresh draws, {choice.risk:.3g})")
    else:
        runner = next((r for r in choice.table if r.method != choice.method), None)
        if runner is not None:
            print(f"  best other method: {runner.method} {runner.params} (estimate {runner.risk:.3g} vs "
                  f"{choice.risk:.3g})")
    if reference is not None:
        _errors_lines(summary)
    return 0


#: meshes with fewer vertices get no progress bar: their runs take seconds, and a progress hook
#: would cost them a compile (below)
BAR_VERTICES = 100_000


def progress_bar(name: str, total: int, vertices: int):
    """A tqdm bar on stderr fed by :func:`jaxmesh.denoise.progress`, for a terminal and a mesh of
    at least :data:`BAR_VERTICES` vertices; elsewhere no hook at all.  The hook is traced into
    the method's loop, so a run inside it compiles its program anew instead of using the kept
    (and stored) one: about 0.7 s for the kernel flow on a 3k-vertex mesh.

    Arguments:
        name: the bar's label.
        total: the iterations.
        vertices: the mesh's vertices.

    Returns:
        A context manager."""
    import contextlib
    import sys

    from ..denoise import progress

    if vertices < BAR_VERTICES or not sys.stderr.isatty():
        return contextlib.nullcontext()
    try:
        from tqdm.auto import tqdm
    except ImportError:  # the bar is a convenience
        return contextlib.nullcontext()
    bar = tqdm(total=total, desc=name, unit="it", file=sys.stderr, leave=False)

    @contextlib.contextmanager
    def managed():
        with progress(lambda i: bar.update(1)):
            try:
                yield
            finally:
                bar.close()

    return managed()
