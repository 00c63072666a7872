"""The feature-preserving denoisers (bilateral and guided normal filtering, L0)
and the shared vertex update against plain numpy loops written from the papers;
the face graph against brute force; the blind chooser's argument checks."""

import inspect
import itertools
import json

import jax
import jax.numpy as jnp
import numpy as np
import pytest
import scipy.sparse as sp
import scipy.sparse.linalg as spla
import trimesh
from jax.test_util import check_grads

import jaxmesh
from jaxmesh.denoise import (METHODS, edge_operator, face_graph, guided_normal_filtering, l0_denoising,
                             patch_inconsistency, vertex_update)
from jaxmesh.denoise.bilateral_normal import bilateral_normal_filtering
from jaxmesh.tune import Candidate, choose_denoiser, edge_tilt


@pytest.fixture(scope="module")
def sphere():
    s = trimesh.creation.icosphere(1)
    rng = np.random.default_rng(7)
    return jaxmesh.Mesh.from_arrays(s.vertices + 0.04 * rng.standard_normal(s.vertices.shape), s.faces)


@pytest.fixture(scope="module")
def box():
    """A subdivided box with small noise: sharp edges, stable patch choices."""
    b = trimesh.creation.box().subdivide().subdivide()
    rng = np.random.default_rng(3)
    return jaxmesh.Mesh.from_arrays(b.vertices + 0.01 * rng.standard_normal(b.vertices.shape), b.faces)


# ------------------------------------------------------------------ numpy references


def np_geometry(v, f):
    c = v[f].mean(axis=1)
    cross = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
    area = 0.5 * np.linalg.norm(cross, axis=1)
    return c, area, cross / np.linalg.norm(cross, axis=1, keepdims=True)


def np_rings(f):
    return [sorted(g for g in range(len(f)) if set(f[g]) & set(f[h])) for h in range(len(f))]


def np_edge_faces(f):
    faces_of = {}
    for i, tri in enumerate(f):
        for k in range(3):
            faces_of.setdefault(frozenset((tri[(k + 1) % 3], tri[(k + 2) % 3])), []).append((i, tri[k]))
    return faces_of


def np_spacing(v, f):
    c = v[f].mean(axis=1)
    d = [np.linalg.norm(c[a[0]] - c[b[0]]) for a, b in (x for x in np_edge_faces(f).values() if len(x) == 2)]
    return np.mean(d)


def np_vertex_update(v, f, n, iterations, tangential=0.0):
    """Sun et al. 2007's update, then (tangential > 0) the umbrella step projected
    onto the plane of the normalised sum of the target normals around each vertex."""
    around = [[t for t in range(len(f)) if i in f[t]] for i in range(len(v))]
    nbrs = [sorted({int(j) for t in around[i] for j in f[t]} - {i}) for i in range(len(v))]
    m = [sum(n[t] for t in a) / np.linalg.norm(sum(n[t] for t in a)) for a in around]
    x = v.copy()
    for _ in range(iterations):
        c = x[f].mean(axis=1)
        new = x.copy()
        for i in range(len(x)):
            new[i] = x[i] + sum(n[t] * (n[t] @ (c[t] - x[i])) for t in around[i]) / len(around[i])
        x = new
        if tangential:
            k = np.array([x[nbrs[i]].mean(axis=0) - x[i] for i in range(len(x))])
            x = x + tangential * np.array([k[i] - (k[i] @ m[i]) * m[i] for i in range(len(x))])
    return x


def np_joint_bilateral(v, f, n, g, sigma_s, sigma_r, rings):
    c, area, _ = np_geometry(v, f)
    ss = sigma_s * np_spacing(v, f)
    out = np.zeros_like(n)
    for i, ring in enumerate(rings):
        acc = sum(area[j] * np.exp(-np.sum((c[i] - c[j]) ** 2) / (2 * ss**2))
                  * np.exp(-np.sum((g[i] - g[j]) ** 2) / (2 * sigma_r**2)) * n[j] for j in ring)
        out[i] = acc / np.linalg.norm(acc)
    return out


def np_inconsistency(f, n, rings):
    pairs = {k: [a for a, _ in x] for k, x in np_edge_faces(f).items() if len(x) == 2}
    h = np.zeros(len(f))
    for j, ring in enumerate(rings):
        spread = max(np.linalg.norm(n[a] - n[b]) for a, b in itertools.product(ring, ring))
        phis = [np.linalg.norm(n[a] - n[b]) for a, b in pairs.values() if a in ring and b in ring]
        h[j] = spread * max(phis) / (1e-9 + sum(phis))
    return h


def np_guidance(v, f, n, rings):
    _, area, _ = np_geometry(v, f)
    h = np_inconsistency(f, n, rings)
    g = np.zeros_like(n)
    for i, ring in enumerate(rings):
        best = min(ring, key=lambda j: h[j])
        acc = sum(area[k] * n[k] for k in rings[best])
        g[i] = acc / np.linalg.norm(acc)
    return g


# ------------------------------------------------------------------ tests


def test_face_graph_matches_brute_force(sphere):
    f = np.asarray(sphere.faces)
    g = face_graph(sphere)
    rings = np_rings(f)
    idx, mask = np.asarray(g.ring), np.asarray(g.ring_mask)
    assert [sorted(idx[i][mask[i]].tolist()) for i in range(len(f))] == rings
    ef = np_edge_faces(f)
    edges = np.asarray(sphere.edges)
    for e, (a, b) in enumerate(edges):
        both = ef[frozenset((a, b))]
        assert bool(g.edge_mask[e]) == (len(both) == 2)
        assert sorted(zip(np.asarray(g.edge_faces[e]).tolist(), np.asarray(g.edge_apex[e]).tolist())) == sorted(
            (int(t), int(v)) for t, v in both)
    pe, pm = np.asarray(g.patch_edges), np.asarray(g.patch_edge_mask)
    for j, ring in enumerate(rings):
        want = sorted(e for e, (a, b) in enumerate(edges)
                      if all(t in ring for t, _ in ef[frozenset((a, b))]) and len(ef[frozenset((a, b))]) == 2)
        assert sorted(pe[j][pm[j]].tolist()) == want


def _tier_cost(counts, widths, per_tier):
    """Pairs computed when faces of ring size c go to the narrowest width >= c, plus a cost per tier."""
    w = np.asarray(widths)[np.searchsorted(widths, counts)]
    return per_tier * len(widths) + float(np.sum(w * (w + 1) / 2))


def test_ring_tiers_are_the_cheapest_split_and_cover_every_face():
    """The widths are the least-cost ones over every increasing tuple of widths 1..K (not only
    the sizes present), and the tiers of a UV sphere (poles of valence 24 among rings of ~13)
    partition its faces, each ring cut to a width that keeps it whole."""
    from jaxmesh.denoise import RING_TIERS, RingTier, ring_tiers
    from jaxmesh.denoise.tiers import _TIER_COST

    rng = np.random.default_rng(0)
    for counts in ([13] * 900 + [29] * 3, rng.integers(9, 20, 500).tolist() + [41] * 20, [7] * 10):
        top = max(counts)
        counts = np.asarray(counts)
        options = [(*inner, top) for t in range(RING_TIERS) for inner in itertools.combinations(range(1, top), t)]
        best = min(_tier_cost(counts, w, _TIER_COST) for w in options)
        got = ring_tiers(counts)
        assert got == sorted(got) and got[-1] == top and len(got) <= RING_TIERS
        assert _tier_cost(counts, got, _TIER_COST) == best
    uv = trimesh.creation.uv_sphere(count=[24, 24])
    mesh = jaxmesh.Mesh.from_arrays(uv.vertices, uv.faces)
    g = face_graph(mesh)
    assert len(g.tiers) > 1
    faces = np.concatenate([np.asarray(t.faces) for t in g.tiers])
    assert sorted(faces.tolist()) == list(range(mesh.num_faces))
    np.testing.assert_array_equal(faces[np.asarray(g.tier_order)], np.arange(mesh.num_faces))
    ring, mask = np.asarray(g.ring), np.asarray(g.ring_mask)
    for t in g.tiers:
        f, k = np.asarray(t.faces), t.ring.shape[1]
        assert not mask[f, k:].any()
        np.testing.assert_array_equal(np.asarray(t.ring), ring[f, :k])
        np.testing.assert_array_equal(np.asarray(t.ring_mask), mask[f, :k])
    n = np.asarray(jaxmesh.geometry.face_normals(mesh)) + 0.1 * rng.standard_normal((mesh.num_faces, 3))
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    got = np.asarray(jax.jit(patch_inconsistency)(g, jnp.asarray(n)))
    one = g._replace(tiers=(RingTier(jnp.arange(mesh.num_faces, dtype=jnp.int32), g.ring, g.ring_mask),),
                     tier_order=jnp.arange(mesh.num_faces, dtype=jnp.int32))
    np.testing.assert_array_equal(got, jax.jit(patch_inconsistency)(one, jnp.asarray(n)))   # rings at full width
    f = np.asarray(mesh.faces)
    widest = np.argsort(-mask.sum(axis=1))[:60]          # the pole faces of the widest tier, against numpy
    pairs = {k: [a for a, _ in x] for k, x in np_edge_faces(f).items() if len(x) == 2}
    for j in widest:
        ring = [h for h in range(len(f)) if set(f[h]) & set(f[j])]
        spread = max(np.linalg.norm(n[a] - n[b]) for a, b in itertools.product(ring, ring))
        phis = [np.linalg.norm(n[a] - n[b]) for a, b in pairs.values() if a in ring and b in ring]
        assert got[j] == pytest.approx(spread * max(phis) / (1e-9 + sum(phis)), rel=1e-10, abs=1e-12)


def test_a_large_tier_in_blocks_gives_what_one_pass_gives(monkeypatch):
    """The largest normal difference of a tier past ``_ONE_PASS_ROWS`` rows goes in blocks
    (the last one padded): thresholds lowered here so the UV sphere's tiers take both paths,
    alone and batched; the same values (to the rounding of the products' fused multiply-adds), and the
    spreads' gradient."""
    from jaxmesh.denoise import guided

    uv = trimesh.creation.uv_sphere(count=[12, 12])
    mesh = jaxmesh.Mesh.from_arrays(uv.vertices, uv.faces)
    g = face_graph(mesh)
    rng = np.random.default_rng(1)
    n = np.asarray(jaxmesh.geometry.face_normals(mesh)) + 0.2 * rng.standard_normal((2, mesh.num_faces, 3))
    n = jnp.asarray(n / np.linalg.norm(n, axis=-1, keepdims=True))

    def fresh():        # traced anew (a new function), so the thresholds are read when it runs
        return jax.jit(lambda graph, x: patch_inconsistency.__wrapped__(graph, x))

    def grad():         # of the largest tier's spreads, eager: compiled under the suite's XLA flags, the two
        # programs' gradients of the max parted at a few faces (their rounding broke ties apart)
        return jax.grad(lambda x: jnp.sum(guided._largest_difference(x, g.tiers[0]) ** 2))

    one_pass = [patch_inconsistency(g, n[0]), patch_inconsistency(g, n)]
    one_pass_grad = grad()(n[0])
    monkeypatch.setattr(guided, "_ONE_PASS_ROWS", 7)
    monkeypatch.setattr(guided, "_BLOCK_ROWS", 5)          # blocks of 5 faces alone, of 2 in a batch of 2
    assert any(t.ring.shape[0] % 5 for t in g.tiers)       # a padded last block
    for got, want in ((fresh()(g, n[0]), one_pass[0]), (fresh()(g, n), one_pass[1])):
        assert got.shape == want.shape
        np.testing.assert_allclose(got, want, rtol=1e-13, atol=1e-15)     # the same products, fused apart
    np.testing.assert_allclose(grad()(n[0]), one_pass_grad, rtol=1e-12, atol=1e-14)


def test_face_graph_needs_the_host(sphere):
    with pytest.raises(ValueError, match="outside jit and pass the result as graph="):
        jax.jit(lambda m: guided_normal_filtering(m).vertices)(sphere)


def test_vertex_update_matches_numpy_loop(sphere):
    v, f = np.asarray(sphere.vertices), np.asarray(sphere.faces)
    n = np.asarray(jaxmesh.geometry.face_normals(sphere.with_vertices(jnp.asarray(v * [1.0, 1.1, 0.9]))))
    got = vertex_update(sphere, sphere.vertices, jnp.asarray(n), 3)
    np.testing.assert_allclose(got, np_vertex_update(v, f, n, 3), atol=1e-12)
    got = vertex_update(sphere, sphere.vertices, jnp.asarray(n), 3, tangential=0.2)
    np.testing.assert_allclose(got, np_vertex_update(v, f, n, 3, 0.2), atol=1e-12)
    # along the face graph's vertex tables (and batched): the same loop
    graph, x = face_graph(sphere), jnp.stack([sphere.vertices, sphere.vertices * 1.1])
    normals = jnp.stack([jnp.asarray(n)] * 2)
    got = jax.jit(lambda x, g: vertex_update(sphere, x, normals, 3, tangential=0.2, graph=g))(x, graph)
    np.testing.assert_allclose(got[0], np_vertex_update(v, f, n, 3, 0.2), atol=1e-12)
    np.testing.assert_allclose(got[1], np_vertex_update(v * 1.1, f, n, 3, 0.2), atol=1e-12)


def test_bilateral_normal_matches_numpy_loop(sphere):
    v, f = np.asarray(sphere.vertices), np.asarray(sphere.faces)
    rings = np_rings(f)
    n = np_geometry(v, f)[2]
    for _ in range(2):
        n = np_joint_bilateral(v, f, n, n, 1.3, 0.4, rings)
    want = np_vertex_update(v, f, n, 3, 0.1)
    got = bilateral_normal_filtering(sphere, 1.3, 0.4, normal_iterations=2, vertex_iterations=3)   # tangential 0.1
    np.testing.assert_allclose(got.vertices, want, atol=1e-12)


def test_guided_normal_matches_numpy_loop(box):
    v, f = np.asarray(box.vertices), np.asarray(box.faces)
    rings = np_rings(f)
    n = np_geometry(v, f)[2]
    np.testing.assert_allclose(patch_inconsistency(face_graph(box), jnp.asarray(n)),
                               np_inconsistency(f, n, rings), rtol=1e-10, atol=1e-12)
    for _ in range(2):
        n = np_joint_bilateral(v, f, n, np_guidance(v, f, n, rings), 1.0, 0.3, rings)
    want = np_vertex_update(v, f, n, 2, 0.25)
    got = guided_normal_filtering(box, 1.0, 0.3, normal_iterations=2, vertex_iterations=2, tangential=0.25)
    np.testing.assert_allclose(got.vertices, want, atol=1e-12)


def test_guided_filter_keeps_the_box_edges():
    b = trimesh.creation.box().subdivide().subdivide().subdivide()
    clean = jaxmesh.Mesh.from_arrays(b.vertices, b.faces)
    noisy = jaxmesh.add_noise(clean, 0.3, 0, along_normals=True)
    err = {m: float(jaxmesh.metrics.mean_normal_angle_error(clean, METHODS[m](noisy)))
           for m in ("taubin", "guided_normal")}
    assert err["guided_normal"] < 0.5 * err["taubin"], err


def test_tangential_relaxation_rescues_isotropic_noise():
    """Under isotropic noise the normal-only update leaves folded triangles; the
    tangential relaxation of the shared update removes them (module docstring)."""
    b = trimesh.creation.box().subdivide().subdivide().subdivide()
    clean = jaxmesh.Mesh.from_arrays(b.vertices, b.faces)
    noisy = jaxmesh.add_noise(clean, 0.3, 0)
    err = [float(jaxmesh.metrics.mean_normal_angle_error(clean, METHODS["guided_normal"](noisy, tangential=t)))
           for t in (0.0, 0.1)]
    assert err[1] < 0.7 * err[0], err


@pytest.mark.slow   # the default run checks every method's gradient jointly (test_denoise_methods)
def test_guided_gradient_where_the_patch_choice_is_stable():
    """The patch choice is an argmin (no gradient); on the box it does not flip under
    the finite-difference steps, so the rest of the chain must match them."""
    b = trimesh.creation.box().subdivide()
    small = jaxmesh.Mesh.from_arrays(b.vertices + 0.01 * np.random.default_rng(3).standard_normal(b.vertices.shape),
                                     b.faces)
    g = face_graph(small)
    w = jax.random.normal(jax.random.PRNGKey(0), small.vertices.shape)

    def loss(x, sr):
        out = guided_normal_filtering(small.with_vertices(x), 1.0, sr, 2, 2, graph=g)   # tangential 0.1
        return jnp.sum(w * out.vertices)

    loss = jax.jit(loss)     # one compile for the finite differences and one for the VJP
    check_grads(lambda x: loss(x, 0.3), (small.vertices,), order=1, modes=("rev",), atol=1e-5, rtol=1e-4)
    check_grads(lambda s: loss(small.vertices, s), (jnp.asarray(0.3),), order=1, modes=("rev",),
                atol=1e-5, rtol=1e-4)


def test_l0_edge_operator_vanishes_on_flat_pairs_and_sums_to_zero(box):
    clean = jaxmesh.Mesh.from_arrays(trimesh.creation.box().subdivide().subdivide().vertices, box.faces)
    g = face_graph(clean)
    idx, coef = edge_operator(clean, g, clean.vertices)
    d = np.linalg.norm(np.sum(np.asarray(coef)[..., None] * np.asarray(clean.vertices)[np.asarray(idx)], 1), axis=1)
    n = np.asarray(jaxmesh.geometry.face_normals(clean))
    ef = np.asarray(g.edge_faces)
    crease = np.abs(np.sum(n[ef[:, 0]] * n[ef[:, 1]], axis=1)) < 0.5
    assert np.all(d[~crease] < 1e-12) and np.all(d[crease] > 0.05)   # 0 exactly where coplanar
    np.testing.assert_allclose(np.asarray(coef).sum(axis=1), 0, atol=1e-12)


def np_l0(v, f, edges, lam_mult, alpha_mult, iterations):
    """He & Schaefer 2013 written out with scipy sparse matrices and a direct solve."""
    ef = np_edge_faces(f)
    rows = [(a, b, ef[frozenset((a, b))]) for a, b in edges if len(ef[frozenset((a, b))]) == 2]
    _, _, n0 = np_geometry(v, f)
    gamma = np.mean([np.arccos(np.clip(n0[x[0][0]] @ n0[x[1][0]], -1, 1)) for _, _, x in rows])
    ell = np.mean([np.linalg.norm(v[a] - v[b]) for a, b in edges])
    lam, alpha = lam_mult * 0.02 * ell**2 * gamma, alpha_mult * 0.1 * gamma
    ratio = 1e6 ** (1 / iterations)
    nv, ne = len(v), len(rows)

    def operator(x, coefs):
        r, c, d = [], [], []
        for e, (a, b, ((f1, p2), (f2, p4))) in enumerate(rows):
            for k, vert in enumerate((a, p2, b, p4)):
                r.append(e), c.append(vert), d.append(coefs(x, a, p2, b, p4, f1, f2)[k])
        return sp.csr_matrix((d, (r, c)), shape=(ne, nv))

    def d_coefs(x, p1, p2, p3, p4, f1, f2):
        area = np_geometry(x, f)[1]
        e = x[p3] - x[p1]
        a = (x[p2] - x[p1]) @ e / (e @ e)
        b = (x[p4] - x[p1]) @ e / (e @ e)
        s123, s134 = area[f1], area[f2]
        w2, w4 = s134 / (s123 + s134), s123 / (s123 + s134)
        return [-(w2 * (1 - a) + w4 * (1 - b)), w2, -(w2 * a + w4 * b), w4]

    rmat = operator(v, lambda *_: [1.0, -1.0, 1.0, -1.0])
    x = v.copy()
    for k in range(iterations):
        beta, alpha_k = 1e-3 * ratio ** (k + 1), alpha * 0.5**k
        dmat = operator(x, d_coefs)
        dx = dmat @ x
        delta = np.where((np.sum(dx * dx, 1) * beta >= lam)[:, None], dx, 0)
        system = sp.identity(nv) + alpha_k * rmat.T @ rmat + beta * dmat.T @ dmat
        x = spla.spsolve(system.tocsc(), v + beta * dmat.T @ delta)
    return x


@pytest.mark.parametrize("solver, atol", [("cholesky", 1e-10), ("cg", 2e-6)])   # CG: a relative residual of 1e-5
def test_l0_matches_a_direct_solve_reference(box, solver, atol):
    v, f = np.asarray(box.vertices), np.asarray(box.faces)
    want = np_l0(v, f, np.asarray(box.edges), 10.0, 1.0, 6)
    got = l0_denoising(box, 10.0, 1.0, iterations=6, solver=solver)
    np.testing.assert_allclose(got.vertices, want, atol=atol)
    with pytest.raises(ValueError, match="solver must be"):
        inspect.unwrap(l0_denoising)(box, solver="lu")


def test_choose_denoiser_refuses_bad_arguments(sphere):
    with pytest.raises(ValueError, match="unknown method 'magic'"):
        choose_denoiser(sphere, candidates=[Candidate("magic", {})])
    with pytest.raises(ValueError, match="has no parameter"):
        choose_denoiser(sphere, candidates=[Candidate("taubin", {"sigma_r": 1.0})])
    with pytest.raises(ValueError, match="draws must be an int >= 1"):
        choose_denoiser(sphere, draws=0)
    with pytest.raises(ValueError, match="sigma must be a positive"):
        choose_denoiser(sphere, sigma=-1.0)
    with pytest.raises(ValueError, match="one mesh"):
        choose_denoiser(sphere.with_vertices(jnp.stack([sphere.vertices] * 2)))


def test_choose_denoiser_picks_the_feature_preserving_filter_on_a_noisy_box():
    """386 vertices: on the 98-vertex box the estimates' spread across draws is as
    large as the gap between the filters (guided 12.2° vs Taubin 16.4° there)."""
    b = trimesh.creation.box().subdivide().subdivide().subdivide()
    clean = jaxmesh.Mesh.from_arrays(b.vertices, b.faces).astype(jnp.float64)
    noisy = jaxmesh.add_noise(clean, 0.3, 1, along_normals=True)
    cands = [Candidate("taubin", {"iterations": k}) for k in (2, 10)] + [Candidate("guided_normal", {})]
    for key in (0, 1, 2):
        c = choose_denoiser(noisy, candidates=cands, paths=(), key=key, blend_draws=0)   # the ranking alone
        assert c.method == "guided_normal" and c.improved
        assert [row[0] for row in c.table].count("taubin") == 2 and c.table[0][2] <= c.table[1][2]


# the same scan for every path (PATHS[2] is PATHS[1]'s method at one setting); Taubin's 100 counts in the slow run
@pytest.mark.parametrize("which", [pytest.param(0, id="taubin", marks=pytest.mark.slow), pytest.param(1, id="bilateral")])
def test_a_path_estimates_what_the_candidate_loop_estimates(sphere, which):
    """A path (one scan over every iteration count per setting) reports for each
    setting the best count and the same estimate as running that setting as a
    fixed candidate; its winner beats every other count of its setting."""
    from jaxmesh.tune.auto import PATHS

    path = PATHS[which]
    noisy = jaxmesh.add_noise(sphere, 0.2, 5)
    c = choose_denoiser(noisy, candidates=[], paths=(path,), key=3, blend_draws=0,
                        race_keep=None)    # the ranking alone, every setting on every draw
    assert len(c.table) == len(path.settings) and {r[0] for r in c.table} == {path.method}
    method, params, risk = [r for r in c.table if r[1]["iterations"] < path.max_iterations][0]
    again = choose_denoiser(noisy, candidates=[Candidate(method, params)], paths=(), key=3, blend_draws=0)
    assert again.table[0][2] == pytest.approx(risk, rel=1e-9, abs=1e-12)
    others = [Candidate(method, {**params, "iterations": k})
              for k in {1, params["iterations"] + 1, path.max_iterations} - {params["iterations"]}]
    worse = choose_denoiser(noisy, candidates=others, paths=(), key=3, blend_draws=0, race_keep=None)
    assert min(r[2] for r in worse.table) >= risk
    np.testing.assert_allclose(c.mesh.vertices, jaxmesh.denoise.denoise(noisy, c.method, **c.params).vertices,
                               atol=1e-12)


@pytest.mark.parametrize("method, params", [("taubin", {"lam": 0.5, "mu": -0.53, "iterations": 7}),
                                            ("bilateral_normal", {"normal_iterations": 1, "vertex_iterations": 5,
                                                                  "iterations": 4})])
def test_a_counted_run_is_the_method_itself(sphere, method, params):
    """run_setting(counted=True), the iterations a traced count of single iterations, gives the
    method's own output, and one program serves every count."""
    from jaxmesh.tune.race import _run, run_setting

    noisy = jaxmesh.add_noise(sphere, 0.2, 5).astype(jnp.float64)
    aux = METHODS[method].prepare(noisy)
    want = METHODS[method](noisy, **params).vertices
    np.testing.assert_allclose(run_setting(noisy, noisy.vertices, method, params, aux, counted=True), want,
                               atol=1e-12)
    before = _run._cache_size()
    run_setting(noisy, noisy.vertices, method, {**params, "iterations": params["iterations"] + 3}, aux, counted=True)
    assert _run._cache_size() == before


def _stop_count(risks, factor, patience):
    """The early stop's rule as a plain loop: after iteration t (0-based), stop once t + 1 > best +
    patience and the risk of t exceeds factor × the least so far."""
    best = 0
    for t in range(len(risks)):
        best = t if risks[t] < risks[best] else best
        if t + 1 > best + patience and risks[t] > factor * risks[best]:
            return t + 1
    return len(risks)


def test_a_path_stops_once_its_risk_has_risen():
    """Stopped, a path's risks are the full curve's up to the count the rule gives (+inf after), so
    the least count is the full curve's; a tight rule stops Taubin's 100 counts early on a noisy
    box (Taubin rounds its creases)."""
    from jaxmesh.geometry import face_normals, mean_edge_length, vertex_normals
    from jaxmesh.tune.paths import PATH_STOP_FACTOR, PATH_STOP_PATIENCE, PATHS, path_risks
    from jaxmesh.tune.recorrupt import recorruptions

    b = trimesh.creation.box().subdivide().subdivide().subdivide()
    clean = jaxmesh.Mesh.from_arrays(b.vertices, b.faces).astype(jnp.float64)
    noisy = jaxmesh.add_noise(clean, 0.2, 5, along_normals=True)
    ell = mean_edge_length(noisy)
    nu, n = face_normals(noisy), vertex_normals(noisy, "area")
    zs, _ = recorruptions(noisy, nu, n, ell, 0.2 * float(ell), 0.0, 2, 1)
    inputs, targets = noisy.vertices[None] + 0.5 * zs, noisy.vertices[None] - zs / 0.5
    path = PATHS[0]
    aux = METHODS[path.method].prepare(noisy)
    for setting in path.settings[4::3]:                 # λ ≥ 0.35: the curve turns within 100 counts
        full = path_risks(noisy, path, setting, inputs, targets, nu, ell, aux, stop=None)
        assert np.isfinite(full).all() and len(full) == path.max_iterations
        for rule in ((PATH_STOP_FACTOR, PATH_STOP_PATIENCE), (1.01, 2)):
            stopped = path_risks(noisy, path, setting, inputs, targets, nu, ell, aux, stop=rule)
            k = _stop_count(full, *rule)
            np.testing.assert_allclose(stopped[:k], full[:k], rtol=1e-12)
            assert np.all(np.isinf(stopped[k:])) and np.argmin(stopped) == np.argmin(full)
            assert k < path.max_iterations or rule[0] > 1.01
        # one draw runs without its draw axis (a faster program): the two draws' curve is the sum of theirs
        single = sum(path_risks(noisy, path, setting, inputs[d:d + 1], targets[d:d + 1], nu, ell, aux, stop=None)
                     for d in range(2))
        np.testing.assert_allclose(single, full, rtol=1e-12)


def test_held_vertices_are_reset_after_every_iteration(sphere):
    """With a pin (mask, p), a path's risks and a counted run are those of a plain loop that sets the
    masked vertices to p after each single iteration; the pinned vertices end at p, the others move."""
    from jaxmesh.geometry import face_normals, mean_edge_length
    from jaxmesh.tune.paths import SearchPath, one_iteration, path_risks
    from jaxmesh.tune.race import run_setting, setting_tilt

    noisy = jaxmesh.add_noise(sphere, 0.2, 3).astype(jnp.float64)
    ell, nu = mean_edge_length(noisy), face_normals(noisy)
    rng = np.random.default_rng(0)
    inputs = noisy.vertices[None] + 0.01 * rng.standard_normal((2, noisy.num_vertices, 3))
    targets = noisy.vertices[None] + 0.01 * rng.standard_normal((2, noisy.num_vertices, 3))
    mask = np.arange(noisy.num_vertices) % 4 == 0
    p = np.asarray(noisy.vertices) + 0.003
    pin = (jnp.asarray(mask), jnp.asarray(p))
    for method, setting, fixed in (("taubin", {"lam": 0.5, "mu": -0.53}, ()),
                                   ("bilateral_normal", {"sigma_s": 1.0, "sigma_r": 0.6},
                                    (("normal_iterations", 1), ("vertex_iterations", 5)))):
        aux = METHODS[method].prepare(noisy)
        path = SearchPath(method, (setting,), fixed, 5)
        cont, statics = METHODS[method].split(**setting, **dict(fixed))
        statics = tuple(kv for kv in statics if kv[0] != "iterations")
        x, want = np.asarray(inputs), []
        for _ in range(5):
            x = np.array(one_iteration(noisy, jnp.asarray(x), cont, aux, method, statics))
            x[:, mask] = p[mask]
            t = np.asarray(edge_tilt(noisy, nu, ell, jnp.asarray(x) - targets))
            want.append(np.sum(t**2) / noisy.num_faces)
        got = path_risks(noisy, path, setting, inputs, targets, nu, ell, aux, stop=None, pin=pin)
        np.testing.assert_allclose(got, want, rtol=1e-10)
        assert not np.allclose(got, path_risks(noisy, path, setting, inputs, targets, nu, ell, aux, stop=None))
        params = {**setting, **dict(fixed), "iterations": 5}
        run = np.asarray(run_setting(noisy, inputs[0], method, params, aux, counted=True, pin=pin))
        np.testing.assert_allclose(run, x[0], atol=1e-12)
        np.testing.assert_array_equal(run[mask], p[mask])
        assert np.abs(run[~mask] - p[~mask]).max() > 1e-3
        tilt = setting_tilt(noisy, inputs[0], targets[0], nu, ell, method, params, aux, counted=True, pin=pin)
        np.testing.assert_allclose(tilt, edge_tilt(noisy, nu, ell, jnp.asarray(x[0]) - targets[0]), atol=1e-12)
        free = run_setting(noisy, inputs[0], method, params, aux, pin=pin)      # a whole run holds nothing
        np.testing.assert_allclose(free, METHODS[method](noisy.with_vertices(inputs[0]), **params).vertices,
                                   atol=1e-12)


def test_racing_finishes_the_best_of_each_family_on_every_draw(sphere):
    """After the first draw only the race_keep best settings of each family go on: their
    estimates are those of the unraced search, they come first in the table, and keeping
    as many as a family has is the unraced search itself."""
    from jaxmesh.tune.auto import PATHS

    noisy = jaxmesh.add_noise(sphere, 0.3, 2)
    cands = [Candidate("taubin", {"iterations": k}) for k in (1, 3, 10, 30)] + [Candidate("guided_normal", {})]
    kw = dict(candidates=cands, paths=(PATHS[1],), key=4, blend_draws=0)
    full = choose_denoiser(noisy, race_keep=None, **kw)
    raced = choose_denoiser(noisy, race_keep=2, **kw)
    every = choose_denoiser(noisy, race_keep=len(PATHS[1].settings), **kw)
    estimate = {(m, json.dumps(p, sort_keys=True)): r for m, p, r in full.table}
    finished = 2 + 1 + 2          # taubin's best two, the one guided, the path's best two settings
    assert len(raced.table) == len(full.table)
    for m, p, r in raced.table[:finished]:
        assert r == pytest.approx(estimate[m, json.dumps(p, sort_keys=True)], rel=1e-9, abs=1e-12)
    head = raced.table[:finished]
    assert sorted(r[2] for r in head) == [r[2] for r in head]
    assert sum(m == "taubin" for m, _, _ in head) == 2 and sum(m == "bilateral_normal" for m, _, _ in head) == 2
    assert raced.table[0][2] == pytest.approx(min(estimate[m, json.dumps(p, sort_keys=True)] for m, p, _ in head))
    assert [(m, p) for m, p, _ in every.table] == [(m, p) for m, p, _ in full.table]
    np.testing.assert_allclose([r[2] for r in every.table], [r[2] for r in full.table], rtol=1e-9, atol=1e-12)
    for bad in (0, -1, True):
        with pytest.raises(ValueError, match="race_keep must be None or an int >= 1"):
            choose_denoiser(noisy, race_keep=bad, **kw)


def test_choose_denoiser_refuses_a_bad_path(sphere):
    from jaxmesh.tune.auto import SearchPath

    with pytest.raises(ValueError, match="paths: each must be a SearchPath"):
        choose_denoiser(sphere, paths=(SearchPath("magic", ({},)),))
    with pytest.raises(ValueError, match="max_iterations must be a positive int"):
        choose_denoiser(sphere, paths=(SearchPath("taubin", ({},), (), 0),))
    with pytest.raises(ValueError, match="has no parameter"):
        choose_denoiser(sphere, paths=(SearchPath("taubin", ({"sigma_r": 1.0},)),))


@pytest.mark.parametrize("ratio", [0.0, 0.4, 1.0])
def test_the_recorruption_has_the_covariance_its_trace_assumes(sphere, ratio):
    """tr(AᵀAΣ)/F, computed in closed form for Σ_i = σ² n nᵀ + σ_t² (I − n nᵀ), equals the
    mean of ‖A z‖²/F over many draws of the recorruption z, and z's normal and
    tangential variances are σ² and 2σ_t² per vertex."""
    from jaxmesh.geometry import face_normals, mean_edge_length, vertex_normals
    from jaxmesh.tune.recorrupt import recorruptions

    mesh = jaxmesh.add_noise(sphere, 0.1, 4)
    nu, n = face_normals(sphere), vertex_normals(sphere, "area")
    ell, s = mean_edge_length(mesh), 0.01
    zs, trace = recorruptions(mesh, nu, n, ell, s, ratio * s, 4000, 7)
    r = edge_tilt(mesh, nu, ell, zs)
    assert float(jnp.mean(jnp.sum(r * r, axis=(-2, -1)))) / mesh.num_faces == pytest.approx(trace, rel=0.02)
    normal = jnp.sum(zs * n[None], axis=-1)
    assert float(jnp.mean(normal**2)) == pytest.approx(s**2, rel=0.02)
    assert float(jnp.mean(jnp.sum(zs * zs, axis=-1) - normal**2)) == pytest.approx(2 * (ratio * s) ** 2, rel=0.02,
                                                                                      abs=1e-12)


def test_antithetic_recorruptions_cancel_the_linear_term(sphere):
    """Draws come in (z, −z) pairs (independent without ``antithetic``), and for a linear denoiser
    f(y) = W y (Taubin: the umbrella operator depends on the topology only) the pair's mean squared
    tilt is exactly ‖A(W y − y)‖² + ‖A(a W z + z/a)‖²: the term linear in z is gone."""
    from jaxmesh.denoise import denoise
    from jaxmesh.geometry import face_normals, mean_edge_length, vertex_normals
    from jaxmesh.tune.recorrupt import recorruptions

    mesh = jaxmesh.add_noise(sphere, 0.2, 4)
    nu, n = face_normals(sphere), vertex_normals(sphere, "area")
    ell, a = mean_edge_length(mesh), 0.5
    zs, _ = recorruptions(mesh, nu, n, ell, 0.01, 0.004, 5, 3, antithetic=True)
    assert zs.shape[0] == 5
    np.testing.assert_array_equal(np.asarray(zs[1]), -np.asarray(zs[0]))
    np.testing.assert_array_equal(np.asarray(zs[3]), -np.asarray(zs[2]))
    plain, _ = recorruptions(mesh, nu, n, ell, 0.01, 0.004, 2, 3)
    assert float(jnp.max(jnp.abs(plain[1] + plain[0]))) > 1e-3
    y = mesh.vertices

    def w(x):
        return denoise(mesh.with_vertices(x), "taubin", iterations=4).vertices

    def sq(u):
        return float(jnp.sum(edge_tilt(mesh, nu, ell, u) ** 2))

    pair = [sq(w(y + a * z) - (y - z / a)) for z in zs[:2]]
    expected = sq(w(y) - y) + sq(a * w(zs[0]) + zs[0] / a)
    assert abs(pair[0] - pair[1]) > 1e-6 * expected          # each draw alone carries the linear term
    assert (pair[0] + pair[1]) / 2 == pytest.approx(expected, rel=1e-9)


def test_fewer_recorruptions_are_the_first_of_more(sphere):
    """The fields of a count are the first fields of any larger count (independent or in antithetic
    pairs; one program draws them for every count up to FIELD_CAPACITY), under another salt others; the
    trace does not depend on the count."""
    from jaxmesh.geometry import face_normals, mean_edge_length, vertex_normals
    from jaxmesh.tune.recorrupt import FIELD_CAPACITY, recorruptions

    mesh = jaxmesh.add_noise(sphere, 0.2, 4)
    nu, n, ell = face_normals(sphere), vertex_normals(sphere, "area"), mean_edge_length(mesh)
    for antithetic in (False, True):
        few, t_few = recorruptions(mesh, nu, n, ell, 0.01, 0.004, 3, 7, antithetic=antithetic)
        many, t_many = recorruptions(mesh, nu, n, ell, 0.01, 0.004, FIELD_CAPACITY + 3, 7, antithetic=antithetic)
        assert few.shape == (3, mesh.num_vertices, 3) and many.shape[0] == FIELD_CAPACITY + 3
        np.testing.assert_array_equal(np.asarray(many[:3]), np.asarray(few))
        assert t_few == t_many
    plain, _ = recorruptions(mesh, nu, n, ell, 0.01, 0.004, 3, 7)
    other, _ = recorruptions(mesh, nu, n, ell, 0.01, 0.004, 3, 7, salt=1)
    assert float(jnp.max(jnp.abs(other[0] - plain[0]))) > 1e-3


def test_the_noise_model_sets_the_recorruptions_tangential_part():
    b = trimesh.creation.box().subdivide().subdivide().subdivide()
    clean = jaxmesh.Mesh.from_arrays(b.vertices, b.faces).astype(jnp.float64)
    noisy = jaxmesh.add_noise(clean, 0.2, 1)
    few = [Candidate("taubin", {"iterations": 5})]
    along = choose_denoiser(noisy, candidates=few, paths=(), noise_model="normal")
    iso = choose_denoiser(noisy, candidates=few, paths=(), noise_model="isotropic")
    auto = choose_denoiser(noisy, candidates=few, paths=())
    assert along.tangential_sigma == 0.0 and iso.tangential_sigma == iso.sigma
    assert 0.0 < auto.tangential_sigma <= auto.sigma and auto.summary()["tangential_noise_sigma"] == auto.tangential_sigma
    assert iso.noisy_risk > along.noisy_risk          # the tangential part adds to the input's error
    with pytest.raises(ValueError, match="noise_model must be one of"):
        choose_denoiser(noisy, candidates=few, noise_model="laplacian")


def test_library_draws_never_reproduce_the_users_noise():
    """jax.random is prefix-consistent: with one integer seed for the user's noise
    and for the library's own draws, the recorruption equalled the noise and the
    SURE probes were minus its signs.  The library folds its keys per stream."""
    from jaxmesh._private import PROBE_STREAM, RECORRUPTION_STREAM, library_key

    noise = np.asarray(jax.random.normal(jax.random.PRNGKey(0), (500, 1))).ravel()
    raw = np.asarray(jax.random.normal(jax.random.PRNGKey(0), (2, 500, 1)))[0].ravel()
    assert np.corrcoef(noise, raw)[0, 1] > 0.999                  # the trap
    ours = np.asarray(jax.random.normal(library_key(0, RECORRUPTION_STREAM), (2, 500, 1)))[0].ravel()
    assert abs(np.corrcoef(noise, ours)[0, 1]) < 0.2
    signs = np.sign(np.asarray(jax.random.normal(jax.random.PRNGKey(0), (500, 3)))).ravel()
    probes = np.asarray(jax.random.rademacher(library_key(0, PROBE_STREAM), (1, 500, 3)), float).ravel()
    assert abs(np.corrcoef(signs, probes)[0, 1]) < 0.2


def test_the_tuner_builds_the_face_graph_and_apply_reproduces_it(box):
    from jaxmesh.tune import tune

    clean = jaxmesh.Mesh.from_arrays(trimesh.creation.box().subdivide().subdivide().vertices, box.faces)
    noisy = jaxmesh.add_noise(clean, 0.3, 2, along_normals=True)
    r = tune(noisy, clean, "bilateral_normal", objective="normal", names=("sigma_r",), max_steps=4)
    assert float(r.loss) < 0.5                       # normal error below half the input's
    np.testing.assert_allclose(r.apply(noisy).vertices, r.mesh.vertices, atol=1e-10)
    with pytest.raises(ValueError, match="built by the tuner"):
        tune(noisy, clean, "bilateral_normal", graph=face_graph(noisy))
