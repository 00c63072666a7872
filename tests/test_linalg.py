"""jaxmesh.linalg: the sparse symmetric solve against SciPy, its derivatives against
finite differences, jit = eager, vmap = loop, the factor reused by the backward pass,
and the refusals."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
import scipy.sparse as sp
import scipy.sparse.linalg as spla
import trimesh
from jax.test_util import check_grads

import jaxmesh
from jaxmesh import linalg
from conftest import assert_refused

BACKENDS = ["lu", pytest.param("cholesky", marks=pytest.mark.skipif(
    linalg.default_backend() != "cholesky", reason="cholespy is not installed (pip install cholespy)"))]


@pytest.fixture(scope="module")
def system():
    """A random symmetric positive-definite matrix on an icosphere's pattern
    (diagonally dominant, negative off-diagonal entries, like M + tL)."""
    s = trimesh.creation.icosphere(1)
    mesh = jaxmesh.Mesh.from_arrays(s.vertices, s.faces)
    rng = np.random.default_rng(0)
    n, e = mesh.num_vertices, np.asarray(mesh.edges)
    a = -rng.uniform(0.5, 1.5, len(e))
    d = np.bincount(e.ravel(), np.repeat(-a, 2), n) + rng.uniform(0.1, 1.0, n)
    b = rng.standard_normal((n, 3))
    return mesh, jnp.asarray(d), jnp.asarray(a), jnp.asarray(b)


def scipy_matrix(edges, d, a):
    e = np.asarray(edges)
    n = len(d)
    rows = np.concatenate([np.arange(n), e[:, 0], e[:, 1]])
    cols = np.concatenate([np.arange(n), e[:, 1], e[:, 0]])
    return sp.csc_matrix((np.concatenate([d, a, a]), (rows, cols)), shape=(n, n))


@pytest.mark.parametrize("backend", BACKENDS)
def test_solve_equals_scipy_and_matvec_inverts_it(system, backend):
    mesh, d, a, b = system
    x = linalg.mesh_solve(mesh, d, a, b, backend=backend)
    want = spla.spsolve(scipy_matrix(mesh.edges, np.asarray(d), np.asarray(a)), np.asarray(b))
    np.testing.assert_allclose(x, want, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(linalg.sparse_matvec(mesh.edges, d, a, x), b, atol=1e-12)
    x1 = linalg.mesh_solve(mesh, d, a, b[:, 0], backend=backend)            # one right-hand side
    np.testing.assert_allclose(x1, want[:, 0], rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize("backend", BACKENDS)
def test_a_pair_given_twice_is_summed_on_both_sides_of_the_solve(system, backend):
    """The system's edges split in two halves of their values, listed twice (and a pair
    (i, i) adding to the diagonal): the solve, the matvec and the derivatives are those of
    the summed matrix, built by hand in dense numpy."""
    mesh, d, a, b = system
    e = np.asarray(mesh.edges)
    twice = jnp.asarray(np.concatenate([e, e[::-1], [[3, 3]]]))
    halves = jnp.concatenate([0.5 * a, 0.5 * a[::-1], jnp.asarray([0.25])])
    dense = np.diag(np.asarray(d)).copy()
    dense[e[:, 0], e[:, 1]] += np.asarray(a)
    dense[e[:, 1], e[:, 0]] += np.asarray(a)
    dense[3, 3] += 0.5
    x = linalg.sparse_solve(twice, d, halves, b, backend=backend)
    np.testing.assert_allclose(x, np.linalg.solve(dense, np.asarray(b)), rtol=1e-11, atol=1e-12)
    np.testing.assert_allclose(linalg.sparse_matvec(twice, d, halves, x), b, atol=1e-11)
    check_grads(lambda v: linalg.sparse_solve(twice, d, jnp.asarray(v), b, backend=backend), (halves,), order=1,
                modes=("fwd", "rev"), atol=1e-6, rtol=1e-6)


@pytest.mark.parametrize("backend", BACKENDS)
def test_host_solve_and_factor_equal_scipy_in_numpy_and_refuse_what_sparse_solve_refuses(system, backend):
    mesh, d, a, b = system
    e, d, a, b = (np.asarray(z) for z in (mesh.edges, d, a, b))
    x = linalg.host_solve(e, d, a, b, backend=backend)
    assert isinstance(x, np.ndarray) and x.dtype == np.float64 and x.shape == b.shape
    np.testing.assert_allclose(x, spla.spsolve(scipy_matrix(e, d, a), b), rtol=1e-12, atol=1e-12)
    # the Laplacian form: the diagonal given is added to the Laplacian of the edge values
    lap = linalg.host_solve(e, np.full(len(d), 0.5), a, b[:, 0], backend=backend, laplacian=True)
    sums = np.bincount(e[:, 0], a, len(d)) + np.bincount(e[:, 1], a, len(d))
    np.testing.assert_allclose(lap, spla.spsolve(scipy_matrix(e, 0.5 - sums, a), b[:, 0]), rtol=1e-10, atol=1e-12)
    assert_refused(linalg.host_solve, e, d, a, b, backend="qr", param="backend", message="backend must be one of")
    if backend != "lu":
        with pytest.raises(ValueError, match="not positive definite"):
            linalg.host_solve(e, -d, a, b, backend=backend)
    # factored once, solved many times: the same answers, one factorization for all of them
    linalg.clear_factor_cache()
    solve = linalg.host_factor(e, np.full(len(d), 0.5), a, backend=backend, laplacian=True)
    np.testing.assert_array_equal(solve(b[:, 0]), lap)
    np.testing.assert_allclose(solve(2 * b), 2 * spla.spsolve(scipy_matrix(e, 0.5 - sums, a), b), rtol=1e-10,
                               atol=1e-12)
    assert linalg.clear_factor_cache() == {"factorizations": 1, "solves": 2}
    assert_refused(linalg.host_factor, e, d, a, backend="qr", param="backend", message="backend must be one of")


@pytest.mark.parametrize("backend", BACKENDS)
def test_derivatives_match_finite_differences(system, backend):
    mesh, d, a, b = system

    def f(d, a, b):     # check_grads evaluates with numpy arrays: the annotations ask for JAX arrays
        return jnp.sum(jnp.sin(linalg.mesh_solve(mesh, jnp.asarray(d), jnp.asarray(a), jnp.asarray(b),
                                                 backend=backend)))

    check_grads(f, (d, a, b), order=1, modes=("fwd", "rev"), atol=1e-7, rtol=1e-7)


def test_jit_equals_eager_and_the_backward_pass_reuses_the_factor(system):
    mesh, d, a, b = system

    def f(d, a, b):
        return jnp.sum(linalg.mesh_solve(mesh, d, a, b) ** 2)

    eager = jax.grad(f, argnums=(0, 1, 2))(d, a, b)
    linalg.clear_factor_cache()
    jitted = jax.jit(jax.grad(f, argnums=(0, 1, 2)))(d, a, b)
    counts = linalg.clear_factor_cache()
    for u, v in zip(eager, jitted):
        np.testing.assert_allclose(u, v, rtol=1e-12, atol=1e-14)
    assert counts == {"factorizations": 1, "solves": 2}        # forward solve, then one more for the gradient
    # the gradient itself, by the adjoint formulas of the module docstring
    x = linalg.mesh_solve(mesh, d, a, b)
    bbar = linalg.mesh_solve(mesh, d, a, 2 * x)
    e = np.asarray(mesh.edges)
    np.testing.assert_allclose(jitted[2], bbar, rtol=1e-10)
    np.testing.assert_allclose(jitted[0], -np.sum(np.asarray(bbar) * np.asarray(x), 1), rtol=1e-10)
    want_a = -np.sum(np.asarray(bbar)[e[:, 0]] * np.asarray(x)[e[:, 1]]
                     + np.asarray(bbar)[e[:, 1]] * np.asarray(x)[e[:, 0]], 1)
    np.testing.assert_allclose(jitted[1], want_a, rtol=1e-10)


def test_vmap_over_right_hand_sides_and_over_matrices_equals_a_loop(system):
    mesh, d, a, b = system
    linalg.clear_factor_cache()
    cols = jax.vmap(lambda r: linalg.mesh_solve(mesh, d, a, r), in_axes=1, out_axes=1)(b)
    assert linalg.clear_factor_cache() == {"factorizations": 1, "solves": 1}   # one factor, one multi-column solve
    np.testing.assert_allclose(cols, linalg.mesh_solve(mesh, d, a, b), rtol=1e-13)
    scales = jnp.array([1.0, 2.0, 5.0])
    batch = jax.jit(jax.vmap(lambda s: linalg.mesh_solve(mesh, d * s, a * s, b)))(scales)
    for k, s in enumerate(scales):
        np.testing.assert_allclose(batch[k], linalg.mesh_solve(mesh, d * s, a * s, b), rtol=1e-12)
    np.testing.assert_allclose(batch[1], batch[0] / 2, rtol=1e-12)


def test_refusals():
    e = jnp.array([[0, 1], [1, 2]])
    b = jnp.ones(3)
    if linalg.default_backend() == "cholesky":
        with pytest.raises(ValueError, match="not positive definite"):
            linalg.sparse_solve(e, jnp.ones(3), jnp.array([2.0, 0.1]), b, backend="cholesky")
    # the indefinite matrix is fine for LU; a singular one is not
    x = linalg.sparse_solve(e, jnp.ones(3), jnp.array([2.0, 0.1]), b, backend="lu")
    np.testing.assert_allclose(linalg.sparse_matvec(e, jnp.ones(3), jnp.array([2.0, 0.1]), x), b, atol=1e-12)
    with pytest.raises(ValueError, match="singular"):
        linalg.sparse_solve(e, jnp.array([1.0, 2.0, 1.0]), jnp.array([-1.0, -1.0]), b, backend="lu")
    assert_refused(linalg.sparse_solve, e, jnp.ones(3), jnp.ones(2), b, backend="qr", param="backend",
                   message="backend must be one of")
    assert_refused(linalg.sparse_solve, e, jnp.ones(3), jnp.ones(2), jnp.ones(4), param="b",
                   message="b must have shape")
    assert_refused(linalg.sparse_solve, e, jnp.ones(3), jnp.ones(3), b, param="edge_values",
                   message="edge_values must have shape")


def test_implicit_flow_with_the_direct_solve_equals_cg_and_batches():
    from jaxmesh.denoise import METHODS

    s = trimesh.creation.icosphere(3)
    clean = jaxmesh.Mesh.from_arrays(s.vertices, s.faces)
    noisy = jaxmesh.add_noise(clean, 0.3, 4)
    flow = METHODS["cotangent_implicit"]
    direct = flow(noisy, solver="cholesky", iterations=2).vertices
    np.testing.assert_allclose(direct, flow(noisy, solver="cg", iterations=2).vertices, atol=1e-9)
    batch = noisy.with_vertices(jnp.stack([noisy.vertices, clean.vertices]))
    both = flow(batch, solver="cholesky", iterations=2).vertices
    np.testing.assert_allclose(both[0], direct, atol=1e-13)
    np.testing.assert_allclose(both[1], flow(clean, solver="cholesky", iterations=2).vertices, atol=1e-13)

    def loss(x, solver):
        return jnp.sum(flow(noisy.with_vertices(x), solver=solver, iterations=1).vertices ** 2)

    np.testing.assert_allclose(jax.grad(loss)(noisy.vertices, "cholesky"), jax.grad(loss)(noisy.vertices, "cg"),
                               atol=1e-7)


@pytest.mark.parametrize("backend", BACKENDS)
def test_the_laplacian_form_sums_the_diagonal_in_float64_and_differentiates(system, backend):
    mesh, _, a, b = system
    ground = jnp.zeros(mesh.num_vertices).at[3].set(1.0)
    e = np.asarray(mesh.edges)
    d = np.asarray(ground) - np.bincount(e.ravel(), np.repeat(np.asarray(a), 2), mesh.num_vertices)
    want = spla.spsolve(scipy_matrix(mesh.edges, d, np.asarray(a)), np.asarray(b))
    x = linalg.mesh_solve(mesh, ground, a, b, backend=backend, laplacian=True)
    np.testing.assert_allclose(x, want, rtol=1e-10, atol=1e-10)
    np.testing.assert_allclose(linalg.sparse_matvec(mesh.edges, ground, a, x, laplacian=True), b, atol=1e-10)

    def f(g, a, b):
        return jnp.sum(jnp.sin(linalg.mesh_solve(mesh, jnp.asarray(g), jnp.asarray(a), jnp.asarray(b),
                                                 backend=backend, laplacian=True)))

    check_grads(f, (ground + 0.5, a, b), order=1, modes=("fwd", "rev"), atol=1e-6, rtol=1e-6)
    # float32: a Laplacian grounded at one vertex (rows summing to 0 but for it) stays definite
    a32, b32 = a.astype(jnp.float32), (b - b.mean(0, keepdims=True)).astype(jnp.float32)
    x32 = linalg.mesh_solve(mesh, ground.astype(jnp.float32), a32, b32, backend=backend, laplacian=True)
    assert x32.dtype == jnp.float32
    ref = linalg.mesh_solve(mesh, ground, a32.astype(jnp.float64), b32.astype(jnp.float64), backend=backend,
                            laplacian=True)
    np.testing.assert_allclose(x32, ref, rtol=1e-5, atol=1e-5 * float(jnp.abs(ref).max()))


def test_a_broken_inner_solve_reaches_the_non_finite_check():
    """What the denoisers' inner CG solves (curvature flow, L0, impulse repair; ``throw=False``,
    ``.value``) rely on: lineax gives NaN when CG breaks down on an operator that is not positive
    definite, which the denoisers' non-finite check (``throw``) then reports; out of steps it gives
    a finite iterate (L0's alternating steps are inexact by design and end most inner solves so)."""
    import lineax as lx

    a = np.diag(np.linspace(1.0, 100.0, 20)) + 0.1
    b = jnp.asarray(np.linspace(-1.0, 1.0, 20))

    def solve(a, steps):
        op = lx.MatrixLinearOperator(jnp.asarray(a), lx.positive_semidefinite_tag)
        return lx.linear_solve(op, b, lx.CG(rtol=1e-12, atol=1e-12, max_steps=steps), throw=False)

    broken = solve(np.diag(np.r_[np.ones(10), -np.ones(10)]), 50)
    assert broken.result != lx.RESULTS.successful and np.all(np.isnan(np.asarray(broken.value)))
    short = solve(a, 1)
    assert short.result == lx.RESULTS.max_steps_reached and np.all(np.isfinite(np.asarray(short.value)))
    full = solve(a, 200)
    assert full.result == lx.RESULTS.successful
    np.testing.assert_allclose(np.asarray(full.value), np.linalg.solve(a, np.asarray(b)), rtol=1e-9)


def test_a_second_eager_call_compiles_nothing(system):
    """The host callback is one function per configuration, so an eager solve's program is kept: a
    second call with new values of the same shapes compiles nothing (JAX's compile events), as does a
    second shape_dna (the host eigensolver's callback)."""
    from jaxmesh import spectral

    mesh, d, a, b = system
    b2 = 2 * b
    compiles = []

    def listen(name, secs, **kw):
        if name.endswith("backend_compile_duration"):
            compiles.append(name)
    first = linalg.mesh_solve(mesh, d, a, b)
    dna = spectral.shape_dna(mesh, 3)
    jax.monitoring.register_event_duration_secs_listener(listen)
    try:
        second = linalg.mesh_solve(mesh, d, a, b2)
        again = spectral.shape_dna(mesh, 3)
    finally:
        jax.monitoring.unregister_event_duration_listener(listen)
    assert compiles == []
    np.testing.assert_allclose(second, 2 * first, rtol=1e-12)
    np.testing.assert_array_equal(again, dna)
