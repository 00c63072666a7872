"""jaxmesh.intrinsic and jaxmesh.geodesics: edge flips checked by hand, the Delaunay
property and the metric kept on real meshes, the heat method against a plain
SciPy implementation of the paper, against exact geodesics, and its derivatives in
the vertex positions against finite differences."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
import scipy.sparse as sp
import scipy.sparse.linalg as spla
import trimesh
from jax.test_util import check_grads

import jaxmesh
from jaxmesh.geodesics import boundary_vertices, heat_distances
from jaxmesh.intrinsic import (cotangents_from_lengths, intrinsic_delaunay, intrinsic_lengths,
                               triangle_areas_from_lengths)
from conftest import assert_refused, grid_arrays, loop_cotangent_matrix, shared_mesh_path


def kite(fold: bool):
    """Two thin triangles (a, b, c), (b, a, d) on the long diagonal a–b, flat or folded
    by 90° about it: their angles at c and d are obtuse, so a–b must flip to c–d."""
    d = [1.0, 0.0, -0.2] if fold else [1.0, -0.2, 0.0]
    v = np.array([[0.0, 0, 0], [2, 0, 0], [1, 0.2, 0], d])
    return jaxmesh.Mesh.from_arrays(v, np.array([[0, 1, 2], [1, 0, 3]]))


@pytest.mark.parametrize("fold", [False, True])
def test_one_flip_by_hand(fold):
    mesh = kite(fold)
    tri = intrinsic_delaunay(mesh)
    assert tri.num_flips == 1
    e = int(tri.flips[0, 0])
    assert sorted(np.asarray(mesh.edges)[e]) == [0, 1]
    lengths = np.asarray(intrinsic_lengths(mesh, tri))
    # flat: the other diagonal, 0.4; folded: the same, measured across the unfolded pair
    # (the chord through space would be 0.2·√2)
    assert lengths[e] == pytest.approx(0.4, rel=1e-12)
    assert {frozenset(f) for f in tri.faces.tolist()} == {frozenset({2, 0, 3}), frozenset({3, 1, 2})}
    assert sorted(tri.pairs[tri.edge_pair[e]].tolist()) == [2, 3]
    l = lengths[tri.face_edges]
    assert triangle_areas_from_lengths(l, np).sum() == pytest.approx(0.4, rel=1e-12)   # 2 · ½ · 2 · 0.2


def test_flips_make_real_meshes_delaunay_and_keep_their_area():
    for name in ("shark.ply", "camelhead.ply"):
        mesh = jaxmesh.load(shared_mesh_path(name), dtype=np.float64)
        tri = intrinsic_delaunay(mesh)
        l = np.asarray(intrinsic_lengths(mesh, tri))[tri.face_edges]
        cot = cotangents_from_lengths(l, np)
        w = np.bincount(tri.face_edges.ravel(), 0.5 * cot.ravel(), tri.num_edges)
        interior = np.bincount(tri.face_edges.ravel(), minlength=tri.num_edges) == 2
        before = np.bincount(np.asarray(mesh.face_edges).ravel(), 0.5 * np.asarray(
            jaxmesh.geometry.corner_cotangents(mesh)).ravel(), mesh.num_edges)
        assert (before[interior] < -1e-6).sum() > 100 and tri.num_flips > 1000, name
        assert w[interior].min() > -1e-10, name                     # every interior weight ≥ 0
        area = float(jnp.sum(jaxmesh.geometry.face_areas(mesh)))
        assert triangle_areas_from_lengths(l, np).sum() == pytest.approx(area, rel=1e-12), name
        # no flip touches a boundary edge
        np.testing.assert_array_equal(np.asarray(boundary_vertices(mesh)).sum(),
                                      len(np.unique(np.asarray(mesh.edges)[~interior & (np.bincount(
                                          np.asarray(mesh.face_edges).ravel(), minlength=mesh.num_edges) == 1)])))


def test_intrinsic_lengths_are_differentiable_in_the_positions():
    v, f = grid_arrays(4, 3, jitter=0.25, seed=3)
    v = np.c_[v[:, :2], 0.3 * np.sin(v[:, 0]) * np.cos(v[:, 1])]
    mesh = jaxmesh.Mesh.from_arrays(v, f)
    tri = intrinsic_delaunay(mesh)
    assert tri.num_flips > 0
    lengths = jax.jit(lambda x: intrinsic_lengths(mesh.with_vertices(x), tri))
    w = jnp.asarray(np.random.default_rng(0).standard_normal(mesh.num_edges))
    check_grads(lambda x: jnp.dot(lengths(x), w), (mesh.vertices,), order=1, modes=("fwd", "rev"),
                atol=1e-6, rtol=1e-6, eps=1e-5)


def paper_heat_method(v, f, sources, t):
    """Crane et al. 2013 on the mesh's own triangles with SciPy, written from the paper
    (Neumann boundary, the heat step's negative weights clamped as the library does)."""
    n = len(v)
    w = 0.5 * loop_cotangent_matrix(v, f)
    area = np.zeros(len(f))
    grads = np.zeros((len(f), 3, 3))
    for k, tri in enumerate(f):
        p = v[tri]
        nrm = np.cross(p[1] - p[0], p[2] - p[0])
        area[k] = 0.5 * np.linalg.norm(nrm)
        unit = nrm / np.linalg.norm(nrm)
        for j in range(3):
            e = p[(j + 2) % 3] - p[(j + 1) % 3]                  # edge opposite corner j
            grads[k, j] = np.cross(unit, e) / (2 * area[k])
    mass = np.zeros(n)
    np.add.at(mass, f.ravel(), np.repeat(area / 3, 3))
    wc = np.maximum(w, 0)
    heat = sp.csc_matrix(np.diag(mass) + t * (np.diag(wc.sum(1)) - wc))
    ell = np.mean([np.linalg.norm(v[a] - v[b]) for a, b in {tuple(sorted(e)) for t_ in f for e in
                                                              ((t_[0], t_[1]), (t_[1], t_[2]), (t_[2], t_[0]))}])
    poisson = sp.csc_matrix(np.diag(w.sum(1)) - w + np.diag(1e-12 * mass / ell ** 2))
    out = []
    for s in sources:
        delta = np.zeros(n)
        delta[s] = 1
        u = spla.spsolve(heat, delta)
        b = np.zeros(n)
        for k, tri in enumerate(f):
            g = sum(u[tri[j]] * grads[k, j] for j in range(3))
            x = -g / np.linalg.norm(g)
            for j in range(3):
                b[tri[j]] += area[k] * grads[k, j] @ x
        phi = spla.spsolve(poisson, b)
        out.append(phi - phi[s])
    return np.array(out)


def test_heat_method_equals_a_plain_implementation_of_the_paper():
    v, f = grid_arrays(6, 5, jitter=0.15, seed=2)
    v = np.c_[v[:, :2], 0.2 * np.sin(v[:, 0])]
    mesh = jaxmesh.Mesh.from_arrays(v, f)
    src = np.array([0, 17, 40])
    t = 1.3 * float(jaxmesh.mean_edge_length(mesh)) ** 2
    got = heat_distances(mesh, src, t, boundary="neumann", intrinsic=False)
    np.testing.assert_allclose(got, paper_heat_method(v, f, src, t), rtol=1e-9, atol=1e-12)


def test_sources_in_blocks_equal_one_block_also_under_jit():
    """More sources than ``block``: solved a block at a time (the last padded), the same distances as
    one block, eagerly and under jit with the triangulation given; the padding never shows."""
    v, f = grid_arrays(6, 5, jitter=0.15, seed=2)
    mesh = jaxmesh.Mesh.from_arrays(np.c_[v[:, :2], 0.2 * np.sin(v[:, 0])], f)
    src = np.array([0, 17, 40, 3, 29, 11, 8])
    whole = heat_distances(mesh, src, block=64)
    np.testing.assert_allclose(heat_distances(mesh, src, block=3), whole, rtol=1e-12, atol=1e-14)
    tri = intrinsic_delaunay(mesh)
    jitted = jax.jit(lambda m, s: heat_distances(m, s, triangulation=tri, block=2))(mesh, jnp.asarray(src))
    assert jitted.shape == (7, mesh.num_vertices)
    np.testing.assert_allclose(jitted, whole, rtol=1e-12, atol=1e-14)


@pytest.mark.parametrize("boundary", ["average", "neumann", "dirichlet"])
@pytest.mark.parametrize("intrinsic", [True, False])
def test_concrete_inputs_take_host_solves_and_equal_the_one_program(boundary, intrinsic):
    """Concrete positions go through the stored stage programs with the solves called from
    the host; traced ones through one program with host callbacks. Both are the same steps:
    the distances agree to rounding, on an open mesh (the boundary conditions differ there)."""
    from jaxmesh.geodesics import heat_solver
    from jaxmesh import linalg

    v, f = grid_arrays(7, 6, jitter=0.2, seed=5)
    mesh = jaxmesh.Mesh.from_arrays(np.c_[v[:, :2], 0.3 * np.cos(v[:, 1])], f)
    tri = intrinsic_delaunay(mesh) if intrinsic else None
    inner = np.flatnonzero(~np.asarray(boundary_vertices(mesh)))      # a Dirichlet source on the boundary has u = 0
    src = inner[[0, 7, 3, 12, 5]]
    traced = jax.jit(lambda m: heat_distances(m, src, boundary=boundary, intrinsic=intrinsic,
                                              triangulation=tri))(mesh)
    linalg.clear_factor_cache()
    solve = heat_solver(mesh, boundary=boundary, intrinsic=intrinsic, triangulation=tri)
    host = solve(src)
    np.testing.assert_allclose(host, traced, rtol=1e-12, atol=1e-13)
    # further sources, in blocks, reuse the set-up and the factors: one per matrix in all
    np.testing.assert_allclose(solve(src[::-1], block=2), np.asarray(host)[::-1], rtol=1e-12, atol=1e-13)
    assert linalg.clear_factor_cache()["factorizations"] == {"average": 3, "neumann": 2, "dirichlet": 2}[boundary]


def test_boundary_conditions():
    s = trimesh.creation.icosphere(2)
    closed = jaxmesh.Mesh.from_arrays(s.vertices, s.faces)
    assert not bool(jnp.any(boundary_vertices(closed)))
    np.testing.assert_array_equal(heat_distances(closed, [0, 5]), heat_distances(closed, [0, 5], boundary="neumann"))
    v, f = grid_arrays(6, 6)
    flat = jaxmesh.Mesh.from_arrays(v, f)
    on = np.asarray(boundary_vertices(flat))
    assert on.sum() == 24 and not on[3 * 7 + 3]
    centre = 3 * 7 + 3
    exact = np.linalg.norm(v - v[centre], axis=1)
    for bc in ("average", "neumann", "dirichlet"):
        d = np.asarray(heat_distances(flat, [centre], boundary=bc))[0]
        assert np.abs(d - exact).mean() < 0.1 * exact.mean(), bc     # a flat grid: Euclidean distances


def test_heat_distances_close_to_exact_geodesics_on_thin_triangles():
    """The shark (8.7 % of its faces have an angle under 5°) and the open camel head,
    against exact geodesic paths (edge flips, Sharp & Crane 2020): the intrinsic
    Delaunay triangulation halves the error of the mesh's own triangles."""
    pp3d = pytest.importorskip("potpourri3d", reason="potpourri3d (the exact-geodesic reference) is not installed")
    for name, bound in (("shark.ply", 0.045), ("camelhead.ply", 0.025)):
        mesh = jaxmesh.load(shared_mesh_path(name), dtype=np.float64)
        v, f = np.asarray(mesh.vertices), np.asarray(mesh.faces)
        src = jaxmesh.stats.sample_sources(mesh, 5, seed=1)
        targets = np.random.default_rng(2).choice(len(v), 12, replace=False)
        solver = pp3d.EdgeFlipGeodesicSolver(v, f)
        exact = np.array([[np.linalg.norm(np.diff(solver.find_geodesic_path(int(s), int(t)), axis=0), axis=1).sum()
                           for t in targets] for s in src])
        ok = exact > 0
        rel = lambda d: np.abs(np.asarray(d)[:, targets][ok] - exact[ok]) / exact[ok]  # noqa: E731
        intrinsic = rel(heat_distances(mesh, src)).mean()
        own = rel(heat_distances(mesh, src, intrinsic=False)).mean()
        assert intrinsic < bound and intrinsic < 0.6 * own, (name, intrinsic, own)


def test_a_mesh_wound_inconsistently_gets_the_distances_of_its_oriented_copy():
    """A bumpy, jittered grid (thin triangles: the flips matter) with a third of its faces
    reversed: the intrinsic triangulation makes the same flips, and the heat distances are
    those of the consistently wound mesh (before, nothing was flipped on such a mesh, and
    its negative weights sent the heat flow below zero)."""
    v, f = grid_arrays(10, 8, jitter=0.35, seed=4)
    v = np.c_[v[:, :2], 0.4 * np.sin(v[:, 0]) * np.cos(0.7 * v[:, 1])]
    mesh = jaxmesh.Mesh.from_arrays(v, f)
    g = f.copy()
    r = np.random.default_rng(5).random(len(f)) < 0.33
    g[r] = g[r][:, [0, 2, 1]]
    messy = jaxmesh.Mesh.from_arrays(v, g)
    tri, tri_messy = intrinsic_delaunay(mesh), intrinsic_delaunay(messy)
    assert tri.num_flips > 10 and tri_messy.num_flips == tri.num_flips
    np.testing.assert_allclose(np.sort(np.asarray(intrinsic_lengths(messy, tri_messy))),
                               np.sort(np.asarray(intrinsic_lengths(mesh, tri))), rtol=1e-12)
    src = [0, 40, 97]
    np.testing.assert_allclose(np.asarray(heat_distances(messy, src)), np.asarray(heat_distances(mesh, src)),
                               rtol=1e-9, atol=1e-12)


def test_the_heat_step_is_an_m_matrix_on_a_defect_mesh():
    """The beetle of the shared defect meshes (two components, 47 non-manifold edges, on which
    two faces run the same way): the triangulation is flipped (it was not at all, with any
    directed edge used twice), every off-diagonal of the heat step is ≤ 0 (negative weights
    clamped, step 1 of the module docstring), and the statistic's heat distances are
    finite from every sampled source, close to the edge graph's (which overestimate)."""
    from jaxmesh import geodesics as G

    mesh = jaxmesh.load(shared_mesh_path("defects/beetle.ply"), dtype=np.float64)
    tri = intrinsic_delaunay(mesh)
    assert tri.num_flips > 500
    arrays = tuple(jnp.asarray(z) for z in (tri.faces, tri.face_edges, tri.flips, tri.pairs, tri.edge_pair))
    systems = G._systems(mesh, None, arrays, boundary="average")
    assert float(jnp.max(systems.heat_off)) <= 0.0 and float(jnp.max(systems.dir_off)) <= 0.0
    src = jaxmesh.stats.sample_sources(mesh, 40, seed=0)
    heat = jaxmesh.stats.heat_geodesics(mesh, src)
    edges = jaxmesh.stats.graph_distances(mesh, src)
    reach = np.isfinite(edges) & (edges > 0)
    assert np.array_equal(np.isfinite(heat), np.isfinite(edges))
    ratio = heat[reach] / edges[reach]
    assert 0.85 < np.median(ratio) < 1.0, np.median(ratio)


def test_heat_distances_are_differentiable_in_the_positions():
    s = trimesh.creation.icosphere(1)
    v = s.vertices * (1 + 0.1 * np.random.default_rng(0).standard_normal((len(s.vertices), 1)))
    mesh = jaxmesh.Mesh.from_arrays(v, s.faces)
    tri = intrinsic_delaunay(mesh)
    src = jnp.array([0, 7])
    w = jnp.asarray(np.random.default_rng(1).standard_normal((2, mesh.num_vertices)))

    @jax.jit
    def loss(x):
        return jnp.sum(w * heat_distances(mesh.with_vertices(x), src, triangulation=tri))

    np.testing.assert_allclose(loss(mesh.vertices), jnp.sum(w * heat_distances(mesh, src)), rtol=1e-12)
    check_grads(loss, (mesh.vertices,), order=1, modes=("fwd", "rev"), atol=1e-6, rtol=1e-6)


def test_refusals():
    s = trimesh.creation.icosphere(1)
    mesh = jaxmesh.Mesh.from_arrays(s.vertices, s.faces)
    with pytest.raises(ValueError, match="triangulation="):
        jax.jit(lambda x: heat_distances(mesh.with_vertices(x), [0]))(mesh.vertices)
    other = jaxmesh.Mesh.from_arrays(*grid_arrays(3, 3))
    with pytest.raises(ValueError, match="another mesh"):
        heat_distances(mesh, [0], triangulation=intrinsic_delaunay(other))
    with pytest.raises(ValueError, match="sources must lie"):
        heat_distances(mesh, [0, mesh.num_vertices])
    assert_refused(heat_distances, mesh, [0], boundary="robin", param="boundary", message="boundary must be one of")


@pytest.mark.slow   # 7 s: two heat programs on spot in each precision
def test_float32_distances_agree_with_float64_or_are_refused_naming_it():
    spot = jaxmesh.data.load_sample("spot", dtype=np.float64)
    strip = jaxmesh.Mesh.from_arrays(*grid_arrays(60, 2))      # u ~ e^-60 at its end: |∇u|² below float32's range
    for mesh, src in ((spot, np.array([0, 700, 2000])), (strip, np.array([0, 100]))):
        d64 = np.asarray(heat_distances(mesh, src))
        d32 = heat_distances(jaxmesh.Mesh.from_arrays(np.asarray(mesh.vertices, np.float32), mesh.faces), src)
        assert d32.dtype == jnp.float32
        np.testing.assert_allclose(d32, d64, rtol=0, atol=1e-5 * d64.max())
    v, f = grid_arrays(160, 2)                   # a strip 160 edges long: e^-160 is below float32's range
    with pytest.raises(ValueError, match="underflows in float32 .* use float64"):
        heat_distances(jaxmesh.Mesh.from_arrays(v.astype(np.float32), f), [0])
    far = np.asarray(heat_distances(jaxmesh.Mesh.from_arrays(v, f), [0]))[0]
    assert np.isfinite(far).all() and abs(far.max() - np.hypot(160, 2)) < 0.1 * 160


@pytest.mark.slow   # 5 s: three heat programs and the probe's larger diffusion times
def test_a_mesh_longer_than_the_float64_heat_flow_reaches_gets_a_larger_t_in_the_statistics():
    """A strip 1 000 edges long: at t = ℓ̄² the heat flow (exp(−d/√t)) underflows in float64
    before its end, which heat_distances refuses, saying to pass a larger t (it said "use
    float64" in float64).  The statistics' distances choose the least 4^j ℓ̄² that reaches
    (a 556k-vertex scan failed `jaxmesh stats` this way): finite, within 3 % of the plane's
    exact distances; a mesh the default reaches keeps t = ℓ̄² (the same distances)."""
    from jaxmesh.stats import heat_geodesics

    v, f = grid_arrays(1000, 2)
    strip = jaxmesh.Mesh.from_arrays(v, f)
    with pytest.raises(ValueError, match="underflows in float64 .* pass a larger t"):
        heat_distances(strip, [0])
    d = heat_geodesics(strip, [0, 1500])
    exact = np.linalg.norm(v[None, :, :2] - v[[0, 1500]][:, None, :2], axis=-1)
    assert np.isfinite(d).all()
    assert np.abs(d - exact).max() < 0.03 * exact.max(), np.abs(d - exact).max()
    short = jaxmesh.Mesh.from_arrays(*grid_arrays(60, 2))
    np.testing.assert_array_equal(heat_geodesics(short, [0, 5]), np.asarray(heat_distances(short, [0, 5],
                                  triangulation=intrinsic_delaunay(short), boundary="average")))


def test_component_labels_name_each_component_by_its_first_vertex_and_can_be_passed_in():
    """heat_components against scipy's components of the faces with area (two boxes and an
    isolated vertex); distances with the labels passed in equal those computed without."""
    import trimesh
    from scipy.sparse.csgraph import connected_components

    from jaxmesh.geodesics import heat_components

    a, b = trimesh.creation.box(), trimesh.creation.box()
    v = np.vstack([a.vertices, b.vertices + 3.0, [[9.0, 9.0, 9.0]]])
    f = np.vstack([a.faces, b.faces + len(a.vertices)])
    mesh = jaxmesh.Mesh.from_arrays(v, f, warn=False)
    given = heat_components(mesh)
    labels = np.asarray(given)
    _, ref = connected_components(jaxmesh.sparse.adjacency_matrix(mesh), directed=False)
    first = {c: np.flatnonzero(ref == c)[0] for c in np.unique(ref)}
    np.testing.assert_array_equal(labels, [first[c] for c in ref])
    src = np.array([0, 9])
    np.testing.assert_array_equal(heat_distances(mesh, src, components=given), heat_distances(mesh, src))
