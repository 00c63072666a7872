"""``jaxmesh denoise --out-dir DIR IN ...``: a whole dataset through
:func:`jaxmesh.dataset.denoise_files` (size buckets, one compiled program per
bucket shape, resumable, failures reported and skipped)."""

from __future__ import annotations

import json
import sys

from ._common import CLIError

__all__ = ["dataset_arguments", "run_dataset"]


def dataset_arguments(p) -> None:
    p.add_argument("--out-dir", metavar="DIR",
                   help="denoise every IN (files, directories of meshes, glob patterns) into DIR, in size "
                        "buckets; outputs that exist are skipped (resume) unless --force")
    p.add_argument("--batch-size", type=int, default=16, metavar="N", help="meshes per compiled call (--out-dir)")
    p.add_argument("--ladder", type=float, default=2 ** 0.25, metavar="R",
                   help="ratio between padded mesh sizes (--out-dir; larger: fewer compiles, more padding)")
    p.add_argument("--report", metavar="FILE", help="append one JSON line per mesh to FILE (--out-dir)")
    p.add_argument("--suffix", metavar=".EXT", help="output format for --out-dir (default: the input's)")
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
    bad = [flag for flag, on in (("--reference", args.reference), ("--tune", args.tune),
                                 ("--raw-units", args.raw_units), ("--noise-sigma", args.noise_sigma is not None))
           if on]
    if bad:
        raise CLIError(f"{', '.join(bad)}: not supported with --out-dir (one setting for every mesh)")
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
    summary = denoise_files(args.paths, args.out_dir, args.method, given, batch_size=args.batch_size,
                            ladder=args.ladder, overwrite=args.force, suffix=args.suffix, report=args.report, progress=_progress)
    for rec in summary.records:
        if rec["status"] == "failed":
            where = "" if rec["input"] in rec["error"] else f"{rec['input']}: "
            print(f"jaxmesh: error: {where}{rec['error']}", file=sys.stderr)
    s = summary.as_dict()
    if args.json:
        print(json.dumps(s))
    else:
        print(f"{s['done']} written, {s['skipped']} skipped (exist), {s['failed']} failed -> {args.out_dir}; "
              f"{s['compiles']} compiled batch shapes, padding waste {100 * s['padding_waste']:.0f}%, "
              f"{s['seconds']:.2f} s")
    return 1 if summary.failed else 0
