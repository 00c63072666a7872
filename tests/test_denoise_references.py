"""Each baseline against an independent implementation: scipy sparse matrices
and plain numpy loops over vertices and faces, written from the papers."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
import scipy.sparse as sp
import scipy.sparse.linalg as spla
import scipy.stats
import trimesh

import jaxmesh
from conftest import loop_cotangent_matrix
from jaxmesh import sparse
from jaxmesh.denoise import (
    METHODS,
    face_curvatures,
    face_rings,
    kernel_density,
    ring_sum,
)


@pytest.fixture(scope="module")
def noisy():
    s = trimesh.creation.icosphere(2)
    rng = np.random.default_rng(7)
    return jaxmesh.Mesh.from_arrays(s.vertices + 0.02 * rng.standard_normal(s.vertices.shape), s.faces)


def np_arrays(mesh):
    return np.asarray(mesh.vertices), np.asarray(mesh.faces)


def np_neighbours(faces, n):
    nb = [set() for _ in range(n)]
    for a, b, c in faces:
        nb[a] |= {b, c}
        nb[b] |= {a, c}
        nb[c] |= {a, b}
    return [sorted(x) for x in nb]


def np_face_normals_areas(v, faces):
    cr = np.cross(v[faces[:, 1]] - v[faces[:, 0]], v[faces[:, 2]] - v[faces[:, 0]])
    nrm = np.linalg.norm(cr, axis=1)
    return cr / nrm[:, None], nrm / 2


def test_laplacian_and_taubin_match_scipy_umbrella_iteration(noisy):
    k = sparse.umbrella_matrix(noisy)
    x = np.asarray(noisy.vertices)
    lap, tau = x.copy(), x.copy()
    for _ in range(4):
        lap = lap + 0.4 * (k @ lap)
        tau = tau + 0.5 * (k @ tau)
        tau = tau - 0.53 * (k @ tau)
    np.testing.assert_allclose(METHODS["umbrella_flow"](noisy, lam=0.4, iterations=4).vertices, lap, atol=1e-12)
    np.testing.assert_allclose(METHODS["taubin"](noisy, iterations=4).vertices, tau, atol=1e-12)


def _cot_matrix(v, faces):
    """Symmetric matrix of cot α + cot β from the plain-loop reference of test_operators."""
    return sp.csr_matrix(loop_cotangent_matrix(v, faces))


def test_explicit_cotangent_flow_matches_numpy(noisy):
    x = np.asarray(noisy.vertices).copy()
    faces = np.asarray(noisy.faces)
    for _ in range(2):
        w = _cot_matrix(x, faces)
        total = np.asarray(w.sum(axis=1)).ravel()
        x = x + 0.5 * (w @ x - total[:, None] * x) / total[:, None]
    np.testing.assert_allclose(METHODS["cotangent"](noisy, dt=0.5, iterations=2).vertices, x, atol=1e-10)


def test_implicit_cotangent_flow_matches_scipy_direct_solve(noisy):
    x = np.asarray(noisy.vertices).copy()
    faces = np.asarray(noisy.faces)
    dt = 0.7
    for _ in range(2):
        _, area = np_face_normals_areas(x, faces)
        mass = np.bincount(faces.ravel(), np.repeat(area, 3), len(x)) / 3
        w = 0.5 * _cot_matrix(x, faces)
        stiff = sp.diags(np.asarray(w.sum(axis=1)).ravel()) - w
        tau = dt * mass.sum() / len(x)
        x = spla.spsolve((sp.diags(mass) + tau * stiff).tocsc(), mass[:, None] * x)
    out = METHODS["cotangent_implicit"](noisy, dt=dt, iterations=2).vertices
    np.testing.assert_allclose(out, x, atol=1e-8)


def test_zhang_ben_hamza_paper_variant_matches_numpy(noisy):
    v, faces = np_arrays(noisy)
    nb = np_neighbours(faces, len(v))
    d = np.array([len(n) for n in nb], float)
    c_rel, dt = 1.5, 0.2

    def grad_mag(x):
        return np.array([np.sqrt(sum(np.sum((x[i] / np.sqrt(d[i]) - x[j] / np.sqrt(d[j])) ** 2)
                                     for j in nb[i])) for i in range(len(x))])

    c = c_rel * grad_mag(v).mean()
    x = v.copy()
    for _ in range(2):
        g = 1 / (1 + (grad_mag(x) / c) ** 2)
        new = x.copy()
        for i in range(len(x)):
            new[i] += dt * sum((g[i] + g[j]) / np.sqrt(d[i]) * (x[j] / np.sqrt(d[j]) - x[i] / np.sqrt(d[i]))
                               for j in nb[i])
        x = new
    out = METHODS["cauchy_diffusion"](noisy, dt=dt, c=c_rel, iterations=2, variant="paper").vertices
    np.testing.assert_allclose(out, x, atol=1e-12)


def test_ring_sum_equals_explicit_face_rings(noisy):
    rings = face_rings(noisy)
    idx, mask = np.asarray(rings.index), np.asarray(rings.mask)
    faces = np.asarray(noisy.faces)
    # N(f) is exactly the faces sharing a vertex with f
    for f in range(0, len(faces), 37):
        expect = {g for g in range(len(faces)) if set(faces[g]) & set(faces[f])}
        assert set(idx[f][mask[f]]) == expect
    vals = np.random.default_rng(0).standard_normal((len(faces), 3))
    explicit = np.array([vals[idx[f][mask[f]]].sum(axis=0) for f in range(len(faces))])
    np.testing.assert_allclose(ring_sum(noisy, jnp.asarray(vals)), explicit, atol=1e-12)


def np_normal_filtering(v, faces, kind, normal_iterations, vertex_iterations):
    """Yagou et al. 2002's normal filters, then Sun et al. 2007's vertex update
    (jaxmesh's one update for every two-step method), one round, explicit loops."""
    n, area = np_face_normals_areas(v, faces)
    rings = [[g for g in range(len(faces)) if set(faces[g]) & set(faces[f])] for f in range(len(faces))]
    for _ in range(normal_iterations):
        new = np.empty_like(n)
        for f, r in enumerate(rings):
            if kind == "mean":
                s = (area[r, None] * n[r]).sum(axis=0)
                new[f] = s / np.linalg.norm(s)
            else:
                ang = np.arccos(np.clip(n[r] @ n[r].T, -1, 1)).sum(axis=1)
                new[f] = n[r][np.argmin(ang)]
        n = new
    x = v.copy()
    for _ in range(vertex_iterations):
        c = x[faces].mean(axis=1)
        move, total = np.zeros_like(x), np.zeros(len(x))
        for f, (a, b, cc) in enumerate(faces):   # the shared update of Sun et al. 2007: uniform weights
            for i in (a, b, cc):
                move[i] += n[f] * (n[f] @ (c[f] - x[i]))
                total[i] += 1
        x = x + move / total[:, None]
    return x


@pytest.mark.parametrize("kind", ["mean", "median"])
def test_normal_filtering_matches_numpy(noisy, kind):
    v, faces = np_arrays(noisy)
    ref = np_normal_filtering(v, faces, kind, 2, 3)
    out = METHODS[f"normal_{kind}"](noisy, iterations=1, normal_iterations=2, vertex_iterations=3)
    np.testing.assert_allclose(out.vertices, ref, atol=1e-10)


def test_bilateral_matches_numpy(noisy):
    v, faces = np_arrays(noisy)
    nb = np_neighbours(faces, len(v))
    edges = {tuple(sorted((f[a], f[b]))) for f in faces for a, b in ((0, 1), (1, 2), (2, 0))}
    ell = np.mean([np.linalg.norm(v[i] - v[j]) for i, j in edges])
    sc, ss = 1.3 * ell, 0.4 * ell
    x = v.copy()
    for _ in range(2):
        fn, area = np_face_normals_areas(x, faces)
        vn = np.zeros_like(x)
        for f, tri in enumerate(faces):
            vn[tri] += area[f] * fn[f]
        vn /= np.linalg.norm(vn, axis=1)[:, None]
        new = x.copy()
        for i in range(len(x)):
            num = den = 0.0
            for j in nb[i]:
                t, h = np.linalg.norm(x[j] - x[i]), vn[i] @ (x[j] - x[i])
                w = np.exp(-t * t / (2 * sc * sc)) * np.exp(-h * h / (2 * ss * ss))
                num, den = num + w * h, den + w
            new[i] = x[i] + vn[i] * num / den
        x = new
    out = METHODS["bilateral"](noisy, sigma_c=1.3, sigma_s=0.4, iterations=2).vertices
    np.testing.assert_allclose(out, x, atol=1e-12)


def test_geometric_diffusion_with_isotropic_tensor_is_implicit_curvature_flow(noisy):
    iso = METHODS["geometric"](noisy, dt=0.5, rho=1e9, iterations=2).vertices
    cot = METHODS["cotangent_implicit"](noisy, dt=0.5, iterations=2).vertices
    np.testing.assert_allclose(iso, cot, atol=1e-8)


def test_face_curvatures_on_a_sphere_and_a_cylinder():
    s = trimesh.creation.icosphere(4, radius=2.0)
    curvatures = jax.jit(face_curvatures)      # one compile per mesh, not one per operation
    k1, k2, _, _ = curvatures(jaxmesh.Mesh.from_arrays(s.vertices, s.faces))
    np.testing.assert_allclose(np.median(k1), 0.5, rtol=0.05)
    np.testing.assert_allclose(np.median(k2), 0.5, rtol=0.05)
    c = trimesh.creation.cylinder(radius=0.5, height=4.0, sections=64)
    c = c.subdivide().subdivide()
    mesh = jaxmesh.Mesh.from_arrays(c.vertices, c.faces)
    k1, k2, w1, w2 = (np.asarray(a) for a in curvatures(mesh))
    centre = np.abs(np.asarray(c.triangles_center)[:, 2]) < 1.0      # away from the caps
    big = np.maximum(np.abs(k1), np.abs(k2))[centre]
    small = np.minimum(np.abs(k1), np.abs(k2))[centre]
    np.testing.assert_allclose(np.median(big), 2.0, rtol=0.05)
    assert np.median(small) < 0.05
    # the direction of zero curvature runs along the axis
    flat_dir = np.where((np.abs(k1) < np.abs(k2))[:, None], w1, w2)[centre]
    assert np.median(np.abs(flat_dir[:, 2])) > 0.99


def test_kernel_density_matches_scipy_gaussian_kde(noisy):
    v = np.asarray(noisy.vertices)
    pts = np.random.default_rng(1).uniform(-1.2, 1.2, (50, 3))
    ref = scipy.stats.gaussian_kde(v.T, bw_method="scott")(pts.T)
    np.testing.assert_allclose(kernel_density(noisy, jnp.asarray(pts), chunk=16), ref, rtol=1e-10)
    lit = kernel_density(noisy, jnp.asarray(pts), scale=1.0)
    np.testing.assert_allclose(lit, scipy.stats.gaussian_kde(v.T, bw_method=1.0)(pts.T), rtol=1e-10)


def test_hc_matches_trimesh_filter_humphrey(noisy):
    import trimesh.smoothing

    m = trimesh.Trimesh(np.asarray(noisy.vertices).copy(), np.asarray(noisy.faces), process=False)
    trimesh.smoothing.filter_humphrey(m, alpha=0.2, beta=0.6, iterations=4)
    out = METHODS["hc"](noisy, alpha=0.2, beta=0.6, iterations=4).vertices
    np.testing.assert_allclose(out, m.vertices, atol=1e-12)


def test_boundary_curve_smoothing_matches_numpy_on_an_open_grid():
    from conftest import grid_arrays

    v, faces = grid_arrays(5, 4, jitter=0.1, seed=4)
    mesh = jaxmesh.Mesh.from_arrays(v, faces)
    edge_faces = {}
    for f in faces:
        for a, b in ((f[0], f[1]), (f[1], f[2]), (f[2], f[0])):
            edge_faces[tuple(sorted((a, b)))] = edge_faces.get(tuple(sorted((a, b))), 0) + 1
    boundary = {e for e, c in edge_faces.items() if c == 1}
    on_boundary = {i for e in boundary for i in e}
    nbrs = {i: set() for i in range(len(v))}
    for a, b in edge_faces:
        if a not in on_boundary or (a, b) in boundary:
            nbrs[a].add(b)
        if b not in on_boundary or (a, b) in boundary:
            nbrs[b].add(a)
    x = v.copy()
    for _ in range(3):
        x = x + 0.5 * np.array([x[sorted(nbrs[i])].mean(axis=0) - x[i] for i in range(len(x))])
    out = METHODS["umbrella_flow"](mesh, lam=0.5, iterations=3, boundary="curve").vertices
    np.testing.assert_allclose(out, x, atol=1e-12)
    # a boundary vertex never moves off the boundary polygon's plane (z = 0 here), and the free
    # mode differs from the curve mode only on the boundary
    free = np.asarray(METHODS["umbrella_flow"](mesh, lam=0.5, iterations=1).vertices)
    curve = np.asarray(METHODS["umbrella_flow"](mesh, lam=0.5, iterations=1, boundary="curve").vertices)
    interior = np.array([i not in on_boundary for i in range(len(v))])
    np.testing.assert_allclose(free[interior], curve[interior], atol=1e-12)
    assert np.abs(free[~interior] - curve[~interior]).max() > 1e-3
