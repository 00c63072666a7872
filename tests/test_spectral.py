"""jaxmesh.spectral: eigenpairs against SciPy's dense generalized solver, reproducible;
derivatives of simple eigenvalues, of a degenerate cluster's sum, of simple
eigenvectors, of a cluster's projector and of the reconstruction error against finite
differences; ShapeDNA's invariances and the sphere's spectrum; the refusals."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
import scipy.linalg
import trimesh
from jax.test_util import check_grads

import jaxmesh
from jaxmesh import spectral as S


@pytest.fixture(scope="module")
def bumpy():
    """An icosphere with radial bumps: no symmetry left, every eigenvalue simple."""
    s = trimesh.creation.icosphere(2)
    v = s.vertices * (1 + 0.05 * np.random.default_rng(0).standard_normal((len(s.vertices), 1)))
    return jaxmesh.Mesh.from_arrays(v, s.faces)


@pytest.fixture(scope="module")
def sphere():
    """The icosphere itself: its l = 1 and l = 2 eigenvalues are exactly 3- and 5-fold."""
    s = trimesh.creation.icosphere(2)
    return jaxmesh.Mesh.from_arrays(s.vertices, s.faces)


def dense(mesh):
    d, a, m = (np.asarray(z) for z in S.laplace_beltrami_system(mesh))
    e = np.asarray(mesh.edges)
    A = np.diag(d)
    A[e[:, 0], e[:, 1]] = a
    A[e[:, 1], e[:, 0]] = a
    return A, m


def test_eigenpairs_equal_scipy_and_are_reproducible(bumpy):
    A, m = dense(bumpy)
    w, u = S.eigenpairs(bumpy.edges, *S.laplace_beltrami_system(bumpy), 8)
    ref_w, ref_u = scipy.linalg.eigh(A, np.diag(m), subset_by_index=[0, 7])
    np.testing.assert_allclose(w, ref_w, rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(np.abs(np.sum(np.asarray(u) * ref_u * m[:, None], 0)), 1, atol=1e-9)
    np.testing.assert_allclose(u.T @ (m[:, None] * u), np.eye(8), atol=1e-12)
    w2, u2 = S.eigenpairs(bumpy.edges, *S.laplace_beltrami_system(bumpy), 8, dense_max=10)   # ARPACK path
    np.testing.assert_allclose(w2, w, rtol=1e-9, atol=1e-10)
    np.testing.assert_allclose(u2, u, atol=1e-7)                       # same canonical signs
    jitted = jax.jit(lambda x: S.eigenpairs(bumpy.edges, *S.laplace_beltrami_system(bumpy.with_vertices(x)), 8))
    np.testing.assert_array_equal(jitted(bumpy.vertices)[1], u)


def test_eigenvalue_derivatives(bumpy, sphere):
    f = jax.jit(lambda x: S.eigenvalues(bumpy.edges, *S.laplace_beltrami_system(bumpy.with_vertices(x)), 6))
    check_grads(f, (bumpy.vertices,), order=1, modes=("fwd", "rev"), atol=1e-6, rtol=1e-6, eps=1e-5)
    # a 3-fold cluster (l = 1): its sum is smooth, and so is its derivative
    w = S.eigenvalues(sphere.edges, *S.laplace_beltrami_system(sphere), 4)
    assert float(w[3] - w[1]) < 1e-10 * float(w[3])

    @jax.jit
    def cluster_sum(x):
        return jnp.sum(S.eigenvalues(sphere.edges, *S.laplace_beltrami_system(sphere.with_vertices(x)), 4)[1:])

    check_grads(cluster_sum, (sphere.vertices,), order=1, modes=("fwd", "rev"), atol=1e-6, rtol=1e-6, eps=1e-5)


def test_eigenvector_and_projector_derivatives(bumpy, sphere):
    weights = jnp.asarray(np.random.default_rng(1).standard_normal((bumpy.num_vertices, 5)))

    @jax.jit
    def vectors(x):
        _, u = S.eigenpairs(bumpy.edges, *S.laplace_beltrami_system(bumpy.with_vertices(x)), 5)
        return jnp.sum(weights * u)

    check_grads(vectors, (bumpy.vertices,), order=1, modes=("fwd", "rev"), atol=1e-5, rtol=1e-5, eps=1e-5)
    # the span of a cluster (constant + l = 1 on the sphere) through its M-orthogonal projector
    probe = jnp.asarray(np.random.default_rng(2).standard_normal((sphere.num_vertices, 3)))

    @jax.jit
    def projector(x):
        d, a, m = S.laplace_beltrami_system(sphere.with_vertices(x))
        _, u = S.eigenpairs(sphere.edges, d, a, m, 4)
        return jnp.sum(probe * (u @ (u.T @ (m[:, None] * probe))))

    check_grads(projector, (sphere.vertices,), order=1, modes=("fwd", "rev"), atol=1e-6, rtol=1e-6, eps=1e-5)


def test_reconstruction_error_and_its_derivative(bumpy):
    err = S.spectral_reconstruction_error(bumpy, 9)
    x = np.asarray(bumpy.vertices)
    A, m = dense(bumpy)
    _, u = scipy.linalg.eigh(A, np.diag(m), subset_by_index=[0, 8])
    r = x - u @ (u.T @ (m[:, None] * x))
    c = x - (m @ x) / m.sum()
    assert float(err) == pytest.approx(np.sum(m[:, None] * r * r) / np.sum(m[:, None] * c * c), rel=1e-9)
    assert 0 < float(err) < 0.05                       # nine modes hold a bumpy sphere's shape
    check_grads(jax.jit(lambda y: S.spectral_reconstruction_error(bumpy.with_vertices(y), 9)), (bumpy.vertices,),
                order=1, modes=("fwd", "rev"), atol=1e-6, rtol=1e-6, eps=1e-5)


def test_shape_dna_invariances_and_the_sphere(bumpy, sphere):
    dna = S.shape_dna(bumpy, 8)
    rot = jnp.asarray(trimesh.transformations.rotation_matrix(0.7, [1, 2, 3])[:3, :3])
    moved = bumpy.with_vertices(2.5 * bumpy.vertices @ rot.T + jnp.array([[1.0, -2.0, 0.5]]))
    np.testing.assert_allclose(S.shape_dna(moved, 8), dna, rtol=1e-9)
    # the unit sphere: λ = l(l + 1), 2 three times and 6 five times (162 vertices with a
    # lumped mass: measured 1.9999 and 5.864)
    raw = S.shape_dna(sphere, 8, scale_invariant=False)
    np.testing.assert_allclose(raw[:3], 2.0, rtol=1e-3)
    np.testing.assert_allclose(raw[3:8], 6.0, rtol=3e-2)
    np.testing.assert_allclose(raw[3:8], raw[3], rtol=1e-10)          # exactly 5-fold


def test_refusals(sphere):
    system = S.laplace_beltrami_system(sphere)
    with pytest.raises(ValueError, match="cuts a cluster"):
        S.eigenvalues(sphere.edges, *system, 3)
    with pytest.raises(ValueError, match="k must be an int"):
        S.eigenvalues(sphere.edges, *system, sphere.num_vertices)
    d, a, m = system
    with pytest.raises(ValueError, match="mass must be positive"):
        S.eigenpairs(sphere.edges, d, a, m.at[0].set(0.0), 4)
