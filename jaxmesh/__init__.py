"""jaxmesh: differentiable triangle-mesh processing in JAX.

The public names are re-exported here; each lives in a module of its own
(see the README for the layout).
"""

from . import attacks, batch, compress, data, denoise, geometry, hash, metrics, operators, sparse, stats, topology, tune
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
from .noise import add_noise
from .topology import mesh_info
from .transforms import normalize

__version__ = "0.1.0"

__all__ = [
    "Mesh",
    "MeshWarning",
    "MeshFileError",
    "load",
    "save",
    "add_noise",
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
    "attacks",
    "batch",
    "compress",
    "data",
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
