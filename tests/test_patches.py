"""The patch search of the blind chooser (jaxmesh.tune.patches and choose_denoiser(search_vertices=...))."""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np
import pytest
import scipy.sparse.csgraph as csgraph
import trimesh

import jaxmesh
from jaxmesh.geometry import face_normals, mean_edge_length, vertex_normals
from jaxmesh.graph import adjacency_from_faces, metis_labels
from jaxmesh.metrics import mean_normal_angle_error
from jaxmesh.tune import Candidate, choose_denoiser
from jaxmesh.tune.patches import sample_patches
from jaxmesh.tune.recorrupt import recorruptions


@pytest.fixture(scope="module")
def ball():
    s = trimesh.creation.icosphere(5)                       # 10242 vertices
    return jaxmesh.Mesh.from_arrays(s.vertices, s.faces).astype(jnp.float64)


def test_the_patches_are_hop_balls_with_their_margin(ball):
    """Each core is a hop ball of at least its share of vertices around its centre; the region adds exactly
    `margin` rings (checked with an independent BFS); core faces have three core vertices; the submesh keeps
    the positions; the centres lie one in each METIS part; the same seed gives the same patches, another
    seed other centres."""
    p = sample_patches(ball, vertices=800, count=4, margin=2)
    assert len(p.seeds) == 4
    adj = adjacency_from_faces(np.asarray(ball.faces), ball.num_vertices)
    d = csgraph.shortest_path(adj, unweighted=True, indices=p.seeds)            # (4, V)
    np.testing.assert_array_equal(np.asarray(p.mesh.vertices), np.asarray(ball.vertices)[p.vertices])
    radii = [np.sort(row)[199] for row in d]                                     # 200 core vertices each
    core = np.any(d <= np.asarray(radii)[:, None], axis=0)
    region = np.any(d <= np.asarray(radii)[:, None] + 2, axis=0)
    np.testing.assert_array_equal(np.sort(p.vertices), np.flatnonzero(region))
    faces = np.asarray(p.mesh.faces)
    np.testing.assert_array_equal(p.core_faces, core[p.vertices][faces].all(axis=1))
    assert 800 <= core.sum() < 1200
    degree = np.asarray(ball.degree)
    labels = metis_labels(np.concatenate([[0], np.cumsum(degree)]), np.asarray(ball.dst), 4)
    assert sorted(labels[p.seeds]) == [0, 1, 2, 3]
    again = sample_patches(ball, vertices=800, count=4, margin=2)
    np.testing.assert_array_equal(again.vertices, p.vertices)
    other = sample_patches(ball, vertices=800, count=4, margin=2, seed=1)
    assert not np.array_equal(np.sort(other.seeds), np.sort(p.seeds))


def test_the_rim_is_where_the_patches_meet_the_rest(ball):
    """The rim is the region's vertices with a whole-mesh edge leaving the region (a plain loop over the
    edges); on a closed mesh these are exactly the search mesh's boundary-edge vertices."""
    p = sample_patches(ball, vertices=800, count=4, margin=2)
    region = np.zeros(ball.num_vertices, bool)
    region[p.vertices] = True
    want = np.zeros(ball.num_vertices, bool)
    for a, b in np.asarray(ball.faces)[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2):
        want[a] |= region[a] and not region[b]
        want[b] |= region[b] and not region[a]
    np.testing.assert_array_equal(p.rim, want[p.vertices])
    faces = np.asarray(p.mesh.faces)
    edges, uses = np.unique(np.sort(faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1), axis=0, return_counts=True)
    on_edge = np.zeros(p.mesh.num_vertices, bool)
    on_edge[edges[uses == 1].ravel()] = True
    has_face = np.bincount(faces.ravel(), minlength=p.mesh.num_vertices) > 0
    np.testing.assert_array_equal(p.rim[has_face], on_edge[has_face])
    assert 0 < p.rim.sum() < p.mesh.num_vertices / 4 and not (p.rim & ~has_face).any()


def test_the_chooser_holds_the_rim_on_patches_only(ball, monkeypatch):
    """choose_denoiser hands the race the patches' rim with the pilot's positions (guided filtering of
    the search mesh), nothing with pin_rim=False or on the whole mesh."""
    import jaxmesh.tune.auto as auto
    from jaxmesh.host import HostMesh
    from jaxmesh.tune.race import run_setting

    class Stop(Exception):
        pass

    drawn, pins = [], []

    def spy_patches(*args, **kwargs):
        drawn.append(sample_patches(*args, **kwargs))
        return drawn[-1]

    def spy_race(*args):
        pins.append(args[-1])
        raise Stop

    monkeypatch.setattr(auto, "sample_patches", spy_patches)
    monkeypatch.setattr(auto, "race", spy_race)
    s = trimesh.creation.icosphere(4)                       # 2562 vertices, 32 patches of 3 core vertices
    noisy = jaxmesh.add_noise(jaxmesh.Mesh.from_arrays(s.vertices, s.faces).astype(jnp.float64), 0.3, 0)
    for kw in ({}, {"pin_rim": False}, {"search_vertices": None}):
        with pytest.raises(Stop):
            choose_denoiser(noisy, **{"search_vertices": 100, "sigma": 0.001, "noise_model": "normal", **kw})
    assert len(drawn) == 2 and pins[1:] == [None, None]
    patches = drawn[0]
    mask, positions = pins[0]                                # on the patches padded to the ladder
    v = patches.mesh.num_vertices
    np.testing.assert_array_equal(np.asarray(mask)[:v], patches.rim)
    assert not np.asarray(mask)[v:].any()
    pilot = run_setting(patches.mesh, patches.mesh.vertices, "guided_normal", {},
                        HostMesh(patches.mesh).aux("guided_normal"))
    np.testing.assert_allclose(np.asarray(positions)[:v], np.asarray(pilot), atol=1e-12)


def test_the_centres_are_uniform_within_their_parts(ball):
    """Over many seeds each part's centre is drawn uniformly: the mean hop distance from the centres
    to their part's vertices matches the part's mean pairwise hop distance (what a uniform draw
    gives), not the smaller distance from its deepest vertex."""
    degree = np.asarray(ball.degree)
    labels = metis_labels(np.concatenate([[0], np.cumsum(degree)]), np.asarray(ball.dst), 2)
    adj = adjacency_from_faces(np.asarray(ball.faces), ball.num_vertices)
    part = np.flatnonzero(labels == 0)
    centres = [next(s for s in sample_patches(ball, 20, count=2, margin=0, seed=k).seeds if labels[s] == 0)
               for k in range(40)]
    drawn = csgraph.shortest_path(adj, unweighted=True, indices=centres)[:, part].mean()
    rng = np.random.default_rng(5)
    uniform = csgraph.shortest_path(adj, unweighted=True, indices=rng.choice(part, 200))[:, part].mean()
    assert drawn == pytest.approx(uniform, rel=0.1)


def test_sample_patches_refuses_bad_arguments(ball):
    for args, message in (((0,), "vertices must be an int >= 1"), ((100, 0), "count must be an int >= 1"),
                          ((100, 2, -1), "margin must be an int >= 0"), ((100, 2, 1, -1), "seed must be an int >= 0")):
        with pytest.raises(ValueError, match=message):
            sample_patches(ball, *args)
    with pytest.raises(ValueError, match="search_vertices must be None or an int >= 32"):
        choose_denoiser(ball, search_vertices=3)


def test_a_zero_normal_row_takes_the_face_out_of_the_trace(ball):
    """recorruptions' trace with some rows of ν zeroed is the unmasked per-face trace summed over the kept
    faces only (an independent per-face numpy sum), divided by F."""
    nu, n = face_normals(ball), vertex_normals(ball, "area")
    ell = mean_edge_length(ball)
    keep = np.arange(ball.num_faces) % 3 != 0
    s = np.linspace(0.5, 1.5, ball.num_vertices) * 0.01
    _, trace = recorruptions(ball, nu * jnp.asarray(keep, nu.dtype)[:, None], n, ell, s, 0.004, 1, 0)
    f = np.asarray(ball.faces)
    dots = np.sum(np.asarray(nu)[:, None, :] * np.asarray(n)[f], axis=-1) ** 2
    var = 0.004**2 + (s[f] ** 2 - 0.004**2) * dots
    per_face = (var[:, [1, 2, 0]] + var[:, [2, 0, 1]]).sum(axis=1) / float(ell) ** 2
    assert trace == pytest.approx(per_face[keep].sum() / ball.num_faces, rel=1e-10)


@pytest.mark.slow   # two whole searches (~6 s)
def test_ranking_on_patches_finds_the_choice_of_the_whole_mesh(ball, monkeypatch):
    """Taubin at 0, 10, 40 iterations on a noisy sphere: ranked on 8 patches of the sphere (a third of it)
    the order is the whole mesh's, doing nothing's risk is per counted face (the whole mesh's), and the
    winner runs on the whole mesh.  (The candidates' own estimates are far noisier on the patches: fewer
    faces average the recorruption's noise.)"""
    noisy = jaxmesh.add_noise(ball, 0.3, 0)
    cands = [Candidate("taubin", {"iterations": k}) for k in (1, 10, 40)]
    kw = dict(candidates=cands, paths=(), blend_draws=0, sigma=0.3 * float(mean_edge_length(ball)))
    import jaxmesh.tune.auto as auto

    flags, counts = [], []

    def spy(*args, **kwargs):
        flags.append(kwargs["antithetic"])
        counts.append(args[6])
        return recorruptions(*args, **kwargs)

    monkeypatch.setattr(auto, "recorruptions", spy)
    whole = choose_denoiser(noisy, search_vertices=None, **kw)
    part = choose_denoiser(noisy, search_vertices=1600, **kw)
    paired = choose_denoiser(noisy, search_vertices=1600, antithetic=True, draws=3, **kw)
    assert flags == [False, False, True]   # independent draws unless asked
    assert counts == [2, 2, 3] == [whole.draws, part.draws, paired.draws] == [
        whole.summary()["draws"], part.summary()["draws"], paired.summary()["draws"]]
    assert [r[1] for r in paired.table] == [r[1] for r in whole.table]
    assert whole.search_vertices == ball.num_vertices and part.search_vertices < ball.num_vertices / 2
    assert [r[1] for r in part.table] == [r[1] for r in whole.table]
    assert part.noisy_risk == pytest.approx(whole.noisy_risk, rel=0.05)
    assert part.mesh.num_vertices == ball.num_vertices
    np.testing.assert_allclose(np.asarray(part.mesh.vertices), np.asarray(whole.mesh.vertices))
    assert part.summary()["search_vertices"] == part.search_vertices
    assert float(mean_normal_angle_error(ball, part.mesh)) < float(mean_normal_angle_error(ball, noisy))
