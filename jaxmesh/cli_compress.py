"""``jaxmesh compress`` and ``jaxmesh decompress`` (see :mod:`jaxmesh.cli`).

    jaxmesh compress IN OUT.jxm [--keep 0.1] [--bits 12] [--basis laplacian|umbrella]
                     [--patch-size N] [--preserve-order] [--force] [--json]
    jaxmesh decompress IN.jxm OUT [--force]
    jaxmesh decompress --info IN.jxm [--json]

OUT may be ``-`` for standard output and IN.jxm ``-`` for standard input; the
report then goes to standard error.
"""

from __future__ import annotations

import argparse
import json
import sys

from .cli_denoise import CLIError, _check_output

__all__ = ["COMPRESS", "DECOMPRESS"]


def _configure_compress(p: argparse.ArgumentParser) -> None:
    from . import data

    p.add_argument("input", nargs="?", metavar="IN", help="mesh file to compress (or use --sample)")
    p.add_argument("output", nargs="?", metavar="OUT", help="compressed file to write (.jxm; - for stdout)")
    p.add_argument("--sample", choices=sorted(data.SAMPLES), help="compress a sample mesh shipped with jaxmesh")
    p.add_argument("--keep", type=float, default=0.1,
                   help="fraction of spectral coefficients kept per patch, in (0, 1] (default 0.1)")
    p.add_argument("--bits", type=int, default=12,
                   help="quantization: step = largest bounding-box side / 2^bits (default 12)")
    p.add_argument("--basis", choices=("laplacian", "umbrella"), default="laplacian",
                   help="laplacian: Karni–Gotsman L = D - A (default); umbrella: the thesis's K = D^-1 A - I")
    p.add_argument("--patch-size", type=int, default=None,
                   help="target vertices per METIS patch (default: 100/keep, clipped to 1000..3000)")
    p.add_argument("--preserve-order", action="store_true",
                   help="also store the vertex order (costs about log2(V) bits per vertex)")
    p.add_argument("--force", action="store_true", help="replace OUT if it exists")
    p.add_argument("--json", action="store_true", help="print the report as one JSON object")


def _report(args, label: str, stats: dict, error: float) -> None:
    stream = sys.stderr if args.output == "-" else sys.stdout
    if args.json:
        print(json.dumps({"input": label, "output": args.output, **stats,
                          "vertex_rms_over_diagonal": error}), file=stream, flush=True)
        return
    sec = stats["section_bits_per_vertex"]
    parts = ", ".join(f"{k} {v:.2f}" for k, v in sec.items() if v > 0)
    print(f"{label} -> {args.output}: {stats['vertices']} vertices, {stats['bytes']} bytes, "
          f"{stats['bits_per_vertex']:.3f} bits/vertex ({parts})", file=stream)
    note = f"; {stats['connectivity_note']}" if stats["connectivity_note"] else ""
    print(f"  connectivity coder: {stats['connectivity_coder']}{note}", file=stream)
    print(f"  {stats['basis']} basis, {stats['patches']} patches, {stats['coefficients']} coefficients per axis, "
          f"step {stats['step']:.3g}", file=stream)
    print(f"  vertex RMS error {error:.3e} of the bounding-box diagonal", file=stream, flush=True)


def _run_compress(args) -> int:
    import jax
    import numpy as np

    from .cli_denoise import _load_input, _positional_output
    from .compress import compress, save_compressed

    jax.config.update("jax_enable_x64", True)
    out = _positional_output(args)
    if out != "-":
        _check_output(out, args.force)
    label, mesh = _load_input(args)
    c = compress(mesh, keep=args.keep, bits=args.bits, basis=args.basis, patch_size=args.patch_size,
                 preserve_order=args.preserve_order)
    v = np.asarray(mesh.vertices, np.float64)
    diag = float(np.linalg.norm(v.max(0) - v.min(0)))
    err = float(np.sqrt(np.mean(np.sum((v[c.order] - np.asarray(c.mesh.vertices)) ** 2, axis=1))))
    if out == "-":
        sys.stdout.buffer.write(c.data)
        sys.stdout.buffer.flush()
    else:
        save_compressed(c, out, overwrite=args.force)
    _report(args, label, {"vertices": mesh.num_vertices, **c.stats}, err / diag if diag > 0 else 0.0)
    return 0


def _configure_decompress(p: argparse.ArgumentParser) -> None:
    p.add_argument("input", metavar="IN", help="compressed mesh (.jxm; - for stdin)")
    p.add_argument("output", nargs="?", metavar="OUT", help="mesh file to write (OBJ, PLY, OFF, STL)")
    p.add_argument("--info", action="store_true", help="print the file's header instead of decoding it")
    p.add_argument("--json", action="store_true", help="--info as one JSON object")
    p.add_argument("--force", action="store_true", help="replace OUT if it exists")


def _run_decompress(args) -> int:
    from pathlib import Path

    import jax

    from .compress import decompress, inspect
    from .io import MeshFileError, save

    jax.config.update("jax_enable_x64", True)  # write the decoded positions unrounded

    if args.input == "-":
        data = sys.stdin.buffer.read()
    else:
        p = Path(args.input)
        if not p.is_file():
            raise MeshFileError(f"{p}: no such file")
        data = p.read_bytes()
    try:
        if args.info:
            info = inspect(data)
            if args.json:
                print(json.dumps({"path": args.input, **info}))
            else:
                print(args.input)
                for k, v in info.items():
                    print(f"  {k.replace('_', ' ')}: {v}")
            return 0
        if not args.output:
            raise CLIError("no output file: name OUT (or use --info)")
        _check_output(args.output, args.force)
        mesh = decompress(data)
    except ValueError as err:
        if isinstance(err, CLIError):
            raise
        raise CLIError(f"{args.input}: {err}") from err
    save(mesh, args.output, overwrite=args.force)
    print(f"{args.input} -> {args.output}: {mesh.num_vertices} vertices, {mesh.num_faces} faces")
    return 0


COMPRESS = ("compress a mesh to a .jxm file (spectral geometry, lossless connectivity; ch.3)",
            _configure_compress, _run_compress)
DECOMPRESS = ("decode a .jxm file to a mesh file", _configure_decompress, _run_decompress)
