"""jaxmesh: differentiable triangle-mesh processing in JAX.

The public names are re-exported here; each lives in a module of its own
(see docs/development.md for the layout).  The core (the mesh, its files and geometry)
is imported with the package; the feature subpackages (``denoise``, ``tune``,
``compress``, ``hash``, ``stats``, ...) on first use, so ``import jaxmesh`` and the
command line start without loading what they do not need.
"""

import importlib

from . import geometry, topology
from .geometry import (
    bounding_box_diagonal,
    corner_angles,
    edge_lengths,
    edge_vectors,
    face_areas,
    face_normals,
    mean_edge_length,
    vertex_areas,
    vertex_normals,
)
from .io import MeshFileError, load, save
from .mesh import Mesh, MeshWarning
from .noise import add_impulsive_noise, add_noise
from .topology import mesh_info
from .transforms import normalize

__version__ = "0.1.0"

#: subpackages imported on first attribute access (PEP 562)
_LAZY = ("batch", "compiler", "compress", "data", "dataset", "denoise", "geodesics", "hash", "intrinsic", "linalg", "metrics",
         "operators", "sparse", "spectral", "stats", "tune", "vf")


def __getattr__(name: str):
    if name in _LAZY:
        module = importlib.import_module(f".{name}", __name__)
        globals()[name] = module
        return module
    raise AttributeError(f"module 'jaxmesh' has no attribute {name!r}")


def __dir__():
    return sorted(set(globals()) | set(_LAZY))

__all__ = [
    "Mesh",
    "MeshWarning",
    "MeshFileError",
    "load",
    "save",
    "add_noise",
    "add_impulsive_noise",
    "normalize",
    "mesh_info",
    "edge_vectors",
    "edge_lengths",
    "mean_edge_length",
    "face_areas",
    "face_normals",
    "corner_angles",
    "vertex_normals",
    "vertex_areas",
    "bounding_box_diagonal",
    "batch",
    "compress",
    "data",
    "dataset",
    "denoise",
    "geometry",
    "hash",
    "metrics",
    "operators",
    "sparse",
    "stats",
    "topology",
    "tune",
]
