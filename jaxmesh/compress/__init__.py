"""Spectral mesh compression (thesis ch.3) and the ``.jxm`` codec.

* :mod:`.basis`: the umbrella (thesis) and Laplacian (Karni–Gotsman) bases, reproducible;
* :mod:`.projection`: eq.5 in JAX, the host eigensolver behind ``pure_callback``;
* :mod:`.connectivity`, :mod:`.rangecoder`, :mod:`.patches`, :mod:`.codec`: the codec.
"""

from .basis import KINDS, SpectralBasis, graph_basis, spectral_basis
from .codec import FORMAT_VERSION, MAGIC, MAX_PATCH_SIZE, CodecError, Compressed, compress, decompress, inspect
from .connectivity import ConnectivityCode, encode_connectivity, decode_connectivity
from .io import load_compressed, save_compressed
from .projection import (
    basis_callback,
    project,
    project_orthonormal,
    spectral_coefficients,
    spectral_reconstruction,
)

__all__ = [
    "KINDS",
    "SpectralBasis",
    "graph_basis",
    "spectral_basis",
    "FORMAT_VERSION",
    "MAGIC",
    "MAX_PATCH_SIZE",
    "CodecError",
    "Compressed",
    "compress",
    "decompress",
    "inspect",
    "load_compressed",
    "save_compressed",
    "ConnectivityCode",
    "encode_connectivity",
    "decode_connectivity",
    "basis_callback",
    "project",
    "project_orthonormal",
    "spectral_coefficients",
    "spectral_reconstruction",
]
