"""Pins, regions and the boundary (jaxmesh.denoise.selection, denoise(where=), --pin/--region):
pinned vertices stay bit for bit, a region's outside stays, the weights against hop counts from
scipy's breadth-first search, gradients against finite differences, jit and vmap."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
import scipy.sparse as sp
from scipy.sparse.csgraph import shortest_path

import jaxmesh
from jaxmesh.cli import main
from jaxmesh.denoise import METHODS, denoise, hold, pin_weights, region_weights
from jaxmesh.geodesics import boundary_vertices
from conftest import grid_arrays


@pytest.fixture(scope="module")
def noisy_grid():
    v, f = grid_arrays(8, 7, jitter=0.0)
    v[:, 2] = 0.1 * np.random.default_rng(3).standard_normal(len(v))
    return jaxmesh.Mesh.from_arrays(v, f)


def test_region_weights_fall_off_with_the_hop_count(noisy_grid):
    m = noisy_grid
    e = np.asarray(m.edges)
    graph = sp.coo_matrix((np.ones(len(e)), (e[:, 0], e[:, 1])), (m.num_vertices,) * 2)
    selected = np.array([0, 40, 41])
    hops = shortest_path(graph, directed=False, unweighted=True, indices=selected).min(axis=0)
    for transition in (0, 1, 3):
        expect = np.maximum(0.0, 1 - hops / (transition + 1))
        np.testing.assert_allclose(region_weights(m, selected, transition), expect, atol=1e-15)
    mask = np.zeros(m.num_vertices, bool)
    mask[selected] = True
    np.testing.assert_array_equal(region_weights(m, mask, 2), region_weights(m, selected, 2))
    np.testing.assert_array_equal(pin_weights(m, selected), ~mask)


def test_bad_selections_are_refused(noisy_grid):
    with pytest.raises(ValueError, match="vertex index 72 is out of range for a mesh of 72 vertices"):
        region_weights(noisy_grid, [72])
    with pytest.raises(ValueError, match="vertex indices must be integers"):
        pin_weights(noisy_grid, [0.5])
    with pytest.raises(ValueError, match="needs shape \\(72,\\)"):
        region_weights(noisy_grid, np.ones(5, bool))
    with pytest.raises(ValueError, match="transition must be an int >= 0"):
        region_weights(noisy_grid, [0], -1)
    with pytest.raises(ValueError, match="one weight per vertex"):
        denoise(noisy_grid, "taubin", where=np.ones(3))


@pytest.mark.parametrize("name", ["taubin", "guided_normal"])
def test_pinned_vertices_stay_bit_for_bit_and_a_region_outside_too(noisy_grid, name):
    m, y = noisy_grid, np.asarray(noisy_grid.vertices)
    pinned = np.asarray(boundary_vertices(m))
    out = np.asarray(denoise(m, name, where=pin_weights(m, pinned)).vertices)
    free = np.asarray(denoise(m, name).vertices)
    np.testing.assert_array_equal(out[pinned], y[pinned])
    np.testing.assert_allclose(out[~pinned], free[~pinned], rtol=0, atol=1e-15)
    w = np.asarray(region_weights(m, [30, 31], transition=1))
    out = np.asarray(denoise(m, name, where=w).vertices)
    np.testing.assert_array_equal(out[w == 0], y[w == 0])
    np.testing.assert_allclose(out, y + w[:, None] * (free - y), atol=1e-15)
    assert np.abs(out[w == 1] - y[w == 1]).max() > 1e-3


def test_gradients_through_the_weights_and_parameters_match_finite_differences(noisy_grid):
    m = noisy_grid
    w0 = region_weights(m, [30, 31], transition=2)

    def loss(w, lam):
        return jnp.sum(denoise(m, "taubin", where=w, lam=lam, iterations=3).vertices[:, 2] ** 2)

    gw, glam = jax.grad(loss, argnums=(0, 1))(w0, 0.5)
    rng = np.random.default_rng(0)
    for _ in range(3):
        d = jnp.asarray(rng.standard_normal(m.num_vertices))
        fd = (loss(w0 + 1e-6 * d, 0.5) - loss(w0 - 1e-6 * d, 0.5)) / 2e-6
        np.testing.assert_allclose(jnp.dot(gw, d), fd, rtol=1e-6)
    fd = (loss(w0, 0.5 + 1e-6) - loss(w0, 0.5 - 1e-6)) / 2e-6
    np.testing.assert_allclose(glam, fd, rtol=1e-6)


def test_where_under_jit_and_vmap_equals_eager_and_a_loop(noisy_grid):
    m = noisy_grid
    ws = jnp.stack([region_weights(m, [k], 1) for k in (10, 30, 50)])
    run = jax.jit(lambda w: denoise(m, "taubin", where=w).vertices)
    batched = jax.vmap(run)(ws)
    for w, b in zip(ws, batched):
        eager = denoise(m, "taubin", where=w).vertices
        np.testing.assert_allclose(run(w), eager, atol=1e-15)
        np.testing.assert_allclose(b, eager, atol=1e-15)
    stacked = m.with_vertices(jnp.stack([m.vertices] * 3))
    out = hold(stacked, denoise(stacked, "taubin"), ws)
    np.testing.assert_allclose(out.vertices[1], denoise(m, "taubin", where=ws[1]).vertices, atol=1e-15)


@pytest.mark.slow       # one compile per method
@pytest.mark.parametrize("name", sorted(METHODS))
def test_every_method_keeps_pinned_vertices_in_place(noisy_grid, name):
    m, y = noisy_grid, np.asarray(noisy_grid.vertices)
    pinned = np.zeros(m.num_vertices, bool)
    pinned[::5] = True
    out = np.asarray(denoise(m, name, where=pin_weights(m, pinned)).vertices)
    np.testing.assert_array_equal(out[pinned], y[pinned])
    assert not np.allclose(out[~pinned], y[~pinned])


def _ply_with_property(path, mesh, selected):
    v, f = np.asarray(mesh.vertices), np.asarray(mesh.faces)
    head = (f"ply\nformat ascii 1.0\nelement vertex {len(v)}\nproperty double x\nproperty double y\n"
            f"property double z\nproperty uchar chosen\nelement face {len(f)}\n"
            "property list uchar int vertex_indices\nend_header\n")
    body = "".join(f"{a!r} {b!r} {c!r} {int(s)}\n" for (a, b, c), s in zip(v.tolist(), selected))
    path.write_text(head + body + "".join(f"3 {a} {b} {c}\n" for a, b, c in f.tolist()))


def test_the_cli_pins_and_selects_regions(tmp_path, capsys, noisy_grid):
    m = noisy_grid
    src, pins = tmp_path / "in.ply", tmp_path / "pins.txt"
    jaxmesh.save(m, src)
    y = np.asarray(jaxmesh.load(src).vertices)
    pins.write_text("0, 5\n17 33\n")
    args = ["--method", "taubin", "--iterations", "4"]
    assert main(["denoise", str(src), str(tmp_path / "a.ply"), "--pin", str(pins), "--pin", "boundary", *args]) == 0
    out = np.asarray(jaxmesh.load(tmp_path / "a.ply").vertices)
    held = np.asarray(boundary_vertices(m)) | np.isin(np.arange(m.num_vertices), [0, 5, 17, 33])
    np.testing.assert_array_equal(out[held], y[held])
    assert np.abs(out[~held] - y[~held]).max() > 1e-3
    chosen = np.isin(np.arange(m.num_vertices), [30, 31, 38])
    _ply_with_property(tmp_path / "sel.ply", m, chosen)
    assert main(["denoise", str(tmp_path / "sel.ply"), str(tmp_path / "b.ply"), "--region", "chosen",
                 "--transition", "1", *args]) == 0
    out = np.asarray(jaxmesh.load(tmp_path / "b.ply").vertices)
    outside = np.asarray(region_weights(m, chosen, 1)) == 0
    np.testing.assert_array_equal(out[outside], y[outside])
    assert np.abs(out[chosen] - y[chosen]).max() > 1e-3
    capsys.readouterr()
    pins.write_text("3 99\n")
    assert main(["denoise", str(src), str(tmp_path / "c.ply"), "--pin", str(pins), *args]) == 1
    assert "vertex index 99 is out of range for a mesh of 72 vertices" in capsys.readouterr().err
    assert main(["denoise", str(src), str(tmp_path / "c.ply"), "--region", "nothing", *args]) == 1
    assert "nothing: no such file, and not a vertex property" in capsys.readouterr().err
    assert main(["denoise", "--out-dir", str(tmp_path / "d"), str(src), "--pin", "boundary", *args]) == 1
    assert "do not combine with --out-dir" in capsys.readouterr().err
