"""Graph and cotangent operators: hand values, plain-loop and networkx references,
sparse export, invariants, gradients, jit."""

import jax
import jax.numpy as jnp
import networkx as nx
import numpy as np
import pytest
import trimesh
from jax.test_util import check_grads

import jaxmesh
from jaxmesh import operators as O
from jaxmesh import sparse as S
from conftest import grid_arrays, loop_cotangent_matrix, shared_mesh_path


def test_tetrahedron_hand_values(tetra):
    x = tetra.vertices  # v0 = origin, the others unit vectors
    np.testing.assert_allclose(O.laplacian(tetra, x)[0], [-1, -1, -1])
    np.testing.assert_allclose(O.umbrella(tetra, x)[0], [1 / 3, 1 / 3, 1 / 3])
    np.testing.assert_allclose(O.umbrella(tetra, x)[1], [-1, 1 / 3, 1 / 3])
    # all degrees 3: normalized Laplacian = I - A/3
    np.testing.assert_allclose(O.normalized_laplacian(tetra, x)[1], [1, 0, 0] - np.array([0, 1, 1]) / 3)


def test_octahedron_laplace_beltrami_hand_value(octa):
    # equilateral faces: cot 60 = 1/sqrt3, edge weight 2/sqrt3, eta_i = 4 * sqrt3/2,
    # w_ij = 3 (2/sqrt3) / (2 sqrt3) = 1, so Δ_m v_0 = sum_j (v_j - v_0) = (-4, 0, 0)
    np.testing.assert_allclose(O.laplace_beltrami_weights(octa), np.ones(24))
    np.testing.assert_allclose(O.laplace_beltrami(octa, octa.vertices)[0], [-4, 0, 0], atol=1e-14)
    np.testing.assert_allclose(O.cotangent_weights(octa), np.full(12, 2 / np.sqrt(3)))


def test_grid_cotangent_hand_values(grid):
    # right isosceles triangles: diagonals face two right angles (weight 0); an axis
    # edge sees 45-degree angles: 2 cotangents inside, 1 on the boundary
    e = np.asarray(grid.edges)
    v = np.asarray(grid.vertices)
    c = np.asarray(O.cotangent_weights(grid))
    d = v[e[:, 1]] - v[e[:, 0]]
    diagonal = (np.abs(d[:, 0]) > 0) & (np.abs(d[:, 1]) > 0)
    on_boundary = np.zeros(len(e), bool)
    on_boundary[np.searchsorted(e[:, 0] * 100 + e[:, 1], [a * 100 + b for a, b in
                                 jaxmesh.topology.boundary_edges(grid)])] = True
    np.testing.assert_allclose(c[diagonal], 0, atol=1e-15)
    np.testing.assert_allclose(c[~diagonal & on_boundary], 1)
    np.testing.assert_allclose(c[~diagonal & ~on_boundary], 2)


def test_cotangent_and_laplace_beltrami_against_plain_loops(bumpy_grid):
    v, f = np.asarray(bumpy_grid.vertices), np.asarray(bumpy_grid.faces)
    w = loop_cotangent_matrix(v, f)
    np.testing.assert_allclose(S.cotangent_weight_matrix(bumpy_grid).toarray(), w, atol=1e-12)
    eta = np.zeros(len(v))
    for tri in f:
        eta[tri] += 0.5 * np.linalg.norm(np.cross(v[tri[1]] - v[tri[0]], v[tri[2]] - v[tri[0]]))
    wl = 3 * w / eta[:, None]
    ref = np.diag(wl.sum(1)) - wl
    np.testing.assert_allclose(S.laplace_beltrami_matrix(bumpy_grid).toarray(), ref, atol=1e-12)
    x = np.random.default_rng(0).standard_normal(v.shape)
    np.testing.assert_allclose(O.laplace_beltrami(bumpy_grid, jnp.asarray(x)), -ref @ x, atol=1e-11)
    np.testing.assert_allclose(O.cotangent_laplacian(bumpy_grid, jnp.asarray(x)),
                               0.5 * (w - np.diag(w.sum(1))) @ x, atol=1e-11)


def test_cotangent_laplacian_reference_on_real_mesh():
    m = jaxmesh.load(shared_mesh_path("eight.ply"), dtype=jnp.float64)
    w = loop_cotangent_matrix(np.asarray(m.vertices), np.asarray(m.faces))
    np.testing.assert_allclose(S.cotangent_weight_matrix(m).toarray(), w, atol=1e-10)


def test_linear_precision_of_cotangent_laplacian():
    v, f = grid_arrays(5, 4, jitter=0.2, seed=3)
    v[:, 2] = 0.0  # planar, irregular
    m = jaxmesh.Mesh.from_arrays(v, f)
    interior = np.ones(len(v), bool)
    interior[np.unique(jaxmesh.topology.boundary_edges(m))] = False
    out = O.cotangent_laplacian(m, m.vertices)
    np.testing.assert_allclose(out[interior], 0, atol=1e-12)


def test_graph_matrices_against_networkx(spot):
    g = nx.Graph()
    g.add_nodes_from(range(spot.num_vertices))
    g.add_edges_from(np.asarray(spot.edges).tolist())
    nodes = list(range(spot.num_vertices))
    np.testing.assert_array_equal(S.adjacency_matrix(spot).toarray(), nx.to_numpy_array(g, nodelist=nodes))
    np.testing.assert_allclose(S.laplacian_matrix(spot).toarray(),
                               nx.laplacian_matrix(g, nodelist=nodes).toarray())
    np.testing.assert_allclose(S.normalized_laplacian_matrix(spot).toarray(),
                               nx.normalized_laplacian_matrix(g, nodelist=nodes).toarray(), atol=1e-14)


@pytest.mark.parametrize("name,op", [
    ("adjacency_matrix", O.neighbor_sum),
    ("laplacian_matrix", O.laplacian),
    ("normalized_laplacian_matrix", O.normalized_laplacian),
    ("umbrella_matrix", O.umbrella),
    ("laplace_beltrami_matrix", lambda m, x: -O.laplace_beltrami(m, x)),
    ("cotangent_laplacian_matrix", O.cotangent_laplacian),
])
def test_sparse_export_matches_operator(bumpy_grid, name, op):
    x = np.random.default_rng(1).standard_normal((bumpy_grid.num_vertices, 2))
    mat = getattr(S, name)(bumpy_grid)
    np.testing.assert_allclose(mat @ x, op(bumpy_grid, jnp.asarray(x)), atol=1e-12)


def test_invariants(spot):
    k = S.umbrella_matrix(spot)
    np.testing.assert_allclose(np.asarray(k.sum(axis=1)).ravel(), 0, atol=1e-14)
    ones = jnp.ones((spot.num_vertices, 1))
    np.testing.assert_allclose(O.umbrella(spot, ones), 0, atol=1e-14)
    np.testing.assert_allclose(O.laplacian(spot, ones), 0, atol=1e-14)
    np.testing.assert_allclose(O.laplace_beltrami(spot, ones), 0, atol=1e-9)
    lap = S.laplacian_matrix(spot)
    assert abs(lap - lap.T).max() == 0
    nl = S.normalized_laplacian_matrix(spot)
    assert abs(nl - nl.T).max() < 1e-15
    cl = S.cotangent_laplacian_matrix(spot)
    assert abs(cl - cl.T).max() < 1e-12
    # spectrum of 𝓛 in [0, 2] with one zero per component; K's in [-2, 0]: dense
    # eigenvalues, so on a 642-vertex sphere with jittered positions (degrees 5 and 6)
    s = trimesh.creation.icosphere(3)
    small = jaxmesh.Mesh.from_arrays(s.vertices * (1 + 0.1 * np.random.default_rng(0).random((len(s.vertices), 1))),
                                     s.faces)
    ev = np.linalg.eigvalsh(S.normalized_laplacian_matrix(small).toarray())
    assert ev.min() > -1e-10 and ev.max() < 2 + 1e-10 and np.sum(np.abs(ev) < 1e-9) == 1
    evk = np.linalg.eigvals(S.umbrella_matrix(small).toarray()).real
    assert evk.min() > -2 - 1e-9 and evk.max() < 1e-9
    # the edge count identities of ch.1: |E| = trace(D)/2 = trace(A^2)/2
    a = S.adjacency_matrix(spot)
    assert (a @ a).diagonal().sum() / 2 == spot.num_edges == S.degree_matrix(spot).diagonal().sum() / 2


def test_vertex_laplace_is_minus_normalized_laplacian_and_not_translation_invariant(spot):
    x = spot.vertices
    np.testing.assert_allclose(O.vertex_laplace(spot, x), -O.normalized_laplacian(spot, x), atol=1e-13)
    shifted = O.vertex_laplace(spot, x + 0.5) - O.vertex_laplace(spot, x)
    assert float(jnp.max(jnp.abs(shifted))) > 1e-3  # eq.10 leaks the origin where degrees differ
    np.testing.assert_allclose(O.umbrella(spot, x + 0.5), O.umbrella(spot, x), atol=1e-12)


def test_gradient_magnitude_variants(tetra):
    x = tetra.vertices
    # all degrees 3: paper variant = translation-invariant variant / sqrt(3)
    np.testing.assert_allclose(O.gradient_magnitude(tetra, x),
                               O.gradient_magnitude(tetra, x, "translation_invariant") / np.sqrt(3))
    np.testing.assert_allclose(O.gradient_magnitude(tetra, x, "translation_invariant")[0], np.sqrt(3))
    with pytest.raises(ValueError, match="variant"):
        O.gradient_magnitude(tetra, x, "other")


OPS = [O.neighbor_sum, O.laplacian, O.normalized_laplacian, O.umbrella, O.vertex_laplace,
       O.laplace_beltrami, O.cotangent_laplacian,
       lambda m, x: O.gradient_magnitude(m, x)[..., None],
       lambda m, x: O.vertex_gradient(m, x)]


@pytest.mark.parametrize("k", range(len(OPS)))
def test_operator_gradients_jit_and_batch(bumpy_grid, k):
    op = OPS[k]
    x = bumpy_grid.vertices
    w = jnp.asarray(np.random.default_rng(k).standard_normal(np.shape(op(bumpy_grid, x))))
    # gradient with respect to the positions (they enter the cotangent weights too)
    # check_grads evaluates at numpy points: the operators are annotated (and checked) for JAX arrays
    loss = lambda y: jnp.sum(w * op(bumpy_grid.with_vertices(jnp.asarray(y)), jnp.asarray(y)))  # noqa: E731
    check_grads(loss, (x,), order=1, modes=("rev",), eps=1e-6, atol=1e-5, rtol=1e-5)
    with jax.disable_jit():      # the operators' bodies are jitted: eager means one primitive at a time
        eager = op(bumpy_grid, x)
    np.testing.assert_allclose(jax.jit(op)(bumpy_grid, x), eager, rtol=1e-12, atol=1e-13)
    np.testing.assert_allclose(op(bumpy_grid, x), eager, rtol=1e-12, atol=1e-13)
    batch = jnp.stack([x, 2.0 * x, x + 1.0])
    out = op(bumpy_grid.with_vertices(batch), batch)
    for i in range(3):
        np.testing.assert_allclose(out[i], op(bumpy_grid.with_vertices(batch[i]), batch[i]),
                                   rtol=1e-12, atol=1e-13)


def test_sparse_export_refuses_batches(tetra):
    with pytest.raises(ValueError, match="single mesh"):
        S.edge_length_matrix(tetra.with_vertices(jnp.stack([tetra.vertices] * 2)))
    np.testing.assert_allclose(S.edge_length_matrix(tetra)[1, 2], np.sqrt(2))


def _fan_with_an_isolated_vertex() -> jaxmesh.Mesh:
    """A 12-triangle fan (its hub of degree 12), a 40 x 40 grid (degree at most 6: the hub gets
    a tier of its own) and an isolated vertex."""
    k = 12
    ring = np.stack([np.cos(2 * np.pi * np.arange(k) / k), np.sin(2 * np.pi * np.arange(k) / k),
                     0.1 * np.arange(k) % 0.3], axis=1)
    gv, gf = grid_arrays(40, 40, jitter=0.1, seed=2)
    v = np.concatenate([[[0.0, 0, 0.2]], ring, gv + [50.0, 0, 0], [[9, 9, 9]]])
    f = np.concatenate([[[0, 1 + i, 1 + (i + 1) % k] for i in range(k)], gf + k + 1])
    with pytest.warns(jaxmesh.MeshWarning, match="isolated"):
        return jaxmesh.Mesh.from_arrays(v, f)


@pytest.mark.parametrize("name", ["bumpy_grid", "fan"])
def test_ring_umbrella_is_the_umbrella(request, name):
    from jaxmesh.denoise import ring_umbrella, vertex_rings

    mesh = _fan_with_an_isolated_vertex() if name == "fan" else request.getfixturevalue(name)
    rings = vertex_rings(mesh)
    x = jax.random.normal(jax.random.PRNGKey(3), (2, mesh.num_vertices, 3), mesh.dtype)
    # the neighbours summed in the edge list's order: the segment sums' values up to rounding
    np.testing.assert_allclose(ring_umbrella(rings, x[0]), O.umbrella(mesh, x[0]), rtol=0, atol=1e-14)
    np.testing.assert_allclose(jax.jit(ring_umbrella)(rings, x), O.umbrella(mesh, x), rtol=0, atol=1e-14)
    if name == "fan":
        assert len(rings.tiers) > 1 and np.all(np.asarray(ring_umbrella(rings, x[0]))[-1] == 0)


@pytest.mark.parametrize("method", ["taubin", "umbrella_flow", "hc"])
def test_smoothing_filters_on_the_rings_equal_the_segment_sums(bumpy_grid, method):
    from jaxmesh.denoise import METHODS

    m = METHODS[method]
    eager = m(bumpy_grid, iterations=7).vertices                     # the rings built on the host and passed
    assert "rings" in m.host_inputs
    traced = jax.jit(lambda mesh: m.function(mesh, iterations=7).vertices)(bumpy_grid)   # traced: segment sums
    np.testing.assert_allclose(eager, traced, rtol=0, atol=1e-12)
    curve = m(bumpy_grid, iterations=7, boundary="curve").vertices   # the boundary-curve form ignores the rings
    np.testing.assert_allclose(curve, jax.jit(lambda mesh: m.function(mesh, iterations=7, boundary="curve").vertices)(
        bumpy_grid), rtol=0, atol=1e-12)
    assert np.abs(np.asarray(curve) - np.asarray(eager)).max() > 1e-3
