"""``jaxmesh denoise --out-dir DIR IN ...``: a whole dataset through
:func:`jaxmesh.dataset.denoise_files` (size buckets, one compiled program per
bucket shape, resumable, failures reported and skipped)."""

from __future__ import annotations

import argparse
import json
import math
import sys

from ._common import CLIError

__all__ = ["dataset_arguments", "run_dataset"]


def dataset_arguments(p) -> None:
    p.add_argument("--out-dir", metavar="DIR",
                   help="denoise every IN (files, directories of meshes, glob patterns) into DIR, in size "
                        "buckets; outputs that exist are skipped (resume) unless --force")
    p.add_argument("--batch-size", type=int, default=None, metavar="N",
                   help="meshes per compiled call (--out-dir; default 1 on CPU, 16 on GPU/TPU)")
    p.add_argument("--ladder", type=float, default=2 ** 0.5, metavar="R",
                   help="ratio between padded mesh sizes (--out-dir; default √2; larger: fewer compiles, "
                        "more padding)")
    p.add_argument("--pack", action=argparse.BooleanOptionalAction, default=None,
                   help="run the meshes as disjoint unions of up to 61,440 vertices (--out-dir; default for the "
                        "methods --list-methods marks as packed, when --batch-size is not given); --no-pack: "
                        "padded batches")
    p.add_argument("--report", metavar="FILE", help="append one JSON line per mesh to FILE (--out-dir)")
    p.add_argument("--suffix", metavar=".EXT", help="output format for --out-dir (default: the input's)")
    p.add_argument("--tune-on", type=int, default=0, metavar="N",
                   help="with --out-dir and parameters 'auto' (or --tune): tune them once on the first N inputs "
                        "(against --reference DIR if given, else blind) and apply that setting to every input")
    p.add_argument("--coordinator", metavar="HOST:PORT",
                   help="run as one of --num-processes processes (jax.distributed; --out-dir): each denoises "
                        "its share of the inputs")
    p.add_argument("--num-processes", type=int, metavar="N", help="processes in the run (with --coordinator)")
    p.add_argument("--process-id", type=int, metavar="I", help="this process, 0..N-1 (with --coordinator)")


def _progress(done: int, total: int) -> None:
    if sys.stderr.isatty():
        print(f"\rjaxmesh: {done}/{total} meshes", end="" if done < total else "\n", file=sys.stderr, flush=True)


def run_dataset(args, given: dict) -> int:
    """Exit 0 when every mesh was written or skipped, 1 when any failed (each named on stderr)."""
    from ..dataset import denoise_files

    if args.sample:
        raise CLIError("--out-dir takes mesh files, directories or globs, not --sample")
    bad = [flag for flag, on in (("--raw-units", args.raw_units), ("--noise-sigma", args.noise_sigma is not None),
                                 ("--noise-model", args.noise_model is not None)) if on]
    if bad:
        raise CLIError(f"{', '.join(bad)}: not supported with --out-dir (each mesh in its unit frame, the "
                       "noise estimated per mesh)")
    from ..tune.patches import SEARCH_VERTICES

    if args.search_vertices != SEARCH_VERTICES:
        raise CLIError(f"--search-vertices: not supported with --out-dir (every mesh is ranked with the default, "
                       f"{SEARCH_VERTICES})")
    if args.tune:
        if args.method == "auto":
            raise CLIError("--tune needs a named method (--method NAME); --method auto chooses its own parameters")
        from ..denoise import as_method

        given = {**given, **{n: "auto" for n, q in as_method(args.method).params.items()
                             if q.kind == "continuous" and n not in given}}
    if args.tune_on and "auto" not in given.values():
        raise CLIError("--tune-on N tunes the parameters given as 'auto' (--lam auto) or all of them (--tune); "
                       "name some")
    if not args.paths:
        raise CLIError("--out-dir needs at least one input (file, directory or glob)")
    cluster = (args.coordinator, args.num_processes, args.process_id)
    if any(v is not None for v in cluster):
        if any(v is None for v in cluster):
            raise CLIError("--coordinator, --num-processes and --process-id go together")
        if not 0 <= args.process_id < args.num_processes:
            raise CLIError(f"--process-id must be in 0..{args.num_processes - 1}, got {args.process_id}")
        import jax

        jax.distributed.initialize(args.coordinator, args.num_processes, args.process_id)
    if args.search_ladder is not None:
        if args.method != "auto":
            raise CLIError("--search-ladder applies to --method auto (the blind choice); drop it or the named method")
        given = {**given, "ladder": args.search_ladder}
    summary = denoise_files(args.paths, args.out_dir, args.method, given, batch_size=args.batch_size,
                            ladder=args.ladder, overwrite=args.force, suffix=args.suffix, report=args.report, progress=_progress,
                            reference=args.reference, tune_on=args.tune_on, pack=args.pack)
    for rec in summary.records:
        if rec["status"] == "failed":
            where = "" if rec["input"] in rec["error"] else f"{rec['input']}: "
            print(f"jaxmesh: error: {where}{rec['error']}", file=sys.stderr)
        elif "reference_error" in rec:
            print(f"jaxmesh: warning: {rec['input']}: {rec['reference_error']}", file=sys.stderr)
    s = summary.as_dict()
    scored = [r for r in summary.records if "after" in r]
    if scored:
        # E is in each file's units: its mean over meshes means nothing, its ratio does
        ratios = [r["after"]["visual_error"] / r["before"]["visual_error"] for r in scored
                  if r["before"]["visual_error"] > 0 and r["after"]["visual_error"] > 0]
        s["mean_errors"] = {"meshes": len(scored), "normal_angle_deg": {
            when: sum(r[when]["normal_angle_deg"] for r in scored) / len(scored) for when in ("before", "after")},
            "visual_error_ratio_geomean": math.exp(sum(map(math.log, ratios)) / len(ratios)) if ratios else None}
    tuned_on = next((r["tuned_on"] for r in summary.records if "tuned_on" in r), None)
    if tuned_on is not None:
        s["tuned_on"] = tuned_on
    if args.json:
        print(json.dumps(s))
        return 1 if summary.failed else 0
    if tuned_on is not None:
        print(f"tuned on {len(tuned_on['files'])} inputs ({'supervised' if tuned_on['supervised'] else 'blind'}): "
              + ", ".join(f"{k} = {v:.6g}" if isinstance(v, float) else f"{k} = {v}"
                          for k, v in s["tuned_on"]["params"].items()))
    print(f"{s['done']} written, {s['skipped']} skipped (exist), {s['failed']} failed -> {args.out_dir}; "
          f"{s['compiles']} compiled batch shapes, padding waste {100 * s['padding_waste']:.0f}%, "
          f"{s['seconds']:.2f} s")
    if scored:
        e = s["mean_errors"]
        ratio = e["visual_error_ratio_geomean"]
        print(f"against {args.reference} ({len(scored)} meshes): mean normal error {e['normal_angle_deg']['before']:.2f}° "
              f"-> {e['normal_angle_deg']['after']:.2f}°"
              + ("" if ratio is None else f"; visual error after / before {ratio:.3g} (geometric mean)"))
    return 1 if summary.failed else 0
