"""``jaxmesh compress IN OUT.jxm``: spectral geometry, lossless connectivity (ch.3).
OUT may be ``-`` (standard output; the report then goes to standard error)."""

from __future__ import annotations

import json
import sys
from pathlib import Path

from ..compress import compress, save_compressed
import numpy as np

from ._common import (CLIError, check_output, check_view, io_arguments, load_input, names_a_mesh_format,
                      positional_output, view_argument, write_view)


def configure(p) -> None:
    io_arguments(p)
    p.add_argument("--keep", type=float, default=0.1,
                   help="fraction of spectral coefficients kept per patch, in (0, 1] (default 0.1)")
    p.add_argument("--bits", type=int, default=12,
                   help="quantization: step = largest bounding-box side / 2^bits (default 12)")
    p.add_argument("--basis", choices=("laplacian", "umbrella"), default="laplacian",
                   help="laplacian: Karni–Gotsman L = D - A (default); umbrella: the thesis's K = D^-1 A - I")
    p.add_argument("--patch-size", type=int, default=None,
                   help="target vertices per METIS patch, 16..10000 (default: 100/keep, clipped to 1000..3000)")
    p.add_argument("--preserve-order", action="store_true",
                   help="also store the vertex order (costs about log2(V) bits per vertex)")
    p.add_argument("--json", action="store_true", help="print the report as one JSON object")
    view_argument(p, "the input and its reconstruction, coloured by the vertex error")


def _report(args, out: str, label: str, stats: dict, error: float) -> None:
    stream = sys.stderr if out == "-" else sys.stdout
    if args.json:
        print(json.dumps({"input": label, "output": out, **stats, "vertex_rms_over_diagonal": error}),
              file=stream, flush=True)
        return
    parts = ", ".join(f"{k} {v:.2f}" for k, v in stats["section_bits_per_vertex"].items() if v > 0)
    print(f"{label} -> {out}: {stats['vertices']} vertices, {stats['bytes']} bytes, "
          f"{stats['bits_per_vertex']:.3f} bits/vertex ({parts})", file=stream)
    note = f"; {stats['connectivity_note']}" if stats["connectivity_note"] else ""
    print(f"  connectivity coder: {stats['connectivity_coder']}{note}", file=stream)
    print(f"  {stats['basis']} basis, {stats['patches']} patches, {stats['coefficients']} coefficients per axis, "
          f"step {stats['step']:.3g}", file=stream)
    print(f"  vertex RMS error {error:.3e} of the bounding-box diagonal", file=stream, flush=True)


def run(args) -> int:
    out = positional_output(args)
    if out != "-":
        check_output(out, args.force)
        if names_a_mesh_format(out):
            raise CLIError(f"{out}: {Path(out).suffix} names a mesh format, but compress writes a .jxm stream; "
                           "name OUT *.jxm (jaxmesh decompress reads it back into a mesh)")
    check_view(args)
    label, mesh = load_input(args)
    c = compress(mesh, keep=args.keep, bits=args.bits, basis=args.basis, patch_size=args.patch_size,
                 preserve_order=args.preserve_order)
    if out == "-":
        sys.stdout.buffer.write(c.data)
        sys.stdout.buffer.flush()
    else:
        save_compressed(c, out, overwrite=args.force)
    _report(args, out, label, {"vertices": mesh.num_vertices, **c.stats}, c.relative_error(mesh))
    if args.view:
        write_view(args, [(label, mesh), (f"{out} (decoded)", c.mesh)],
                   [np.zeros(mesh.num_vertices), c.vertex_errors(mesh)], scalar_label="vertex error")
    return 0
