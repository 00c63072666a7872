"""A mesh's host mirror: the scipy matrices host code needs, each built once.

Host code that reads a mesh several ways (the noise estimators, the blind
chooser) takes a :class:`HostMesh`, built once per mesh by :func:`as_host`.
Each matrix is built the first time it is read, from its one definition in
:mod:`jaxmesh.sparse`, and kept:

* A, the 0/1 vertex adjacency; the two-ring R₂ = [A + A² ≠ 0] − I;
* K = D⁻¹A − I, the umbrella operator (zero rows on isolated vertices), and K²
  with its row norms ‖row_i(K²)‖;
* each registry method's auxiliary inputs (:meth:`HostMesh.aux`): the face
  graph is built once for every method that takes it.

Values a consumer derives from the mesh and wants to share (a smoothed normal
field, say) are kept by :meth:`HostMesh.memo` under a name.  The positions are
the mesh's: a mesh with moved vertices is another mesh and needs its own mirror.
"""

from __future__ import annotations

import dataclasses
import functools
from collections.abc import Callable
from typing import Any

import numpy as np
import scipy.sparse as sp

from . import sparse
from .mesh import Mesh

__all__ = ["HostMesh", "as_host", "aux_key"]


@dataclasses.dataclass(frozen=True, eq=False)
class HostMesh:
    """The host mirror of one single mesh (module docstring); its matrices are
    CSR, float64, (V, V), built on first read."""

    mesh: Mesh
    _memo: dict = dataclasses.field(default_factory=dict, init=False, repr=False)

    def __post_init__(self):
        if not isinstance(self.mesh, Mesh):
            raise TypeError(f"HostMesh takes a jaxmesh.Mesh, got {type(self.mesh).__name__}")
        if self.mesh.batch_shape:
            raise ValueError(f"HostMesh takes one mesh, got batch shape {self.mesh.batch_shape}")

    @functools.cached_property
    def adjacency(self) -> sp.csr_matrix:
        """A: A_ij = 1 where ij is an edge."""
        return sparse.adjacency_matrix(self.mesh)

    @functools.cached_property
    def two_ring(self) -> sp.csr_matrix:
        """R₂: 1 where j ≠ i is within two edges of i."""
        a = self.adjacency
        ring = (a + a @ a).tocsr()
        ring.data[:] = 1
        ring.setdiag(0)
        ring.eliminate_zeros()
        return ring

    @functools.cached_property
    def umbrella(self) -> sp.csr_matrix:
        """K = D⁻¹A − I (:func:`jaxmesh.sparse.umbrella_matrix`)."""
        return sparse.umbrella_matrix(self.mesh)

    @functools.cached_property
    def umbrella_square(self) -> sp.csr_matrix:
        """K²."""
        k = self.umbrella
        return (k @ k).tocsr()

    @functools.cached_property
    def umbrella_square_row_norms(self) -> np.ndarray:
        """‖row_i(K²)‖, (V,) float64 (0 on isolated vertices)."""
        k2 = self.umbrella_square
        return np.sqrt(np.asarray(k2.multiply(k2).sum(axis=1)).ravel())

    def memo(self, name: str, build: Callable[[], Any]) -> Any:
        """The value kept under ``name``, built by ``build()`` on the first call.

        Arguments:
            name: the value's name (one per derived quantity).
            build: makes the value from this mesh.

        Returns:
            The value."""
        if name not in self._memo:
            self._memo[name] = build()
        return self._memo[name]

    def aux(self, method: str) -> dict[str, Any]:
        """The registry method's auxiliary inputs for this mesh
        (:meth:`jaxmesh.denoise.Method.prepare`) and the inputs it would build itself
        (``host_inputs``), each builder run once for all methods.

        Arguments:
            method: a registry name.

        Returns:
            Keyword arguments (empty for methods that need none)."""
        from .denoise import as_method

        m = as_method(method)
        builders = {**{k: m.params[k].build for k in m.aux}, **m.host_inputs}
        return {k: self.memo(aux_key(b), functools.partial(b, self.mesh)) for k, b in builders.items()}


def aux_key(build: Callable) -> str:
    """The :meth:`HostMesh.memo` name under which :meth:`HostMesh.aux` keeps what ``build`` made:
    a value stored there first (a padded table, say) is the one every method is given.

    Arguments:
        build: a builder of a method's auxiliary input (``Param.build``, ``Method.host_inputs``).

    Returns:
        The name."""
    return f"aux:{build.__module__}.{build.__qualname__}"


def as_host(mesh: Mesh | HostMesh) -> HostMesh:
    """``mesh``'s host mirror: ``mesh`` itself when it is one already.

    Arguments:
        mesh: a single mesh, or its :class:`HostMesh`.

    Returns:
        A :class:`HostMesh`."""
    return mesh if isinstance(mesh, HostMesh) else HostMesh(mesh)
