"""Helpers shared by the experiment scripts: the shared meshes and a wall-clock timer."""

from __future__ import annotations

import time
import warnings
from pathlib import Path

import numpy as np

import jaxmesh

ROOT = Path(__file__).resolve().parents[1]
SHARED = ROOT.parent / "shared" / "meshes"
#: the twelve development meshes of ../shared/meshes, smallest first
MESHES = ("eight", "cow", "spot", "fertility", "maxplanck", "fandisk", "shark", "human", "camelhead",
          "bunny", "armadillo", "igea")


def load(name: str) -> jaxmesh.Mesh:
    """../shared/meshes/NAME.ply in float64, or exit with the reason."""
    path = SHARED / f"{name}.ply"
    if not path.is_file():
        raise SystemExit(f"{path} not found: this experiment needs ../shared/meshes beside the repo")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", jaxmesh.MeshWarning)
        return jaxmesh.load(path, dtype=np.float64)


def timed(f, *args, **kw):
    """(f(*args, **kw), wall seconds)."""
    t = time.perf_counter()
    out = f(*args, **kw)
    return out, time.perf_counter() - t
