"""What the examples share: an output folder from the command line (default
./example-out) and float64 (files are read and written unrounded)."""

from __future__ import annotations

import argparse
from pathlib import Path

import jax

jax.config.update("jax_enable_x64", True)


def out_dir(description: str) -> Path:
    p = argparse.ArgumentParser(description=description)
    p.add_argument("--out", default="example-out", help="folder for the files written (default ./example-out)")
    out = Path(p.parse_args().out)
    out.mkdir(parents=True, exist_ok=True)
    return out
