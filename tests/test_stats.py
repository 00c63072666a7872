"""Mesh statistics (thesis ch.5) against networkx and scipy, and the heat
method against exact great-circle distances on a sphere."""


import networkx as nx
import numpy as np
import pytest
import scipy.linalg
import trimesh

import jaxmesh
from jaxmesh import stats

from conftest import assert_refused, shared_mesh_path


def as_networkx(mesh):
    g = nx.Graph()
    g.add_nodes_from(range(mesh.num_vertices))
    g.add_edges_from(np.asarray(mesh.edges).tolist())
    return g


@pytest.fixture(scope="module", params=["camelhead.ply", "cow.ply", "fertility.ply"])
def real(request):
    mesh = jaxmesh.load(shared_mesh_path(request.param))
    return mesh, as_networkx(mesh)


def by_node(d, n):
    return np.array([d[i] for i in range(n)])


def test_clustering_matches_networkx(real):
    mesh, g = real
    np.testing.assert_allclose(stats.clustering(mesh), by_node(nx.clustering(g), mesh.num_vertices), atol=1e-12)
    tri = nx.triangles(g)
    np.testing.assert_array_equal(stats.triangle_counts(mesh), by_node(tri, mesh.num_vertices))


@pytest.mark.parametrize("grouped", [True, False])
def test_triangle_counts_by_out_degree_groups_or_one_group_match_networkx(monkeypatch, grouped):
    """Both layouts of the forward search (one group per out-degree, the large-graph path; one
    group) against networkx, on random faces (hubs, chords and triangles that are no face:
    out-degrees spread far wider than a mesh's) and on a real mesh."""
    import importlib

    monkeypatch.setattr(importlib.import_module("jaxmesh.stats.clustering"), "GROUPED_VERTICES",
                        0 if grouped else 10**9)
    rng = np.random.default_rng(5)
    faces = np.array([rng.choice(40, 3, replace=False) for _ in range(300)])
    faces[:40] = [[0, *rng.choice(np.arange(1, 40), 2, replace=False)] for _ in range(40)]       # a hub
    tangled = jaxmesh.Mesh.from_arrays(rng.normal(size=(45, 3)), faces, warn=False)             # 5 isolated
    for mesh in (tangled, jaxmesh.load(shared_mesh_path("camelhead.ply"))):
        want = by_node(nx.triangles(as_networkx(mesh)), mesh.num_vertices)
        np.testing.assert_array_equal(stats.triangle_counts(mesh), want)
    assert want.sum() > 0 and by_node(nx.triangles(as_networkx(tangled)), 45).max() > 20


def test_degree_statistics_match_networkx(real):
    mesh, g = real
    n = mesh.num_vertices
    np.testing.assert_allclose(stats.neighbor_connectivity(mesh), by_node(nx.average_neighbor_degree(g), n),
                               atol=1e-12)
    np.testing.assert_allclose(stats.degree_assortativity(mesh), nx.degree_assortativity_coefficient(g),
                               atol=1e-10)
    ks, knn = stats.assortativity_function(mesh)
    ref = nx.average_degree_connectivity(g)
    np.testing.assert_allclose(knn, [ref[k] for k in ks], atol=1e-12)
    ks, pk = stats.degree_distribution(mesh)
    hist = nx.degree_histogram(g)
    np.testing.assert_allclose(pk, [hist[k] / n for k in ks])
    assert stats.average_degree(mesh) == pytest.approx(2 * g.number_of_edges() / n)


def test_laplacian_spectrum_matches_networkx_dense_and_sparse():
    mesh = jaxmesh.load(shared_mesh_path("eight.ply"))
    g = as_networkx(mesh)
    for kind, ref_mat in (("combinatorial", nx.laplacian_matrix(g)), ("normalized", nx.normalized_laplacian_matrix(g))):
        ref = scipy.linalg.eigvalsh(ref_mat.toarray())
        rank, vals = stats.laplacian_spectrum(mesh, kind)
        np.testing.assert_allclose(vals, ref, atol=1e-9)
        assert rank[0] == 0 and rank[-1] == 1
        rank_k, vals_k = stats.laplacian_spectrum(mesh, kind, k=10)     # extremes through eigsh
        np.testing.assert_allclose(vals_k, np.r_[ref[:10], ref[-10:]], atol=1e-7)
        np.testing.assert_allclose(rank_k, np.r_[rank[:10], rank[-10:]])


def test_spectral_density_moments_are_the_exact_spectrums_chebyshev_moments():
    """μ_m = (1/n) Σ_i T_m(x_i) over the exact eigenvalues x_i mapped to [−1, 1] (numpy's Chebyshev
    series of the dense spectrum), within the stochastic trace's error (R probes: σ ≈ √(2/(nR))),
    for both Laplacians; the Jackson factors start at 1 and fall to ≈ 0."""
    from jaxmesh.stats.density import jackson

    mesh = jaxmesh.load(shared_mesh_path("eight.ply"))
    n, probes = mesh.num_vertices, 256
    for kind in ("combinatorial", "normalized"):
        _, lam = stats.laplacian_spectrum(mesh, kind)
        d = stats.spectral_density(mesh, kind, moments=40, probes=probes)
        a, b = d.bounds
        assert d.support[1] == pytest.approx(lam.max(), rel=1e-6)
        x = (lam - (a + b) / 2) / ((b - a) / 2)
        exact = np.array([np.polynomial.chebyshev.chebval(x, np.eye(40)[m]).mean() for m in range(40)])
        got = d.moments / jackson(40)
        assert np.max(np.abs(got - exact)) < 6 * np.sqrt(2 / (n * probes))
    g = jackson(256)
    assert g[0] == pytest.approx(1.0) and np.all(np.diff(g) <= 1e-15) and abs(g[-1]) < 1e-3


def _cone(sides: int) -> jaxmesh.Mesh:
    """A closed double cone: two apexes of degree ``sides`` over a ring of ``sides`` vertices."""
    angle = 2 * np.pi * np.arange(sides) / sides
    v = np.r_[np.c_[np.cos(angle), np.sin(angle), np.zeros(sides)], [[0, 0, 1], [0, 0, -1]]]
    i, j = np.arange(sides), (np.arange(sides) + 1) % sides
    f = np.r_[np.c_[i, j, np.full(sides, sides)], np.c_[j, i, np.full(sides, sides + 1)]]
    return jaxmesh.Mesh.from_arrays(v, f)


def test_the_row_table_products_equal_scipys_also_past_its_width():
    """The padded table plus the leftover triples multiply as the sparse matrix does, for widths
    below, at and above the longest row (the cone's apexes: 40 entries and their diagonal)."""
    from jaxmesh.stats.density import _row_table, laplacian_of_kind

    mat, _ = laplacian_of_kind(_cone(40), "normalized")
    x = np.random.default_rng(0).normal(size=(mat.shape[0], 3))
    for width in (1, 3, 16, 41, 100):
        (columns, values), (rows, cols, vals) = _row_table(mat, width)
        past = np.maximum(np.diff(mat.indptr) - width, 0).sum()        # apexes 41 entries, ring vertices 5
        assert columns.shape[1] == min(width, 41) and len(vals) == past and (past > 0) == (width < 41)
        product = np.einsum("nk,nkr->nr", values, x[columns])
        np.add.at(product, rows, vals[:, None] * x[cols])
        np.testing.assert_allclose(product, mat @ x, atol=1e-13)


def test_spectral_density_of_a_mesh_with_rows_past_the_table():
    """A vertex of degree 40 (past ``ROW_WIDTH``): the moments are still the exact spectrum's."""
    from jaxmesh.stats.density import ROW_WIDTH, jackson

    mesh = _cone(40)
    assert int(np.max(mesh.degree)) + 1 > ROW_WIDTH
    n, probes = mesh.num_vertices, 512
    for kind in ("combinatorial", "normalized"):
        _, lam = stats.laplacian_spectrum(mesh, kind)
        d = stats.spectral_density(mesh, kind, moments=20, probes=probes)
        a, b = d.bounds
        x = (lam - (a + b) / 2) / ((b - a) / 2)
        exact = np.array([np.polynomial.chebyshev.chebval(x, np.eye(20)[m]).mean() for m in range(20)])
        assert np.max(np.abs(d.moments / jackson(20) - exact)) < 6 * np.sqrt(2 / (n * probes))


@pytest.mark.parametrize("name", ["eight.ply", pytest.param("cow.ply", marks=pytest.mark.slow)])  # cow's exact: 4 s
def test_the_estimated_spectrum_is_within_2_percent_of_the_exact_one(name):
    """Wasserstein-1 distance between the kernel-polynomial distribution and the exact spectrum
    ≤ 2% of the spectrum's range on shared meshes (measured: 0.06–0.25%); laplacian_spectrum's
    large-mesh path is that distribution's quantile function, within the support."""
    mesh = jaxmesh.load(shared_mesh_path(name))
    for kind in ("combinatorial", "normalized"):
        rank, lam = stats.laplacian_spectrum(mesh, kind)
        d = stats.spectral_density(mesh, kind)
        assert stats.spectrum_distance(d, lam) < 0.02 * (lam.max() - lam.min())
        assert d.cdf[0] == 0 and d.cdf[-1] == pytest.approx(1, abs=1e-9) and np.all(np.diff(d.cdf) >= 0)
        assert np.all(d.density >= 0)
        ranks, estimate = stats.laplacian_spectrum(mesh, kind, dense_max=100)
        assert ranks[0] == 0 and ranks[-1] == 1 and estimate.min() >= 0 and estimate.max() <= lam.max() * (1 + 1e-9)
        assert np.mean(np.abs(estimate - np.interp(ranks, rank, lam))) < 0.02 * lam.max()


def test_spectrum_distance_by_hand_and_bad_arguments():
    """W₁ between the uniform law on [0, 1] and a point mass at ½ is ∫|x − 1[x ≥ ½]| = ¼."""
    grid = np.linspace(0.0, 1.0, 4001)
    uniform = stats.SpectralDensity(grid, grid, np.ones_like(grid), np.zeros(2), (0.0, 1.0), (0.0, 1.0))
    assert stats.spectrum_distance(uniform, [0.5]) == pytest.approx(0.25, abs=1e-3)
    assert stats.spectrum_distance(uniform, np.linspace(0, 1, 2001)) < 1e-3
    np.testing.assert_allclose(stats.density_quantiles(uniform, [0.0, 0.3, 1.0]), [0.0, 0.3, 1.0], atol=1e-6)
    mesh = jaxmesh.load(shared_mesh_path("eight.ply"))
    with pytest.raises(ValueError, match="kind"):
        stats.spectral_density(mesh, "signless")
    with pytest.raises(ValueError, match="moments"):
        stats.spectral_density(mesh, moments=1)
    assert_refused(stats.spectral_density, mesh, seed=1.5, param="seed", message="seed must be an int")
    with pytest.raises(ValueError, match="ranks"):
        stats.density_quantiles(uniform, [1.5])


def test_thesis_clustering_equals_general_definition_on_closed_manifold_interior():
    mesh = jaxmesh.load(shared_mesh_path("fandisk.ply"))       # closed, manifold
    c, ct = stats.clustering(mesh), stats.thesis_clustering(mesh)
    d = np.asarray(mesh.degree)
    t = stats.triangle_counts(mesh)
    no_chords = t == d                                          # link is one cycle without chords
    assert no_chords.mean() > 0.99
    np.testing.assert_allclose(c[no_chords], ct[no_chords], atol=1e-12)
    # where they differ: a tetrahedron (every neighbour pair is joined) and a boundary vertex
    tet = jaxmesh.Mesh.from_arrays(np.eye(4)[:, :3] + [[0, 0, 0]] * 4 + np.r_[np.zeros((3, 3)), [[1, 1, 1]]],
                                   [[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])
    assert np.allclose(stats.clustering(tet), 1.0) and np.allclose(stats.thesis_clustering(tet), 1.0)
    strip = jaxmesh.Mesh.from_arrays(np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]]),
                                     [[0, 1, 2], [1, 3, 2]])
    np.testing.assert_allclose(stats.clustering(strip), [1, 2 / 3, 2 / 3, 1])
    np.testing.assert_allclose(stats.thesis_clustering(strip), [2, 1, 1, 2])


def test_graph_geodesics_match_scipy_dijkstra():
    mesh = jaxmesh.load(shared_mesh_path("eight.ply"))
    v, e = np.asarray(mesh.vertices), np.asarray(mesh.edges)
    g = as_networkx(mesh)
    for a, b in e:
        g[a][b]["w"] = float(np.linalg.norm(v[a] - v[b]))
    src = stats.sample_sources(mesh, 5, seed=3)
    ours = stats.graph_distances(mesh, src)
    for row, s in zip(ours, src):
        ref = nx.single_source_dijkstra_path_length(g, int(s), weight="w")
        np.testing.assert_allclose(row, by_node(ref, mesh.num_vertices), rtol=1e-12)
    knn = stats.graph_distances(mesh, src, "knn", k=6)
    assert np.all(np.isfinite(knn)) and np.all(knn[np.arange(5), src] == 0)
    np.testing.assert_array_equal(stats.sample_sources(mesh, 5, seed=3), src)   # seeded


HEAT_TOLERANCE = 0.015   # mean relative error against great circles on icosphere(4); measured 0.9%


def test_heat_method_on_a_sphere_within_stated_tolerance():
    s = trimesh.creation.icosphere(4)
    mesh = jaxmesh.Mesh.from_arrays(s.vertices, s.faces)
    src = stats.sample_sources(mesh, 6, seed=0)
    v = np.asarray(s.vertices)
    exact = np.arccos(np.clip(v[src] @ v.T, -1, 1))
    heat = stats.heat_geodesics(mesh, src)
    far = exact > 0.1
    rel = np.abs(heat - exact)[far] / exact[far]
    assert rel.mean() < HEAT_TOLERANCE
    edges = stats.graph_distances(mesh, src)
    assert ((edges - exact)[far] / exact[far]).mean() > 3 * rel.mean()     # the graph is much worse
    np.testing.assert_allclose(heat[np.arange(6), src], 0, atol=1e-12)
    np.testing.assert_allclose(stats.heat_geodesics(mesh, src, block=4), heat, rtol=1e-10, atol=1e-14)  # padded


def test_heat_geodesics_are_inf_exactly_where_the_edge_graph_cannot_reach():
    """Two spheres apart, and an isolated vertex: the heat distances are inf exactly where
    Dijkstra on the edge graph finds no path (the connected components), finite elsewhere."""
    a, b = trimesh.creation.icosphere(2), trimesh.creation.icosphere(1)
    v = np.r_[a.vertices, b.vertices + [5.0, 0, 0], [[9.0, 9.0, 9.0]]]
    mesh = jaxmesh.Mesh.from_arrays(v, np.r_[a.faces, b.faces + len(a.vertices)], warn=False)
    src = np.array([0, len(a.vertices) + 3, 7])
    heat = stats.heat_geodesics(mesh, src)
    reach = np.isfinite(stats.graph_distances(mesh, src))
    np.testing.assert_array_equal(np.isfinite(heat), reach)
    assert not reach[0, len(a.vertices):].any() and reach[1, len(a.vertices):-1].all()


def test_mesh_statistics_of_a_genus_two_mesh():
    mesh = jaxmesh.load(shared_mesh_path("eight.ply"))
    s = stats.mesh_statistics(mesh, sources=20, seed=1)["summary"]
    assert s["average_degree"] == pytest.approx(2 * 2304 / 766) and s["sources"] == 20   # genus 2: χ = -2
    assert s["geodesic_edges_mean"] > s["geodesic_heat_mean"] > 0


def test_heat_method_stays_nonnegative_on_a_mesh_with_obtuse_triangles():
    mesh = jaxmesh.load(shared_mesh_path("cow.ply"))      # coarse, obtuse, one non-manifold vertex
    src = stats.sample_sources(mesh, 30, seed=0)
    heat = stats.heat_geodesics(mesh, src)
    diag = float(jaxmesh.bounding_box_diagonal(mesh))
    assert heat.min() > -0.002 * diag
    edges = stats.graph_distances(mesh, src)
    ratio = (heat / np.where(edges > 0, edges, 1))[edges > 0]
    # shorter than edge paths on the whole (measured: median 0.94, 99th percentile 1.04)
    assert np.median(ratio) < 0.97 and np.percentile(ratio, 99) < 1.1


def test_distance_blocks_concatenate_to_the_whole_arrays():
    mesh = jaxmesh.load(shared_mesh_path("eight.ply"))
    src = stats.sample_sources(mesh, 11, seed=2)
    for method in ("edges", "knn"):
        parts = list(stats.distance_blocks(mesh, src, method, k=6, block=4))
        assert [len(s) for s, _ in parts] == [4, 4, 3]
        np.testing.assert_array_equal(np.concatenate([s for s, _ in parts]), src)
        np.testing.assert_array_equal(np.concatenate([d for _, d in parts]),
                                      stats.geodesic_distances(mesh, src, method, k=6))
    with pytest.raises(ValueError, match="lie in"):
        stats.distance_blocks(mesh, [0, mesh.num_vertices], "edges")
    with pytest.raises(ValueError, match="method"):
        stats.distance_blocks(mesh, src, "euclid")
    with pytest.raises(ValueError, match="block"):
        stats.distance_blocks(mesh, src, "edges", block=0)


def test_distance_histogram_counts_what_numpy_counts_on_its_final_edges():
    """Streamed one source at a time (so the range doubles several times and bins merge),
    the counts equal np.histogram of all finite non-self distances on the final edges, and
    the moments equal numpy's; the coarse density integrates to 1."""
    mesh = jaxmesh.load(shared_mesh_path("eight.ply"))
    src = stats.sample_sources(mesh, 9, seed=4)
    d = stats.graph_distances(mesh, src)
    keep = np.isfinite(d)
    keep[np.arange(len(src)), src] = False
    x = d[keep]
    h = stats.distance_histogram(mesh, src, "edges", block=1, bins=256)
    top = h.edges[-1]
    assert np.log2(top) == np.round(np.log2(top)) and x.max() < top <= 2 * x.max()
    np.testing.assert_array_equal(h.counts, np.histogram(x, bins=h.edges)[0])
    assert h.count == x.size
    assert h.mean == pytest.approx(x.mean(), rel=1e-12) and h.std == pytest.approx(x.std(), rel=1e-10)
    edges, density = h.density(20)
    assert len(density) <= 20 and np.sum(density * np.diff(edges)) == pytest.approx(1.0)
    assert edges[-1] > x.max() >= edges[-2]          # the occupied range, no empty tail of bins
    with pytest.raises(ValueError, match="power of two"):
        stats.distance_histogram(mesh, src, "edges", bins=100)


def test_mesh_statistics_geodesics_are_histograms_of_the_distances():
    mesh = jaxmesh.load(shared_mesh_path("eight.ply"))
    st = stats.mesh_statistics(mesh, sources=12, seed=0, geodesics=("edges",))
    h = st["geodesics"]["edges"]
    d = stats.graph_distances(mesh, st["sources"])
    keep = np.isfinite(d)
    keep[np.arange(12), st["sources"]] = False
    assert isinstance(h, stats.DistanceHistogram) and h.count == keep.sum()
    assert st["summary"]["geodesic_edges_mean"] == pytest.approx(d[keep].mean(), rel=1e-12)
    with pytest.warns(jaxmesh.MeshWarning, match="every vertex is a source"):      # said, not clamped silently
        every = stats.mesh_statistics(mesh, sources=10**9, geodesics=("edges",), spectrum_k=2)
    assert every["summary"]["sources"] == mesh.num_vertices
    ico = trimesh.creation.icosphere(0)                  # 12 vertices: the defaults lower quietly
    small = stats.mesh_statistics(jaxmesh.Mesh.from_arrays(ico.vertices, ico.faces))   # warnings are errors here
    assert small["summary"]["sources"] == 12 < stats.SOURCES


def test_mesh_statistics_on_threads_equal_a_plain_loop(monkeypatch):
    """The geodesics and spectra run beside each other on the cores: each is the same
    computation as one after the other, so every number is identical."""
    mesh = jaxmesh.load(shared_mesh_path("eight.ply"))
    spread = stats.mesh_statistics(mesh, sources=12, seed=3)
    monkeypatch.setenv("JAXMESH_THREADS", "1")
    plain = stats.mesh_statistics(mesh, sources=12, seed=3)
    assert spread["summary"] == plain["summary"]
    for kind in ("combinatorial", "normalized"):
        np.testing.assert_array_equal(spread["spectrum"][kind][1], plain["spectrum"][kind][1])
    for g in ("edges", "knn", "heat"):
        np.testing.assert_array_equal(spread["geodesics"][g].counts, plain["geodesics"][g].counts)


def test_source_blocks_are_sized_to_the_faces():
    assert [stats.source_block(f) for f in (0, 20_000, 65_536, 65_537, 131_073, 10**7)] == [16, 16, 16, 8, 4, 4]


@pytest.mark.slow
def test_mesh_statistics_compiles_few_programs_in_a_fresh_process():
    """The statistics' host code calls the geometry through one compiled program each, not
    op by op (every eager op is a program compiled anew in each process: about 50 of them,
    a second of ``jaxmesh stats``' start, before)."""
    import subprocess
    import sys

    code = """
import logging, jax
jax.config.update("jax_enable_x64", True)
jax.config.update("jax_log_compiles", True)
names = []
class Count(logging.Handler):
    def emit(self, record):
        if record.getMessage().startswith("Finished XLA compilation of "):
            names.append(record.getMessage().split()[4])
logger = logging.getLogger("jax"); logger.addHandler(Count()); logger.setLevel(logging.DEBUG); logger.propagate = False
import trimesh, jaxmesh
from jaxmesh import stats
s = trimesh.creation.icosphere(3)
stats.mesh_statistics(jaxmesh.Mesh.from_arrays(s.vertices, s.faces), sources=12, knn=4)
print(len(names), sorted(set(names)))
"""
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr[-2000:]
    count = int(out.stdout.split()[0])
    assert 3 <= count <= 20, out.stdout
