"""Impulsive-noise detection (jaxmesh.tune.impulsive) and the chooser's impulsive law."""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np
import pytest
import trimesh

import jaxmesh
from jaxmesh.geometry import face_normals, mean_edge_length, vertex_normals
from jaxmesh.tune import Candidate, choose_denoiser, edge_tilt
from jaxmesh.denoise import METHODS, impulse_repair, mixture_posterior, scale_mixture
from jaxmesh.metrics import mean_normal_angle_error
from jaxmesh.tune.impulsive import estimate_impulsive_noise, read_after_repair
from jaxmesh.tune.recorrupt import recorruptions


@pytest.fixture(scope="module")
def ball():
    s = trimesh.creation.icosphere(4)                       # 2562 vertices
    return jaxmesh.Mesh.from_arrays(s.vertices, s.faces).astype(jnp.float64)


def test_the_mixture_fit_recovers_a_known_scale_mixture():
    """EM on samples of 0.3 N(0, 4) + 0.7 N(0, 0.09) (numpy draws) returns the weights and variances;
    masked samples do not count."""
    rng = np.random.default_rng(0)
    heavy = rng.random(200_000) < 0.3
    z = np.where(heavy, 2.0, 0.3) * rng.standard_normal(heavy.size)
    p, v0, v1 = (float(v) for v in scale_mixture(jnp.asarray(z**2), 300))
    assert p == pytest.approx(0.3, abs=0.01)
    assert v0 == pytest.approx(0.09, rel=0.03) and v1 == pytest.approx(4.0, rel=0.03)
    padded = jnp.concatenate([jnp.asarray(z**2), jnp.full(50_000, 1e6)])
    mask = jnp.arange(padded.size) < z.size
    np.testing.assert_allclose(scale_mixture(padded, 300, mask=mask), (p, v0, v1), rtol=1e-9)


def test_the_mixture_fit_is_the_em_of_its_formula():
    """A plain numpy EM loop written from the mixture's formulas, from the same start, gives the same fit."""
    rng = np.random.default_rng(1)
    r2 = (np.where(rng.random(5000) < 0.4, 1.5, 0.2) * rng.standard_normal(5000)) ** 2
    p, v0, v1 = 0.5, r2.mean() / 4, 2 * r2.mean()
    for _ in range(40):
        a = p * np.exp(-r2 / (2 * v1)) / np.sqrt(v1)
        b = (1 - p) * np.exp(-r2 / (2 * v0)) / np.sqrt(v0)
        post = a / (a + b)
        p, v0, v1 = post.mean(), np.sum((1 - post) * r2) / np.sum(1 - post), np.sum(post * r2) / np.sum(post)
    np.testing.assert_allclose(scale_mixture(jnp.asarray(r2), 40), (p, v0, v1), rtol=1e-9)
    np.testing.assert_allclose(mixture_posterior(jnp.asarray(r2), p, v0, v1), post_of(r2, p, v0, v1), rtol=1e-9,
                               atol=1e-12)


def post_of(r2, p, v0, v1):
    a = p * np.exp(-r2 / (2 * v1)) / np.sqrt(v1)
    return a / (a + (1 - p) * np.exp(-r2 / (2 * v0)) / np.sqrt(v0))


def test_each_fit_solves_the_weighted_thin_plate_system(ball):
    """(W + α KᵀK) x = W y against scipy's direct solve with the umbrella matrix."""
    import scipy.sparse as sp
    import scipy.sparse.linalg as sla

    from jaxmesh.denoise.impulse_repair import _fit
    from jaxmesh.sparse import umbrella_matrix

    noisy = jaxmesh.add_noise(ball, 0.3, 2)
    w = np.random.default_rng(2).uniform(0.01, 1.0, ball.num_vertices)
    k = umbrella_matrix(noisy)
    y = np.asarray(noisy.vertices)
    want = sla.spsolve((sp.diags(w) + 0.7 * (k.T @ k)).tocsc(), w[:, None] * y)
    got = _fit(noisy, noisy.vertices, jnp.asarray(w), 0.7, noisy.vertices)
    np.testing.assert_allclose(got, want, atol=1e-8)


def test_impulse_repair_keeps_the_untouched_vertices_and_beats_taubin(ball):
    ell = float(mean_edge_length(ball))
    noisy = jaxmesh.add_impulsive_noise(ball, 0.5, 6, fraction=0.3)
    moved = np.linalg.norm(np.asarray(noisy.vertices - ball.vertices), axis=1) > 0
    out = impulse_repair(noisy)
    shift = np.linalg.norm(np.asarray(out.vertices - noisy.vertices), axis=1)
    assert np.median(shift[~moved]) < 0.02 * ell                  # the untouched stay (nearly) where they are
    taubin = METHODS["taubin"](noisy, iterations=20)
    assert float(mean_normal_angle_error(ball, out)) < 0.5 * float(mean_normal_angle_error(ball, taubin))


def test_the_second_reading_is_sharper(ball):
    noisy = jaxmesh.add_impulsive_noise(ball, 0.5, 3, fraction=0.5)
    first = estimate_impulsive_noise(noisy)
    second = read_after_repair(noisy, first)
    untouched = np.linalg.norm(np.asarray(noisy.vertices - ball.vertices), axis=1) == 0
    assert second.impulsive == first.impulsive and second.posterior.shape == first.posterior.shape
    assert second.posterior[untouched].mean() < 0.5 * first.posterior[untouched].mean()
    assert second.fraction == pytest.approx(0.5, abs=0.12)


def test_impulsive_noise_is_read_with_its_fraction_and_level(ball):
    ell = float(mean_edge_length(ball))
    noisy = jaxmesh.add_impulsive_noise(ball, 0.5, 3, fraction=0.5)
    moved = np.linalg.norm(np.asarray(noisy.vertices - ball.vertices), axis=1)
    law = estimate_impulsive_noise(noisy)
    assert law.impulsive
    assert law.fraction == pytest.approx(0.5, abs=0.1)
    assert law.sigma / ell == pytest.approx(0.5, rel=0.15) and law.sigma0 < 0.35 * law.sigma
    assert law.posterior.shape == (ball.num_vertices,) and np.all((law.posterior >= 0) & (law.posterior <= 1))
    # a vertex moved by more than σ is read as displaced; an untouched one leans the other way (its
    # neighbours' noise reaches its residual, so it is not read as clean with certainty)
    assert law.posterior[moved > 0.5 * ell].mean() > 0.85 and law.posterior[moved == 0].mean() < 0.5
    s = law.vertex_sigma()
    assert np.all((s >= law.sigma0 - 1e-12) & (s <= law.sigma + 1e-12))


@pytest.mark.parametrize("along", [True, False])
def test_gaussian_noise_and_a_clean_mesh_are_not_read_as_impulsive(ball, along):
    ell = float(mean_edge_length(ball))
    law = estimate_impulsive_noise(jaxmesh.add_noise(ball, 0.3, 4, along_normals=along))
    assert not law.impulsive and law.sigma0 > 0.5 * law.sigma and law.sigma / ell == pytest.approx(0.3, rel=0.3)
    assert not estimate_impulsive_noise(ball).impulsive


def test_the_reading_is_scale_equivariant_and_rotation_invariant(ball):
    noisy = jaxmesh.add_impulsive_noise(ball, 0.5, 5, fraction=0.3)
    law = estimate_impulsive_noise(noisy)
    q, _ = np.linalg.qr(np.random.default_rng(1).standard_normal((3, 3)))
    moved = noisy.with_vertices(2.5 * noisy.vertices @ jnp.asarray(q.T) + 1.0)
    other = estimate_impulsive_noise(moved)
    assert other.impulsive == law.impulsive and other.fraction == pytest.approx(law.fraction, abs=1e-6)
    assert other.sigma == pytest.approx(2.5 * law.sigma, rel=1e-6)
    np.testing.assert_allclose(other.posterior, law.posterior, atol=1e-6)


@pytest.mark.slow   # a statistical check over many draws
def test_per_vertex_recorruption_has_the_covariance_its_trace_assumes():
    """With s_i per vertex, z's normal variance is s_i² and the closed-form trace equals the Monte Carlo mean."""
    s = trimesh.creation.icosphere(3)                        # 642 vertices: no decision here, only draws
    ball = jaxmesh.Mesh.from_arrays(s.vertices, s.faces).astype(jnp.float64)
    nu, n = face_normals(ball), vertex_normals(ball, "area")
    ell = mean_edge_length(ball)
    s = np.where(np.arange(ball.num_vertices) % 3 == 0, 0.02, 0.002)
    zs, trace = recorruptions(ball, nu, n, ell, s, 0.0, 3000, 7)
    r = edge_tilt(ball, nu, ell, zs)
    assert float(jnp.mean(jnp.sum(r * r, axis=(-2, -1)))) / ball.num_faces == pytest.approx(trace, rel=0.03)
    var = np.asarray(jnp.mean(jnp.sum(zs * n[None], axis=-1) ** 2, axis=0))
    for level in (0.02, 0.002):
        assert var[s == level].mean() == pytest.approx(level**2, rel=0.03)
    _, scalar = recorruptions(ball, nu, n, ell, 0.02, 0.0, 1, 7)
    _, uniform = recorruptions(ball, nu, n, ell, np.full(ball.num_vertices, 0.02), 0.0, 1, 7)
    assert uniform == pytest.approx(scalar, rel=1e-12)


@pytest.mark.slow   # a whole blind search; the default run has the command's (tests/cli) and the held-out one's
def test_the_chooser_uses_the_impulsive_law_and_its_robust_candidates(ball):
    few = [Candidate("taubin", {"iterations": 5})]
    robust = [Candidate("impulse_repair", {"iterations": 1})]
    noisy = jaxmesh.add_impulsive_noise(ball, 0.5, 3, fraction=0.5)
    c = choose_denoiser(noisy, candidates=few, impulsive_candidates=robust, paths=(), blend_draws=0)
    assert c.noise_law == "impulsive" and c.fraction == pytest.approx(0.5, abs=0.1)
    assert {row[0] for row in c.table} == {"taubin", "impulse_repair"} and c.tangential_sigma == 0.0
    assert c.summary()["noise_law"] == "impulsive" and c.summary()["noise_fraction"] == c.fraction
    gaussian = choose_denoiser(jaxmesh.add_noise(ball, 0.3, 4), candidates=few, impulsive_candidates=robust,
                               paths=(), blend_draws=0)
    assert gaussian.noise_law == "gaussian" and gaussian.fraction == 1.0 and {r[0] for r in gaussian.table} == {"taubin"}
    level = 0.5 * float(mean_edge_length(ball))
    given = choose_denoiser(noisy, level, candidates=few, impulsive_candidates=robust, paths=(), blend_draws=0)
    assert given.noise_law == "impulsive" and given.sigma == level and not given.estimated
    forced = choose_denoiser(jaxmesh.add_noise(ball, 0.3, 4), candidates=few, impulsive_candidates=(), paths=(),
                             noise_model="impulsive", blend_draws=0)
    assert forced.noise_law == "impulsive"
    off = choose_denoiser(noisy, candidates=few, impulsive_candidates=robust, paths=(), noise_model="normal",
                          blend_draws=0)
    assert off.noise_law == "gaussian" and {r[0] for r in off.table} == {"taubin"}


def test_the_impulsive_reading_refuses_a_batch(ball):
    with pytest.raises(ValueError, match="takes one mesh"):
        estimate_impulsive_noise(ball.with_vertices(jnp.stack([ball.vertices, ball.vertices])))


def test_a_few_hundred_vertices_are_too_few_to_decide():
    """On the 386-vertex box, Gaussian noise along the normals (this seed) fits like impulsive noise."""
    b = trimesh.creation.box().subdivide().subdivide().subdivide()
    box = jaxmesh.Mesh.from_arrays(b.vertices, b.faces).astype(jnp.float64)
    law = estimate_impulsive_noise(jaxmesh.add_noise(box, 0.3, 1, along_normals=True))
    assert box.num_vertices < 500 and law.sigma0 < 0.35 * law.sigma and not law.impulsive
