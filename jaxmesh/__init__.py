"""jaxmesh: differentiable triangle-mesh processing in JAX.

The public names are re-exported here; each lives in a module of its own (see
docs/development.md for the layout).  Every name and subpackage is imported on first
use (PEP 562), so ``import jaxmesh`` and the command line's ``--help`` start without
loading JAX, and a command loads only what it needs.  One table, :data:`_NAMES`, says
where each top-level name lives; ``__all__`` and ``dir(jaxmesh)`` are read from it.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING

__version__ = "0.1.0"

#: each top-level function and class -> the module that defines it
_NAMES = {
    "Mesh": "mesh", "MeshWarning": "mesh",
    "MeshFileError": "io", "load": "io", "save": "io",
    "MeshAttributes": "attributes", "read_attributes": "attributes",
    "add_noise": "noise", "add_impulsive_noise": "noise",
    "normalize": "transforms",
    "mesh_info": "topology",
    **{name: "geometry" for name in (
        "edge_vectors", "edge_lengths", "mean_edge_length", "face_areas", "face_normals", "corner_angles",
        "vertex_normals", "vertex_areas", "bounding_box_diagonal")},
}

#: the public modules and subpackages, attributes of the package
_MODULES = ("attributes", "batch", "compiler", "compress", "data", "dataset", "denoise", "geodesics", "geometry",
            "graph", "hashing", "host", "intrinsic", "io", "linalg", "mesh", "metrics", "noise", "operators", "render", "sparse",
            "spectral", "stats", "topology", "transforms", "tune", "vf", "view")

__all__ = [*_NAMES, *_MODULES]


def __getattr__(name: str):
    if name in _MODULES:
        value = importlib.import_module(f".{name}", __name__)
    elif name in _NAMES:
        value = getattr(importlib.import_module(f".{_NAMES[name]}", __name__), name)
    else:
        raise AttributeError(f"module 'jaxmesh' has no attribute {name!r}")
    globals()[name] = value
    return value


def __dir__():
    return sorted(set(globals()) | set(__all__))


if TYPE_CHECKING:   # what static tools see (explicit re-exports); at run time every name comes through __getattr__
    from . import attributes as attributes
    from . import batch as batch
    from . import compiler as compiler
    from . import compress as compress
    from . import data as data
    from . import dataset as dataset
    from . import denoise as denoise
    from . import geodesics as geodesics
    from . import geometry as geometry
    from . import graph as graph
    from . import hashing as hashing
    from . import host as host
    from . import intrinsic as intrinsic
    from . import io as io
    from . import linalg as linalg
    from . import mesh as mesh
    from . import metrics as metrics
    from . import noise as noise
    from . import operators as operators
    from . import render as render
    from . import sparse as sparse
    from . import spectral as spectral
    from . import stats as stats
    from . import topology as topology
    from . import transforms as transforms
    from . import tune as tune
    from . import vf as vf
    from . import view as view
    from .attributes import MeshAttributes as MeshAttributes
    from .attributes import read_attributes as read_attributes
    from .geometry import bounding_box_diagonal as bounding_box_diagonal
    from .geometry import corner_angles as corner_angles
    from .geometry import edge_lengths as edge_lengths
    from .geometry import edge_vectors as edge_vectors
    from .geometry import face_areas as face_areas
    from .geometry import face_normals as face_normals
    from .geometry import mean_edge_length as mean_edge_length
    from .geometry import vertex_areas as vertex_areas
    from .geometry import vertex_normals as vertex_normals
    from .io import MeshFileError as MeshFileError
    from .io import load as load
    from .io import save as save
    from .mesh import Mesh as Mesh
    from .mesh import MeshWarning as MeshWarning
    from .noise import add_impulsive_noise as add_impulsive_noise
    from .noise import add_noise as add_noise
    from .topology import mesh_info as mesh_info
    from .transforms import normalize as normalize
