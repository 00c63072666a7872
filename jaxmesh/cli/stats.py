"""``jaxmesh stats MESH ... [--json] [--plot PNG]``: the statistics of thesis ch.5."""

from __future__ import annotations

import io
import sys

import numpy as np

from ..io import write_bytes_atomic
from ..stats import DENSE_MAX, KNN, SOURCES, mesh_statistics, plot_statistics
from ._common import CLIError, check_output, mesh_arguments, mesh_source, print_record


def configure(p) -> None:
    mesh_arguments(p)
    p.add_argument("--plot", metavar="PNG", help="draw the six-panel figure (one mesh only)")
    p.add_argument("--force", action="store_true", help="replace the --plot file if it exists")
    p.add_argument("--sources", type=int, default=None,
                   help=f"geodesic sources (default {SOURCES}, or every vertex of a smaller mesh)")
    p.add_argument("--seed", type=int, default=0, help="seed of the source sample (default 0)")
    p.add_argument("--knn", type=int, default=None, help=f"neighbours of the kNN graph (default {KNN})")
    p.add_argument("--dense-max", type=int, default=DENSE_MAX, metavar="V",
                   help=f"meshes of up to V vertices get their whole spectra exactly, from a dense eigensolver "
                        f"(cubic in V: about 1 s a spectrum at 3k vertices, 16 s at 6.5k); larger ones the "
                        f"kernel polynomial method's estimate (default {DENSE_MAX})")


def _stage(label: str):
    """Progress lines on stderr for a terminal (long statistics), silent otherwise."""
    if not sys.stderr.isatty():
        return None
    return lambda stage: print(f"jaxmesh: {label}: {stage}...", file=sys.stderr, flush=True)


def run(args) -> int:
    sources = mesh_source(args)
    if args.plot:
        if len(sources) > 1:
            raise CLIError("--plot draws one mesh; name a single MESH")
        check_output(args.plot, args.force)
    for i, (label, loader) in enumerate(sources):
        mesh = loader()
        st = mesh_statistics(mesh, sources=args.sources, seed=args.seed, knn=args.knn,
                             dense_max=args.dense_max, progress=_stage(label))
        record = {"path": label, **st["summary"]}
        if args.json:     # the spectra as quantile functions: the eigenvalue at ranks 0, 1/64, …, 1
            ranks = np.linspace(0.0, 1.0, 65)
            record["spectrum_quantiles"] = {kind: np.interp(ranks, *st["spectrum"][kind]).tolist()
                                            for kind in st["spectrum"]}
        print_record(record, args.json, i == 0)
        if args.plot:
            import matplotlib

            matplotlib.use("Agg")
            buf = io.BytesIO()
            plot_statistics(mesh, st, title=label).savefig(buf, dpi=100, format="png")
            write_bytes_atomic(args.plot, buf.getvalue(), overwrite=args.force)
    return 0
