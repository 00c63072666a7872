"""The blind chooser's second pilot (jaxmesh.tune.second_pilot): the path leaders' counts picked again
under the race winner's output, and the choice judged under it."""

import jax.numpy as jnp
import numpy as np
import pytest
import trimesh

import jaxmesh
from jaxmesh.denoise import METHODS
from jaxmesh.geometry import face_normals, mean_edge_length
from jaxmesh.tune import Candidate, Ranked, choose_denoiser
from jaxmesh.tune.paths import SearchPath, path_risks
from jaxmesh.tune.second_pilot import repick_counts


@pytest.fixture(scope="module")
def noisy():
    s = trimesh.creation.icosphere(3)
    clean = jaxmesh.Mesh.from_arrays(s.vertices, s.faces).astype(jnp.float64)
    return jaxmesh.add_noise(clean, 0.3, 1)


def test_repick_counts_takes_each_paths_least_count_over_the_draws(noisy):
    """Each path leader gets the count of the least risk summed over the draws, each draw's curve being
    path_risks' own with every count run; its estimate is that least mean less the constant; the fixed
    leaders stay as they were (the same objects)."""
    ell, nu = mean_edge_length(noisy), face_normals(noisy)
    rng = np.random.default_rng(0)
    inputs = noisy.vertices[None] + 0.02 * rng.standard_normal((2, noisy.num_vertices, 3))
    targets = noisy.vertices[None] + 0.02 * rng.standard_normal((2, noisy.num_vertices, 3))
    paths = (SearchPath("taubin", ({"lam": 0.5, "mu": -0.53}, {"lam": 0.2, "mu": -0.21}), (), 30),
             SearchPath("bilateral_normal", ({"sigma_s": 1.0, "sigma_r": 0.6},),
                        (("normal_iterations", 1), ("vertex_iterations", 5)), 8))
    fixed = Ranked("guided_normal", {"sigma_r": 0.3}, 0.5)
    leaders = [fixed, Ranked("taubin", {"lam": 0.2, "mu": -0.21, "iterations": 30}, 0.1),
               Ranked("bilateral_normal", {"sigma_s": 1.0, "sigma_r": 0.6, "normal_iterations": 1,
                                           "vertex_iterations": 5, "iterations": 1}, 0.2)]
    auxes = {m: METHODS[m].prepare(noisy) for m in ("taubin", "bilateral_normal")}
    out = repick_counts(noisy, leaders, paths, inputs, targets, nu, ell, auxes, 0.25)
    assert out[0] is fixed and leaders[1].params["iterations"] == 30          # the input list is left alone
    for lead, new, path, setting in zip(leaders[1:], out[1:], paths, ({"lam": 0.2, "mu": -0.21}, paths[1].settings[0])):
        curve = sum(path_risks(noisy, path, setting, inputs[d:d + 1], targets[d:d + 1], nu, ell, auxes[path.method],
                               stop=None) for d in range(2)) / 2
        t = int(np.argmin(curve))
        assert new.method == lead.method and new.params == {**lead.params, "iterations": t + 1}
        assert new.risk == pytest.approx(curve[t] - 0.25, rel=1e-10)
        assert 1 <= t + 1 <= path.max_iterations


@pytest.mark.slow   # four searches of an opt-in path (~4 s); the default path is the default suite's
def test_the_chooser_repicks_under_the_race_winners_output(noisy, monkeypatch):
    """With the second pilot the chooser hands repick_counts the face normals of the race winner run on the
    noisy mesh (an independent run of the registry method); by default, with second_pilot=False or with
    blend_draws=0 it is not called."""
    import jaxmesh.tune.auto as auto

    seen = []

    def spy(mesh, leaders, paths, inputs, targets, nu, *rest, **kw):
        seen.append((leaders, np.asarray(nu)))
        return repick_counts(mesh, leaders, paths, inputs, targets, nu, *rest, **kw)

    monkeypatch.setattr(auto, "repick_counts", spy)
    cands = [Candidate("taubin", {"iterations": k}) for k in (1, 4, 12)] + [Candidate("guided_normal", {})]
    kw = dict(candidates=cands, paths=(SearchPath("taubin", ({"lam": 0.5, "mu": -0.53},), (), 20),), key=2,
              noise_model="normal")
    r = choose_denoiser(noisy, second_pilot=True, **kw)
    assert len(seen) == 1
    won = r.table[0]
    want = face_normals(METHODS[won.method](noisy, **won.params))
    np.testing.assert_allclose(seen[0][1], np.asarray(want), atol=1e-9)
    assert r.components and all(c.weight > 0 for c in r.components)
    for off in ({}, {"second_pilot": False}, {"blend_draws": 0, "second_pilot": True}):
        choose_denoiser(noisy, **kw, **off)
    assert len(seen) == 1
    with pytest.raises(ValueError, match="second_pilot must be True or False"):
        auto._check(noisy, cands, (), 2, 0.5, "auto", second_pilot=1)
