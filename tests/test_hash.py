"""Mesh hashing (thesis ch.4): MST, Laplace–Beltrami, METIS, both hashes, the CLI."""

import json
import subprocess
import sys

import numpy as np
import pytest

import jaxmesh
from jaxmesh.hashing import attacks
from jaxmesh.hashing import (THRESHOLDS, cosine_similarity, euclidean_mst, euclidean_mst_length,
                          graph_mst_length, laplace_beltrami_eigenvalues,
                          mesh_hash, metis_partition, robust_hash, similarity, submesh,
                          tsallis_entropy, verdict)
from jaxmesh.hashing.robust import affine_normalize
from conftest import grid_arrays

# ---------------------------------------------------------------- MST


def prim_length(p: np.ndarray) -> float:
    """Brute-force Euclidean MST length: Prim's algorithm on the complete graph."""
    n = len(p)
    d = np.linalg.norm(p[:, None] - p[None], axis=-1)
    inside = np.zeros(n, bool)
    inside[0] = True
    best = d[0].copy()
    total = 0.0
    for _ in range(n - 1):
        j = int(np.argmin(np.where(inside, np.inf, best)))
        total += best[j]
        inside[j] = True
        best = np.minimum(best, d[j])
    return total


@pytest.mark.parametrize("case", ["random", "coplanar", "duplicates", "tiny"])
def test_euclidean_mst_matches_brute_force(case):
    rng = np.random.default_rng(3)
    p = rng.standard_normal((60, 3))
    if case == "coplanar":
        p[:, 2] = 0.5  # Qhull cannot triangulate: complete-graph fallback
    if case == "duplicates":
        p = np.concatenate([p, p[:7]])
    if case == "tiny":
        p = p[:3]
    edges, lengths = euclidean_mst(p)
    assert len(edges) == len(p) - 1
    assert euclidean_mst_length(p) == pytest.approx(prim_length(p), rel=1e-12)
    np.testing.assert_allclose(lengths, np.linalg.norm(p[edges[:, 0]] - p[edges[:, 1]], axis=1))


def test_mst_errors_and_graph_mst():
    with pytest.raises(ValueError, match="shape"):
        euclidean_mst(np.zeros((4, 2)))
    with pytest.raises(ValueError, match="NaN"):
        euclidean_mst(np.array([[0.0, 0, 0], [np.nan, 0, 0]]))
    # square with a diagonal: the MST takes three unit sides
    p = np.array([[0.0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]])
    assert graph_mst_length(p, [[0, 1], [1, 2], [2, 3], [3, 0], [0, 2]]) == pytest.approx(3.0)


def test_tsallis_entropy_formula():
    assert tsallis_entropy(12.0, 16) == pytest.approx(2 * (12 / 4 - 1))
    with pytest.raises(ValueError, match="empty point set"):
        tsallis_entropy(1.0, 0)


# ---------------------------------------------------------------- Laplace–Beltrami


def lb_loop(v, f):
    """L = D - W, w_ij = 3 (cot α + cot β) / η_i, by a plain loop over faces."""
    n = len(v)
    w = np.zeros((n, n))
    eta = np.zeros(n)
    for tri in f:
        area = 0.5 * np.linalg.norm(np.cross(v[tri[1]] - v[tri[0]], v[tri[2]] - v[tri[0]]))
        for k in range(3):
            a, b, c = tri[k], tri[(k + 1) % 3], tri[(k + 2) % 3]
            eta[a] += area
            u, s = v[b] - v[a], v[c] - v[a]
            cot = u @ s / np.linalg.norm(np.cross(u, s))
            w[b, c] += cot
            w[c, b] += cot
    w = 3 * w / eta[:, None]
    return np.diag(w.sum(1)) - w


def test_laplace_beltrami_against_loop_and_jax_operator(bumpy_grid):
    v, f = np.asarray(bumpy_grid.vertices), np.asarray(bumpy_grid.faces)
    ref = lb_loop(v, f)
    np.testing.assert_allclose(jaxmesh.sparse.laplace_beltrami_matrix(bumpy_grid).toarray(), ref,
                               rtol=1e-10, atol=1e-10)


@pytest.mark.parametrize("dense_max", [10_000, 50])
def test_lb_eigenvalues_match_nonsymmetric_dense_eigvals(dense_max):
    v, f = grid_arrays(14, 12, jitter=0.2, seed=4)
    v[:, 2] = 0.3 * np.sin(v[:, 0]) * np.cos(v[:, 1])
    ref = np.sort(np.linalg.eigvals(lb_loop(v, f)).real)[::-1]
    got = laplace_beltrami_eigenvalues(v, f, 12, dense_max=dense_max)  # 50: the ARPACK path
    np.testing.assert_allclose(got, ref[:12], rtol=1e-8)


# ---------------------------------------------------------------- partition


def test_metis_partition_deterministic_balanced(spot):
    labels = metis_partition(spot, 8)
    np.testing.assert_array_equal(labels, metis_partition(spot, 8))
    sizes = np.bincount(labels)
    assert len(sizes) == 8 and sizes.max() <= 1.05 * spot.num_vertices / 8
    with pytest.raises(ValueError, match="cannot split"):
        metis_partition(jaxmesh.Mesh.from_arrays(*grid_arrays(1, 1)), 8)
    v, f, idx = submesh(np.asarray(spot.vertices), np.asarray(spot.faces), labels == 3)
    assert np.all(labels[idx] == 3) and f.max() == len(v) - 1


# ---------------------------------------------------------------- the thesis's hash


@pytest.fixture(scope="module")
def spot_hash(spot):
    return mesh_hash(spot)


def test_thesis_hash_structure(spot, spot_hash):
    h = spot_hash
    assert h.kind == "thesis" and len(h) == 8
    # canonical order: decreasing mu; labels follow it
    assert np.all(np.diff(h.log_vector) <= 0)
    np.testing.assert_array_equal(np.bincount(h.labels), h.parts["sizes"])
    # each part's numbers recomputed from scratch in canonical order
    v, f = np.asarray(spot.vertices), np.asarray(spot.faces)
    for k in (0, 7):
        inside = h.labels == k
        length = euclidean_mst_length(v[inside])
        xi = 2 * (length / np.sqrt(inside.sum()) - 1)
        lam = laplace_beltrami_eigenvalues(*submesh(v, f, inside)[:2], 16)
        assert h.parts["entropies"][k] == pytest.approx(xi, rel=1e-12)
        assert h.log_vector[k] == pytest.approx(np.log(np.sum(lam ** xi)), rel=1e-10)


def test_thesis_hash_exact_invariances(spot, spot_hash):
    for moved in (attacks.rotate(spot, "x", 45), attacks.rotate(spot, "y", 33), attacks.translate(spot)):
        assert abs(similarity(spot_hash, mesh_hash(moved)) - 1) < 1e-9
    assert similarity(spot_hash, spot_hash) == pytest.approx(1.0, abs=1e-15)


def test_thesis_hash_deterministic_across_processes(spot_hash):
    code = ("import jax; jax.config.update('jax_enable_x64', True); import json, jaxmesh; "
            "from jaxmesh.hashing import mesh_hash; "
            "print(json.dumps(mesh_hash(jaxmesh.data.load_sample('spot', dtype='float64')).to_dict()))")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    assert json.loads(r.stdout)["log_vector"] == [float(x) for x in spot_hash.log_vector]


def test_thesis_hash_options_and_errors(spot):
    h = mesh_hash(spot, parts=4, r=0.01, mst="edges")
    assert len(h) == 4 and h.params["mst"] == "edges"
    with pytest.raises(ValueError, match="mst"):
        mesh_hash(spot, mst="kruskal")
    with pytest.raises(ValueError, match="fraction"):
        mesh_hash(spot, r=1.5)
    with pytest.raises(ValueError, match="parameters"):
        similarity(h, mesh_hash(spot, parts=4))


# ---------------------------------------------------------------- similarity


def test_similarity_eq4_by_hand():
    assert cosine_similarity([1, 0], [1, 1]) == pytest.approx(1 / np.sqrt(2))
    assert cosine_similarity([1, 2, 3], [-2, -4, -6]) == pytest.approx(1.0)  # |h1 . h2|
    assert cosine_similarity([0, 0], [1, 2]) == 0.0
    with pytest.raises(ValueError, match="length"):
        cosine_similarity([1, 2], [1, 2, 3])
    assert verdict(0.995, "thesis") and not verdict(0.4, "robust")


def test_overflowing_mu_is_compared_in_log_space():
    from jaxmesh.hashing import MeshHash

    with np.errstate(over="ignore"):
        big = MeshHash("thesis", np.exp([800.0, 799.0]), np.array([800.0, 799.0]))
    small = MeshHash("thesis", np.exp([1.0, 0.0]), np.array([1.0, 0.0]))
    assert similarity(big, small) == pytest.approx(1.0)  # the same direction (e, 1)
    assert big.to_dict()["vector"] == [None, None]
    json.dumps(big.to_dict(), allow_nan=False)


# ---------------------------------------------------------------- the robust hash


def test_affine_normalization_whitens_and_cancels_affine_maps(spot):
    v, f = np.asarray(spot.vertices), np.asarray(spot.faces)
    x, area = affine_normalize(v, f)
    # the whitened surface has centroid 0 and identity covariance: check by dense sampling
    from jaxmesh.metrics import sample_surface

    pts = sample_surface(x, f, 200_000, np.random.default_rng(0), systematic=True, area=area)
    np.testing.assert_allclose(pts.mean(0), 0, atol=0.01)
    np.testing.assert_allclose(np.cov(pts.T), np.eye(3), atol=0.02)
    # a similarity map changes the whitened shape by a rotation only: same radii
    r = attacks.rotation_matrix("z", 30) * 2.5
    x2, _ = affine_normalize(v @ r.T + 4.0, f)
    np.testing.assert_allclose(np.linalg.norm(x2, axis=1), np.linalg.norm(x, axis=1), rtol=1e-9)


@pytest.fixture(scope="module")
def spot_robust(spot):
    return robust_hash(spot)


def test_robust_hash_invariances_and_attacks(spot, spot_robust):
    for moved in (attacks.rotate(spot, "y", 45), attacks.translate(spot),
                  spot.with_vertices(spot.vertices * 3.0)):
        assert abs(similarity(spot_robust, robust_hash(moved)) - 1) < 1e-9
    for name in ("scale x 1.5", "smooth 10 it", "simplify 30%", "noise 0.25ℓ̄", "reorder"):
        rho = similarity(spot_robust, robust_hash(attacks.ALL_ATTACKS[name](spot, 0)))
        assert rho >= THRESHOLDS["robust"], (name, rho)


def test_robust_hash_on_shapes_it_was_not_fitted_on():
    """The threshold (ρ = ½) was fitted on the 12 shared development meshes; these
    generated shapes are not among them.  A torus and a bent capsule (not an affine
    image of a capsule) are different models (ρ 0.10 measured); each attacked by noise,
    smoothing, rotation and decimation stays the same model (ρ ≥ 0.75 measured).
    Not every unseen shape is this kind: a coarse bent cone smoothed 5 times reads
    ρ = 0.17 (the apex and the base rim shrink), a limit stated in the module doc."""
    import trimesh

    torus = jaxmesh.Mesh.from_arrays(*_arrays(trimesh.creation.torus(1.0, 0.35, 48, 24)))
    capsule = trimesh.creation.capsule(height=1.5, radius=0.4, count=[32, 32])
    v = capsule.vertices.copy()
    v[:, 0] += 0.3 * v[:, 2] ** 2                           # bent: not an affine image of a capsule
    bent = jaxmesh.Mesh.from_arrays(v, capsule.faces)
    h_torus, h_bent = robust_hash(torus), robust_hash(bent)
    assert similarity(h_torus, h_bent) < THRESHOLDS["robust"]
    for m, h in ((torus, h_torus), (bent, h_bent)):
        for attacked in (attacks.add_gaussian_noise(m, 0.1), attacks.smooth(m, 5),
                         attacks.rotate(m, "z", 40), attacks.simplify(m, 0.5)):
            assert similarity(h, robust_hash(attacked)) >= THRESHOLDS["robust"]


def _arrays(t):
    return np.asarray(t.vertices), np.asarray(t.faces)


def test_robust_hash_separates_the_two_samples_a_training_set_check(spot_robust):
    """Spot and the bunny are two of the meshes the threshold was fitted on: this checks
    the fit, not how it generalises (see the test above)."""
    bunny = jaxmesh.data.load_sample("bunny", dtype=np.float64)
    rho = similarity(spot_robust, robust_hash(bunny))
    assert rho < THRESHOLDS["robust"]
    with pytest.raises(ValueError, match="cannot compare"):
        similarity(spot_robust, mesh_hash(bunny))


def test_robust_hash_errors(spot):
    with pytest.raises(ValueError, match="samples"):
        robust_hash(spot, samples=10)
    flat = jaxmesh.Mesh.from_arrays(np.zeros((3, 3)), np.array([[0, 1, 2]]), warn=False)
    with pytest.raises(ValueError, match="zero area"):
        robust_hash(flat)


# ---------------------------------------------------------------- attacks


def test_geometric_attacks(spot):
    v = np.asarray(spot.vertices)
    s = np.asarray(attacks.scale_axis(spot, "y", 1.5).vertices)
    np.testing.assert_allclose(s, v * [1, 1.5, 1])
    r = np.asarray(attacks.rotate(spot, "z", 90).vertices)
    np.testing.assert_allclose(r, np.stack([-v[:, 1], v[:, 0], v[:, 2]], 1), atol=1e-12)
    ry = attacks.rotation_matrix("y", 90)
    np.testing.assert_allclose(ry @ [0, 0, 1.0], [1, 0, 0], atol=1e-15)  # z -> x about y
    t = np.asarray(attacks.translate(spot, offset=[1, 2, 3]).vertices)
    np.testing.assert_allclose(t - v, np.broadcast_to([1, 2, 3], v.shape))
    n1, n2 = attacks.add_gaussian_noise(spot, 0.25, seed=5), attacks.add_gaussian_noise(spot, 0.25, seed=5)
    d = np.asarray(n1.vertices) - v
    np.testing.assert_array_equal(n1.vertices, n2.vertices)
    assert np.std(d) == pytest.approx(0.25 * float(jaxmesh.mean_edge_length(spot)), rel=0.05)
    sm = attacks.smooth(spot)
    assert sm.num_faces == spot.num_faces and not np.allclose(sm.vertices, v)
    with pytest.raises(ValueError, match="axis"):
        attacks.scale_axis(spot, "w")


def test_topological_attacks(spot):
    simp = attacks.simplify(spot, keep=0.3)
    assert abs(simp.num_faces / spot.num_faces - 0.3) < 0.01
    dist = jaxmesh.metrics.surface_distance(spot, simp, samples=2000)
    assert dist["rms"] < 2e-3 * dist["diagonal"]  # a decimation, not a different shape
    re = attacks.reorder_vertices(spot, seed=2)
    key = lambda m: sorted(map(tuple, np.round(np.sort(np.asarray(m.vertices)[np.asarray(m.faces)].reshape(-1, 9), 1), 12)))  # noqa: E731
    assert key(re) == key(spot)
    assert not np.array_equal(re.vertices, spot.vertices)
    cr = attacks.crop(spot, 0.02, seed=1)
    removed = spot.num_vertices - cr.num_vertices
    assert 0.02 * spot.num_vertices <= removed <= 0.05 * spot.num_vertices
    assert cr.num_faces < spot.num_faces
    np.testing.assert_array_equal(attacks.crop(spot, 0.02, seed=1).vertices, cr.vertices)
    for bad, why in ((lambda: attacks.simplify(spot, 0), r"keep must be in \(0, 1\]"),
                     (lambda: attacks.crop(spot, 1.0), r"fraction must be in \[0, 1\)")):
        with pytest.raises(ValueError, match=why):
            bad()


def test_attack_registry():
    """Every registered attack maps a mesh to a valid, finite mesh, is deterministic for
    a seed, and changes the mesh (an attack that returned its input would make the
    robustness table vacuous)."""
    import trimesh

    assert len(attacks.TABLE_4_1) == 9 and set(attacks.TABLE_4_1) <= set(attacks.ALL_ATTACKS)
    s = trimesh.creation.icosphere(3)
    m = jaxmesh.Mesh.from_arrays(s.vertices * [1.0, 0.8, 0.6], s.faces)
    for name, fn in attacks.ALL_ATTACKS.items():
        a, b = fn(m), fn(m)
        assert isinstance(a, jaxmesh.Mesh) and np.isfinite(np.asarray(a.vertices)).all(), name
        np.testing.assert_array_equal(np.asarray(a.vertices), np.asarray(b.vertices), err_msg=name)
        same = a.num_vertices == m.num_vertices and np.array_equal(np.asarray(a.vertices), np.asarray(m.vertices)) \
            and np.array_equal(np.asarray(a.faces), np.asarray(m.faces))
        assert not same, f"{name} left the mesh unchanged"


def test_host_laplace_beltrami_uses_the_one_degenerate_face_rule():
    """A sliver of height 1e-17: the hash spectra's host matrix S = D^½ L_c D^½ (D = diag(3/η))
    is similar to the JAX-defined L = D L_c, S = D^-½ L D^½ (before: entries up to 6e34 from
    its own zero-area rule)."""
    from jaxmesh.hashing.spectrum import symmetric_laplace_beltrami
    from jaxmesh.sparse import laplace_beltrami_matrix

    v = np.array([[0, 0, 0], [1, 0, 0], [0.5, 1e-17, 0], [0.5, 0.5, 1]], float)
    f = np.array([[0, 1, 2], [0, 1, 3], [1, 2, 3], [2, 0, 3]])
    host = symmetric_laplace_beltrami(v, f).toarray()
    lap = laplace_beltrami_matrix(jaxmesh.Mesh.from_arrays(v, f, warn=False)).toarray()
    area = 0.5 * np.linalg.norm(np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]]), axis=1)
    d = np.sqrt(3 / np.bincount(f.ravel(), np.repeat(area, 3)))            # (3/η)^½, η_i the incident faces' area
    assert np.abs(host).max() < 100
    np.testing.assert_allclose(host, lap * (1 / d)[:, None] * d[None, :], rtol=1e-12, atol=1e-12)


def test_systematic_surface_sampling_follows_the_areas():
    """The robust hash's sampler (metrics.sample_surface, systematic): each face gets
    its expected count count·A_f/ΣA to within one point, and every point is on its face."""
    from jaxmesh.metrics import sample_surface

    v = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [3, 0, 0], [3, 3, 0]])
    f = np.array([[0, 1, 2], [1, 3, 4]])                  # areas 0.5 and 3
    pts = sample_surface(v, f, 7000, np.random.default_rng(1), systematic=True)
    in_first = (pts[:, 0] + pts[:, 1] <= 1 + 1e-12) & (pts[:, 0] <= 1 + 1e-12)
    assert abs(in_first.sum() - 1000) <= 1
    assert np.all(pts[:, 2] == 0)
