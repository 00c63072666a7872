"""Differentiable sparse symmetric solves on a mesh's sparsity pattern.

A symmetric matrix on the pattern of a graph with n vertices and undirected edges
``edges`` (E, 2) is given by its values:

    A = diag(d) + sum_e a_e (e_i e_jᵀ + e_j e_iᵀ),   e = (i, j),

``d`` (n,) the diagonal and ``a`` (E,) one value per undirected edge (so A is
symmetric by construction).  The Laplacians of a mesh are of this form: the
cotangent Laplacian L_c has a_e = ½(cot α + cot β) and d_i = -Σ_j a_ij; M + tL
adds a lumped mass to the diagonal.

:func:`sparse_solve` returns x = A⁻¹ b and is a JAX function in every sense:

* the factorization and the solve run on the host (``jax.pure_callback``), through
  cholespy's sparse Cholesky (CHOLMOD-style supernodal, the fastest measured; see
  ``benchmarks/bench_linalg.py``) when it is installed, else SciPy's SuperLU; the
  factor of each distinct matrix is kept (a small LRU cache keyed by its values),
  so every further right-hand side, and the backward pass, costs one solve;
* it works under ``jit`` and ``vmap`` (over right-hand sides, and over a batch of
  matrices: one factor per element);
* it is differentiable in ``d``, ``a`` and ``b`` in forward and reverse mode,
  through ``jax.lax.custom_linear_solve`` (implicit differentiation):

      ẋ = A⁻¹ (ḃ − Ȧ x),        b̄ = A⁻¹ x̄,   d̄_i = −b̄_i x_i,   ā_e = −(b̄_i x_j + b̄_j x_i),

  so a reverse pass is one more solve with the same factor (A is symmetric).

With ``laplacian=True`` the diagonal given is what the matrix adds to a graph Laplacian,

    A = diag(d − s) + sum_e a_e (e_i e_jᵀ + e_j e_iᵀ),   s_i = Σ_j a_ij,

and the row sums s are formed on the host in float64: a Laplacian's rows then sum to
exactly d whatever the input's precision, so a Laplacian with a tiny shift d stays
positive definite in float32, where d − s rounded to float32 would not.

The matrix must be nonsingular, and positive definite for the Cholesky backend
(an indefinite matrix is refused with ``ValueError`` there; ``backend="lu"`` takes any
nonsingular symmetric matrix).
"""

from __future__ import annotations

import contextlib
import functools
import hashlib
import importlib.util
import threading
from collections import OrderedDict
from typing import Literal

import jax
import jax.numpy as jnp
import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from jaxtyping import Array, Float, Int

from ._private import one_program
from .mesh import Mesh

__all__ = ["sparse_solve", "sparse_matvec", "mesh_solve", "host_solve", "host_factor", "BACKENDS",
           "default_backend", "clear_factor_cache"]

BACKENDS = ("auto", "cholesky", "lu")
_CACHE_SIZE = 16


def default_backend() -> str:
    """The backend ``"auto"`` resolves to: ``"cholesky"`` when cholespy imports, else ``"lu"``.

    Arguments:

    Returns:
        ``"cholesky"`` or ``"lu"``."""
    return "cholesky" if importlib.util.find_spec("cholespy") is not None else "lu"


@one_program(static_argnames=("laplacian",))
def sparse_matvec(
    edges: Int[Array, "E 2"], diagonal: Float[Array, " n"], edge_values: Float[Array, " E"],
    x: Float[Array, "n ..."], *, laplacian: bool = False,
) -> Float[Array, "n ..."]:
    """y = A x for A = diag(d) + Σ_e a_e (e_i e_jᵀ + e_j e_iᵀ) (module docstring), by
    segment sums over both directions of every edge; with ``laplacian``, A = diag(d − s) + …
    and y_i = d_i x_i + Σ_j a_ij (x_j − x_i).

    Arguments:
        edges: undirected edges (i, j), (E, 2).
        diagonal: d, (n,).
        edge_values: a, one per edge, (E,).
        x: vectors, (n,) or (n, k).
        laplacian: the Laplacian form of the module docstring.

    Returns:
        A x, the shape of ``x``."""
    i, j = edges[:, 0], edges[:, 1]
    a = edge_values.reshape(edge_values.shape + (1,) * (x.ndim - 1))
    d = diagonal.reshape(diagonal.shape + (1,) * (x.ndim - 1))
    out = d * x
    if laplacian:
        out = out.at[i].add(a * (x[j] - x[i]))
        return out.at[j].add(a * (x[i] - x[j]))
    out = out.at[i].add(a * x[j])
    return out.at[j].add(a * x[i])


def sparse_solve(
    edges: Int[Array, "E 2"], diagonal: Float[Array, " n"], edge_values: Float[Array, " E"],
    b: Float[Array, "n ..."], *, backend: Literal["auto", "cholesky", "lu"] = "auto", laplacian: bool = False,
) -> Float[Array, "n ..."]:
    """x = A⁻¹ b for the symmetric sparse A of the module docstring; differentiable in
    ``diagonal``, ``edge_values`` and ``b`` (forward and reverse), jittable and vmappable.

    Arguments:
        edges: undirected pairs (i, j), (E, 2); a pair listed more than once adds up its
            values (the matrix is the sum, in the solve, the matvec and the derivatives), and a
            pair (i, i) adds twice its value to the diagonal.
        diagonal: d, (n,).
        edge_values: a, one per edge, (E,).
        b: right-hand sides, (n,) or (n, k).
        backend: ``"cholesky"`` (cholespy; A must be positive definite), ``"lu"``
            (SciPy SuperLU; any nonsingular A) or ``"auto"`` (:func:`default_backend`).
        laplacian: ``diagonal`` is added to the Laplacian of ``edge_values`` (module
            docstring), its row sums formed in float64.

    Returns:
        x, the shape and dtype of ``b``."""
    _check_backend(backend)
    resolved = default_backend() if backend == "auto" else backend
    if edges.ndim != 2 or edges.shape[-1] != 2:
        raise ValueError(f"edges must have shape (E, 2), got {edges.shape}")
    n = diagonal.shape[-1]
    if b.ndim not in (1, 2) or b.shape[0] != n:
        raise ValueError(f"b must have shape ({n},) or ({n}, k), got {b.shape}")
    if edge_values.shape != (edges.shape[0],):
        raise ValueError(f"edge_values must have shape ({edges.shape[0]},), got {edge_values.shape}")
    dtype = jnp.result_type(diagonal, edge_values, b)
    diagonal, edge_values, b = (jnp.asarray(z, dtype) for z in (diagonal, edge_values, b))

    def matvec(x):
        return sparse_matvec(edges, diagonal, edge_values, x, laplacian=laplacian)

    if not any(isinstance(z, jax.core.Tracer) for z in (edges, diagonal, edge_values)):
        # concrete matrix: factor now, so that a singular or indefinite matrix is a plain
        # ValueError here (the callback below then finds the factor in the cache)
        e, a = np.asarray(edges), np.asarray(edge_values)
        _factor(e, _host_diagonal(e, np.asarray(diagonal), a, laplacian), a, resolved)

    def solve(_, rhs):
        return _host_solve(edges, jax.lax.stop_gradient(diagonal), jax.lax.stop_gradient(edge_values), rhs,
                           resolved, laplacian)

    return jax.lax.custom_linear_solve(matvec, b, solve, symmetric=True)


def mesh_solve(
    mesh: Mesh, diagonal: Float[Array, " V"], edge_values: Float[Array, " E"], b: Float[Array, "V ..."], *,
    backend: Literal["auto", "cholesky", "lu"] = "auto", laplacian: bool = False,
) -> Float[Array, "V ..."]:
    """:func:`sparse_solve` on the pattern of ``mesh``: ``edge_values`` in ``mesh.edges`` order.

    Arguments:
        mesh: a single mesh (a batch: ``jax.vmap`` over meshes and values).
        diagonal: d, (V,).
        edge_values: a, one per edge in ``mesh.edges`` order, (E,).
        b: right-hand sides, (V,) or (V, k).
        backend: as :func:`sparse_solve`.
        laplacian: as :func:`sparse_solve`.

    Returns:
        x, the shape and dtype of ``b``."""
    return sparse_solve(mesh.edges, diagonal, edge_values, b, backend=backend, laplacian=laplacian)


def host_solve(edges, diagonal, edge_values, b, *, backend: Literal["auto", "cholesky", "lu"] = "auto",
               laplacian: bool = False) -> np.ndarray:
    """x = A⁻¹ b for host code: :func:`sparse_solve`'s matrix and factor cache, numpy in and
    out, no JAX program (nothing to compile, nothing to differentiate).  A matrix that
    cannot be factored raises ``ValueError`` here, as :func:`sparse_solve` does on a
    concrete matrix.

    Arguments:
        edges: undirected edges (i, j), (E, 2).
        diagonal: d, (n,).
        edge_values: a, one per edge, (E,).
        b: right-hand sides, (n,) or (n, k).
        backend: as :func:`sparse_solve`.
        laplacian: as :func:`sparse_solve`.

    Returns:
        x, float64, the shape of ``b``."""
    _check_backend(backend)     # here too: a bad name is a ValueError of this call, not of the annotated inner one
    return host_factor(edges, diagonal, edge_values, backend=backend, laplacian=laplacian)(b)


def host_factor(edges, diagonal, edge_values, *, backend: Literal["auto", "cholesky", "lu"] = "auto",
                laplacian: bool = False):
    """:func:`host_solve` for one matrix, factored (or found in the factor cache) here once: ``solve(b)``
    then costs only its solves, where each :func:`host_solve` call hashes the matrix to find its factor.

    Arguments:
        edges: undirected edges (i, j), (E, 2).
        diagonal: d, (n,).
        edge_values: a, one per edge, (E,).
        backend: as :func:`sparse_solve`.
        laplacian: as :func:`sparse_solve`.

    Returns:
        ``solve(b)``: x = A⁻¹ b, float64, the shape of ``b`` ((n,) or (n, k))."""
    _check_backend(backend)
    e, a = np.asarray(edges), np.asarray(edge_values)
    factor = _factor(e, _host_diagonal(e, np.asarray(diagonal), a, laplacian), a,
                     default_backend() if backend == "auto" else backend)

    def solve(b) -> np.ndarray:
        x = factor.solve(np.asarray(b))
        with _lock:
            _stats["solves"] += 1
        return x

    return solve


def _check_backend(backend) -> None:
    if backend not in BACKENDS:
        raise ValueError(f"backend must be one of {BACKENDS}, got {backend!r}")


def _host_diagonal(edges: np.ndarray, diagonal: np.ndarray, values: np.ndarray, laplacian: bool) -> np.ndarray:
    """The matrix's diagonal in float64: d, or d − s (s the row sums of the edge values)."""
    d = np.asarray(diagonal, np.float64)
    if not laplacian:
        return d
    a = np.asarray(values, np.float64)
    return d - np.bincount(edges[:, 0], a, len(d)) - np.bincount(edges[:, 1], a, len(d))


# --------------------------------------------------------------------------- host side
class _Factor:
    """One factorization of an n × n matrix; ``solve`` takes (n,) or (n, k) float64."""

    def __init__(self, n: int, edges: np.ndarray, diagonal: np.ndarray, values: np.ndarray, backend: str):
        rows = np.concatenate([np.arange(n), edges[:, 0], edges[:, 1]]).astype(np.int32)
        cols = np.concatenate([np.arange(n), edges[:, 1], edges[:, 0]]).astype(np.int32)
        data = np.concatenate([diagonal, values, values]).astype(np.float64)
        self.n = n
        if backend == "cholesky":
            import cholespy

            # cholespy does not report a failed factorization: check positive definiteness
            # cheaply first (a negative or zero diagonal), then the residual of one solve
            if n and not np.all(diagonal > 0):
                raise ValueError("sparse_solve: the matrix is not positive definite (a diagonal entry is <= 0); "
                                 "use backend='lu' for an indefinite matrix")
            try:
                with _stdout_to_stderr():          # CHOLMOD prints its warnings on the C stdout
                    self._chol = cholespy.CholeskySolverD(n, rows, cols, data, cholespy.MatrixType.COO)
            except ValueError as e:          # CHOLMOD: "Matrix is not positive definite!"
                raise ValueError(f"sparse_solve: the matrix is not positive definite ({e}); use backend='lu' "
                                 "for an indefinite matrix") from None
            self._lu = None
            self._matrix = sp.csr_matrix((data, (rows, cols)), shape=(n, n))
            probe = np.ones(n)
            x = self._solve(probe)
            err = _backward_error(self._matrix, x, probe)
            if not err <= 1e-8:
                raise ValueError("sparse_solve: the Cholesky factorization failed (the matrix is not positive "
                                 f"definite: backward error {err:.3g}); use backend='lu' for an indefinite matrix")
        else:
            mat = sp.csc_matrix((data, (rows, cols)), shape=(n, n))
            try:
                self._lu = spla.splu(mat)
            except RuntimeError as e:        # "Factor is exactly singular"
                raise ValueError(f"sparse_solve: the matrix is singular ({e})") from None
            self._chol = None

    def _solve(self, rhs: np.ndarray) -> np.ndarray:
        if self._chol is not None:
            b = np.array(rhs, np.float64, order="C")      # a writable copy: cholespy refuses read-only views
            x = np.zeros_like(b)
            self._chol.solve(b, x)
            return x
        return self._lu.solve(np.asfortranarray(rhs, np.float64))

    def solve(self, rhs: np.ndarray) -> np.ndarray:
        return self._solve(rhs)


@contextlib.contextmanager
def _stdout_to_stderr():
    """File descriptor 1 pointed at 2 for the block: a C library's diagnostics go where
    diagnostics belong, not into a command's output (``jaxmesh stats --json``).  The
    descriptors are the process's: one thread at a time redirects them (two overlapping
    blocks would each save the other's redirection and leave fd 1 on stderr)."""
    import os
    import sys

    with _redirect_lock:
        try:
            sys.stdout.flush()
            saved = os.dup(1)
        except (OSError, ValueError):          # no usable fd 1 (embedded interpreters): leave it alone
            yield
            return
        try:
            os.dup2(2, 1)
            yield
        finally:
            os.dup2(saved, 1)
            os.close(saved)


_redirect_lock = threading.RLock()   # re-entrant: a nested block restores what the outer one set


def _backward_error(matrix: sp.csr_matrix, x: np.ndarray, b: np.ndarray) -> float:
    """‖A x − b‖∞ / (‖A‖∞ ‖x‖∞ + ‖b‖∞): small (≈ 1e-16) for a backward-stable solve even
    of an ill-conditioned matrix; NaN or large when the factorization broke down."""
    r = np.abs(matrix @ x - b).max()
    scale = np.abs(matrix).sum(axis=1).max() * np.abs(x).max() + np.abs(b).max()
    return float(r / scale) if np.isfinite(r) and np.isfinite(scale) and scale > 0 else float("nan")


_cache: OrderedDict = OrderedDict()
_lock = threading.Lock()
_stats = {"factorizations": 0, "solves": 0}


def clear_factor_cache() -> dict:
    """Drop every cached factorization and reset the counters.

    Arguments:

    Returns:
        The counters before the reset: ``factorizations`` and ``solves`` performed."""
    with _lock:
        before = dict(_stats)
        _cache.clear()
        _stats.update(factorizations=0, solves=0)
    return before


def _factor(edges: np.ndarray, diagonal: np.ndarray, values: np.ndarray, backend: str) -> _Factor:
    h = hashlib.blake2b(digest_size=16)
    for a in (np.ascontiguousarray(edges, np.int64), np.ascontiguousarray(diagonal, np.float64),
              np.ascontiguousarray(values, np.float64)):
        h.update(a.tobytes())
        h.update(str(a.shape).encode())
    key = (backend, h.hexdigest())
    with _lock:
        hit = _cache.get(key)
        if hit is not None:
            _cache.move_to_end(key)
            return hit
    made = _Factor(len(diagonal), np.asarray(edges), np.asarray(diagonal, np.float64),
                   np.asarray(values, np.float64), backend)
    with _lock:
        _stats["factorizations"] += 1
        _cache[key] = made
        while len(_cache) > _CACHE_SIZE:
            _cache.popitem(last=False)
    return made


@functools.lru_cache(maxsize=32)
def _solve_callback(base: int, backend: str, laplacian: bool):
    """The host side of :func:`_host_solve` for right-hand sides of ``base`` dimensions: one
    function per configuration, so that an eager call's program is kept (a new callback each call
    would compile a new one)."""

    def host(e, d, a, r):
        e, d, a, r = (np.asarray(z) for z in (e, d, a, r))
        lead = np.broadcast_shapes(e.shape[:-2], d.shape[:-1], a.shape[:-1], r.shape[:-base])
        e = np.broadcast_to(e, lead + e.shape[-2:])
        d = np.broadcast_to(d, lead + d.shape[-1:])
        a = np.broadcast_to(a, lead + a.shape[-1:])
        r = np.broadcast_to(r, lead + r.shape[-base:])
        if lead and e.strides[:len(lead)] == (0,) * len(lead) and d.strides[:len(lead)] == (0,) * len(lead) \
                and a.strides[:len(lead)] == (0,) * len(lead):
            # one matrix, many right-hand sides (vmap over b): one factor, one multi-column solve
            idx0 = (0,) * len(lead)
            cols = np.moveaxis(r.reshape((-1,) + r.shape[len(lead):]), 0, -1)     # (n, [k,] B)
            x = host_solve(e[idx0], d[idx0], a[idx0], cols.reshape(cols.shape[0], -1), backend=backend,
                           laplacian=laplacian).reshape(cols.shape)
            return np.moveaxis(x, -1, 0).reshape(r.shape).astype(r.dtype)
        out = np.empty(r.shape, r.dtype)
        for idx in np.ndindex(*lead):
            out[idx] = host_solve(e[idx], d[idx], a[idx], r[idx], backend=backend, laplacian=laplacian)
        return out

    return host


def _host_solve(edges, diagonal, edge_values, rhs, backend: str, laplacian: bool = False):
    """The callback: batched over any leading axes that ``vmap`` added (``expand_dims``:
    unbatched arguments carry size-1 axes there)."""
    out_type = jax.ShapeDtypeStruct(rhs.shape, rhs.dtype)
    host = _solve_callback(rhs.ndim, backend, laplacian)     # rhs (n,) or (n, k) before vmap
    return jax.pure_callback(host, out_type, edges, diagonal, edge_values, rhs, vmap_method="expand_dims")
