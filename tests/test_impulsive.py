"""Impulsive-noise detection (jaxmesh.tune.impulsive) and the chooser's impulsive law."""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np
import pytest
import trimesh

import jaxmesh
from jaxmesh.geometry import face_normals, mean_edge_length, vertex_normals
from jaxmesh.tune import Candidate, choose_denoiser, edge_tilt
from jaxmesh.tune.impulsive import estimate_impulsive_noise, scale_mixture_em
from jaxmesh.tune.recorrupt import recorruptions


@pytest.fixture(scope="module")
def ball():
    s = trimesh.creation.icosphere(4)                       # 2562 vertices
    return jaxmesh.Mesh.from_arrays(s.vertices, s.faces).astype(jnp.float64)


def test_the_mixture_fit_recovers_a_known_scale_mixture():
    """EM on samples of 0.3 N(0, 4) + 0.7 N(0, 0.09) (numpy draws) returns the weights and variances."""
    rng = np.random.default_rng(0)
    heavy = rng.random(200_000) < 0.3
    z = np.where(heavy, 2.0, 0.3) * rng.standard_normal(heavy.size)
    p, v0, v1 = scale_mixture_em(z)
    assert p == pytest.approx(0.3, abs=0.01)
    assert v0 == pytest.approx(0.09, rel=0.03) and v1 == pytest.approx(4.0, rel=0.03)
    assert scale_mixture_em(np.zeros(10)) == (0.0, 0.0, 0.0)


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


def test_per_vertex_recorruption_has_the_covariance_its_trace_assumes(ball):
    """With s_i per vertex, z's normal variance is s_i² and the closed-form trace equals the Monte Carlo mean."""
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


def test_the_chooser_uses_the_impulsive_law_and_its_robust_candidates(ball):
    few = [Candidate("taubin", {"iterations": 5})]
    robust = [Candidate("l0", {"lam": 10.0, "iterations": 10})]
    noisy = jaxmesh.add_impulsive_noise(ball, 0.5, 3, fraction=0.5)
    c = choose_denoiser(noisy, candidates=few, impulsive_candidates=robust, paths=(), blend_draws=0)
    assert c.noise_law == "impulsive" and c.fraction == pytest.approx(0.5, abs=0.1)
    assert {row[0] for row in c.table} == {"taubin", "l0"} and c.tangential_sigma == 0.0
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
    s = trimesh.creation.icosphere(3)                        # 642 vertices
    small = jaxmesh.Mesh.from_arrays(s.vertices, s.faces).astype(jnp.float64)
    law = estimate_impulsive_noise(jaxmesh.add_impulsive_noise(small, 0.5, 3, fraction=0.5))
    assert not law.impulsive and law.sigma0 < 0.35 * law.sigma      # it reads like impulsive noise, undecided
