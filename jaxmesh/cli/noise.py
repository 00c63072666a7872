"""``jaxmesh noise IN OUT --sigma S``: Gaussian noise (thesis ch.2 eq.1)."""

from __future__ import annotations

import sys

from ..io import save
from ..noise import add_noise
from ._common import CLIError, check_output, io_arguments, load_input, positional_output

HELP = "add Gaussian noise to a mesh (thesis ch.2 eq.1)"


def configure(p) -> None:
    io_arguments(p)
    p.add_argument("--sigma", type=float, default=0.1,
                   help="noise standard deviation, in mean edge lengths (default 0.1)")
    p.add_argument("--absolute", action="store_true", help="--sigma is in the mesh's own units")
    p.add_argument("--along-normals", action="store_true", help="displace along vertex normals only")
    p.add_argument("--seed", type=int, default=0, help="random seed (default 0)")


def run(args) -> int:
    out = positional_output(args)
    label, mesh = load_input(args)
    check_output(out, args.force)
    if not args.sigma >= 0:
        raise CLIError(f"--sigma must be >= 0, got {args.sigma}")
    noisy = add_noise(mesh, args.sigma, args.seed, along_normals=args.along_normals, relative=not args.absolute)
    save(noisy, out, overwrite=args.force)
    unit = "" if args.absolute else " mean edge lengths"
    print(f"jaxmesh: wrote {out}: {label} + Gaussian noise sigma={args.sigma:g}{unit}, seed {args.seed}",
          file=sys.stderr)
    return 0
