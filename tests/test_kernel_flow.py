"""The kernel flow (thesis ch.2 eq.6–12): independent numpy reference, the
translation defect of eq.7 and its corrected variant, gradients, jit, batches."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from conftest import assert_refused
from jax.test_util import check_grads

import jaxmesh
from jaxmesh.denoise import kernel_diffusion, kernel_weights


def numpy_paper_flow(v, faces, lam, iterations):
    """Plain loop over vertices of eq.7–10, 12 (neighbours from the faces directly)."""
    nbrs = [set() for _ in range(len(v))]
    for a, b, c in faces:
        nbrs[a] |= {b, c}
        nbrs[b] |= {a, c}
        nbrs[c] |= {a, b}
    nbrs = [sorted(n) for n in nbrs]
    deg = np.array([len(n) for n in nbrs], float)
    x = v.copy()
    for _ in range(iterations):
        new = x.copy()
        for i, n in enumerate(nbrs):
            c = x[n].mean(axis=0)
            h = sum(np.outer(x[j] - c, x[j] - c) for j in n) + lam * np.eye(3)
            hinv, det = np.linalg.inv(h), np.linalg.det(h)
            upd = np.zeros(3)
            for j in n:
                dlt = x[i] - x[j]
                k = det ** -0.5 * (2 * np.pi) ** -1.5 * np.exp(-0.5 * dlt @ hinv @ dlt)
                upd += k / np.sqrt(deg[i]) * (x[j] / np.sqrt(deg[j]) - x[i] / np.sqrt(deg[i]))
            new[i] = x[i] + upd
        x = new
    return x


@pytest.fixture(scope="module")
def noisy_spot():
    clean = jaxmesh.normalize(jaxmesh.data.load_sample("spot", dtype=np.float64))
    return clean, jaxmesh.add_noise(clean, 0.3, jax.random.PRNGKey(0))


def test_paper_variant_matches_numpy_reference(noisy_spot):
    _, noisy = noisy_spot
    ref = numpy_paper_flow(np.asarray(noisy.vertices), np.asarray(noisy.faces), 0.4, 2)
    out = kernel_diffusion(noisy, 0.4, 2, variant="paper").vertices
    np.testing.assert_allclose(out, ref, rtol=1e-6, atol=1e-9)


def test_translation_defect_of_the_paper_and_the_fix(noisy_spot):
    _, noisy = noisy_spot
    shift = jnp.array([0.5, 0.5, 0.5])
    moved = noisy.with_vertices(noisy.vertices + shift[None])
    rw = kernel_diffusion(noisy, 0.4, 3).vertices
    rw_moved = kernel_diffusion(moved, 0.4, 3).vertices - shift[None]
    np.testing.assert_allclose(rw_moved, rw, atol=1e-12)
    paper = kernel_diffusion(noisy, 0.4, 3, variant="paper").vertices
    paper_moved = kernel_diffusion(moved, 0.4, 3, variant="paper").vertices - shift[None]
    gap = float(jnp.max(jnp.linalg.norm(paper_moved - paper, axis=-1)))
    assert gap > 1e-4  # the origin leaks into eq.7 where neighbouring degrees differ


def test_kernel_matrix_diagonal_and_symmetry_of_weights_on_octahedron(octa):
    kappa, diag = kernel_weights(octa, octa.vertices, 0.5)
    # regular octahedron: every H_i is the same up to rotation, all κ_ij equal
    np.testing.assert_allclose(kappa, kappa[0], rtol=1e-12)
    np.testing.assert_allclose(diag, diag[0], rtol=1e-12)
    assert float(kappa[0]) < float(diag[0])


def test_random_walk_denoises(noisy_spot):
    clean, noisy = noisy_spot
    e0 = jaxmesh.metrics.visual_error(clean, noisy)
    e1 = jaxmesh.metrics.visual_error(clean, kernel_diffusion(noisy, 0.4, 5))
    assert float(e1) < 0.8 * float(e0)


@pytest.mark.parametrize("variant", [pytest.param("paper", marks=pytest.mark.slow), "random_walk"])
def test_gradients_with_respect_to_lambda_and_positions(bumpy_grid, variant):
    x = bumpy_grid.vertices
    # jitted: one compile each for the evaluations, the JVP and the VJP
    loss_lam = jax.jit(lambda lam: jnp.sum(kernel_diffusion(bumpy_grid, lam, 3, variant).vertices ** 2))
    check_grads(loss_lam, (jnp.asarray(0.7),), order=1, modes=("rev", "fwd"), eps=1e-6, atol=1e-6, rtol=1e-5)
    loss_x = jax.jit(lambda y: jnp.sum(jnp.sin(kernel_diffusion(bumpy_grid.with_vertices(y), 0.7, 2, variant).vertices)))
    check_grads(loss_x, (x,), order=1, modes=("rev",), eps=1e-6, atol=1e-6, rtol=1e-5)


def test_jit_vmap_and_batch_equal_single_calls(bumpy_grid):
    x = bumpy_grid.vertices
    batch = jnp.stack([x, x + 0.05 * jnp.sin(7 * x), x * 1.3])
    lams = jnp.array([0.3, 0.7, 1.1])
    f = lambda m, lam: kernel_diffusion(m, lam, 4).vertices  # noqa: E731
    batched = jax.jit(f)(bumpy_grid.with_vertices(batch), lams)
    vm = jax.vmap(lambda y, lam: f(bumpy_grid.with_vertices(y), lam))(batch, lams)
    for i in range(3):
        single = f(bumpy_grid.with_vertices(batch[i]), lams[i])
        np.testing.assert_allclose(batched[i], single, rtol=1e-12, atol=1e-14)
        np.testing.assert_allclose(vm[i], single, rtol=1e-12, atol=1e-14)


def test_bad_arguments(tetra):
    assert_refused(kernel_diffusion, tetra, 0.5, 1, variant="nope", param="variant", message="variant")
    with pytest.raises(ValueError, match="iterations"):
        kernel_diffusion(tetra, 0.5, -1)


def test_one_pass_covariances_equal_the_direct_formula(noisy_spot):
    from jaxmesh.denoise import neighborhood_covariances

    _, noisy = noisy_spot
    x = noisy.vertices + 100.0      # far from the origin: the one-pass form must not cancel
    h = neighborhood_covariances(noisy, x, 0.3)           # sum (x_j - c_i)(x_j - c_i)^T + λI, direct
    _, diag = kernel_weights(noisy.with_vertices(x), x, 0.3)
    np.testing.assert_allclose(diag, (2 * np.pi) ** -1.5 / np.sqrt(np.linalg.det(np.asarray(h))), rtol=1e-9)


def test_one_ring_tiers_cover_each_vertex_once_with_its_neighbours(noisy_spot):
    from jaxmesh.denoise import METHODS, ring_tiers, vertex_rings

    _, noisy = noisy_spot
    rings = vertex_rings(noisy)
    src, dst, deg = (np.asarray(a) for a in (noisy.src, noisy.dst, noisy.degree))
    widths = [t.neighbors.shape[1] for t in rings.tiers]
    assert widths == ring_tiers(np.maximum(deg, 1), pairs=False) and widths[-1] == deg.max()
    seen = np.concatenate([np.asarray(t.vertices) for t in rings.tiers])
    np.testing.assert_array_equal(np.sort(seen), np.arange(noisy.num_vertices))
    np.testing.assert_array_equal(seen[np.asarray(rings.order)], np.arange(noisy.num_vertices))
    for t in rings.tiers:
        for v, row, m in zip(np.asarray(t.vertices), np.asarray(t.neighbors), np.asarray(t.mask)):
            np.testing.assert_array_equal(row[m], dst[src == v])        # the mesh's own order
            assert np.all(row[~m] == v)                                 # padding: the vertex itself
    assert METHODS["kernel"].prepare(noisy) == {}      # optional: padded batches of meshes still tune


@pytest.mark.parametrize("variant,safeguard", [("random_walk", True), ("random_walk", False), ("paper", True)])
def test_one_ring_tiers_step_equals_the_segment_sums(variant, safeguard):
    """Degrees 2–9, a boundary and an isolated vertex; batched positions with one λ each."""
    from jaxmesh.denoise import kernel_step, vertex_rings

    clean = jaxmesh.normalize(jaxmesh.data.load_sample("spot", dtype=np.float64))
    v = np.r_[np.asarray(clean.vertices), [[3.0, 3.0, 3.0]]]
    f = np.asarray(clean.faces)[:-40]                           # cut a hole: boundary vertices
    mesh = jaxmesh.Mesh.from_arrays(v, f, warn=False)
    rings = vertex_rings(mesh)
    assert np.asarray(mesh.degree)[-1] == 0 and len(rings.tiers) > 1
    x = jnp.stack([mesh.vertices, mesh.vertices * 1.1 + 0.01 * jnp.sin(9 * mesh.vertices)])
    lam = jnp.array([0.2, 0.9])
    seg = kernel_step(mesh, x, lam, variant, safeguard)
    tiered = jax.jit(lambda m, y, r: kernel_step(m, y, lam, variant, safeguard, rings=r))(mesh, x, rings)
    np.testing.assert_allclose(tiered, seg, rtol=1e-12, atol=1e-15)
    np.testing.assert_array_equal(tiered[:, -1], x[:, -1])      # the isolated vertex stays
