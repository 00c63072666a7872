"""jaxmesh.learn: the learned denoiser's gradients against finite differences, jit against
eager, batches and vmap against a loop, model files (round trip, corrupt files), training's
determinism and resume after a kill, and the registry method."""

import json

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest
import trimesh

import jaxmesh
from jaxmesh.denoise import METHODS, denoise, face_graph, impulse_repair
from jaxmesh.learn import (DEFAULT_MODEL, REPAIR_ALPHA0, LearnedDenoiser, ModelConfig, NoiseRange, TrainConfig,
                           default_model, draw_noise, example, file_sha256, init_model, learned_denoising,
                           load_model, repair_parameters, roughness_features, save_model, stage_parameters, train,
                           training_loss)

SMALL = ModelConfig(stages=2, smooth_iterations=1, normal_iterations=2, vertex_iterations=2, width=4)
#: SMALL with every optional part: an impulse-repair stage, gated stages, tail features
FULL = ModelConfig(stages=2, smooth_iterations=1, normal_iterations=2, vertex_iterations=2, width=4,
                   repair_rounds=2, gated=True, tail_features=True)


@pytest.fixture(scope="module")
def sphere():
    s = trimesh.creation.icosphere(subdivisions=2)
    return jaxmesh.Mesh.from_arrays(s.vertices, s.faces, dtype=np.float64)


@pytest.fixture(scope="module")
def noisy(sphere):
    return jaxmesh.add_noise(sphere, 0.3, 3)


def _randomised(model: LearnedDenoiser, seed: int = 0) -> LearnedDenoiser:
    """``model`` with every weight drawn at random (small), so both networks matter."""
    leaves, treedef = jax.tree_util.tree_flatten(eqx.filter(model, eqx.is_array))
    keys = jax.random.split(jax.random.PRNGKey(seed), len(leaves))
    bases = {id(model.stage_base), id(model.repair_base)}
    new = [0.3 * jax.random.normal(k, leaf.shape, leaf.dtype) + (leaf if id(leaf) in bases else 0)
           for k, leaf in zip(keys, leaves)]
    return eqx.combine(jax.tree_util.tree_unflatten(treedef, new), model)


def test_initial_model_is_the_registry_defaults_on_every_mesh(sphere, noisy):
    model = init_model(SMALL, 1)
    z = roughness_features(sphere, noisy.vertices)
    theta = stage_parameters(model, z)
    np.testing.assert_allclose(theta["lam"], 0.9 * np.exp(-3.0))
    np.testing.assert_allclose(theta["sigma_s"], 1.0)
    np.testing.assert_allclose(theta["guidance"], 0.5)
    z2 = roughness_features(sphere, sphere.vertices)
    assert z.shape == (3,) and np.all(z > z2), "noise raises every roughness feature"


@pytest.mark.parametrize("tails", [False, True])
def test_features_are_scale_and_rotation_invariant(noisy, tails):
    z = roughness_features(noisy, noisy.vertices, tails)
    r = jnp.asarray(trimesh.transformations.rotation_matrix(0.7, [1, 2, 3])[:3, :3])
    np.testing.assert_allclose(roughness_features(noisy, 3.0 * noisy.vertices @ r.T, tails), z, atol=1e-9)


def test_tail_features_read_impulsive_noise(sphere, noisy):
    """The two tail ratios extend the three medians, and impulsive noise (a few vertices far
    out) has heavier tails than Gaussian noise on every vertex."""
    z3, z5 = roughness_features(sphere, noisy.vertices), roughness_features(sphere, noisy.vertices, True)
    assert z5.shape == (5,)
    np.testing.assert_allclose(z5[:3], z3, rtol=1e-12)
    spikes = jaxmesh.add_noise(sphere, 0.6, 3, along_normals=True, fraction=0.2)
    zi = roughness_features(sphere, spikes.vertices, True)
    assert np.all(zi[3:] > z5[3:] + 0.2), (zi, z5)


@pytest.mark.parametrize("config", [pytest.param(SMALL, id="plain"),   # every optional part on: -m slow (10 s)
                                    pytest.param(FULL, id="full", marks=pytest.mark.slow)])
def test_gradient_in_positions_and_parameters_matches_finite_differences(sphere, noisy, config):
    model = _randomised(init_model(config, 2))
    graph = face_graph(sphere)
    params, static = eqx.partition(model, eqx.is_array)
    loss = jax.jit(lambda p, y: training_loss(eqx.combine(p, static), sphere, y, graph, 1.0))
    y = noisy.vertices
    g_params, g_y = jax.grad(loss, argnums=(0, 1))(params, y)
    rng = np.random.default_rng(0)
    dy = jnp.asarray(rng.standard_normal(y.shape))
    eps = 1e-6
    fd = (loss(params, y + eps * dy) - loss(params, y - eps * dy)) / (2 * eps)
    np.testing.assert_allclose(jnp.sum(g_y * dy), fd, rtol=1e-4)
    leaves, treedef = jax.tree_util.tree_flatten(params)
    tangent = jax.tree_util.tree_unflatten(treedef, [jnp.asarray(rng.standard_normal(x.shape)) for x in leaves])
    shift = lambda s: jax.tree_util.tree_map(lambda p, t: p + s * t, params, tangent)  # noqa: E731
    fd = (loss(shift(eps), y) - loss(shift(-eps), y)) / (2 * eps)
    analytic = sum(jnp.sum(a * b) for a, b in zip(jax.tree_util.tree_leaves(g_params),
                                                  jax.tree_util.tree_leaves(tangent)))
    np.testing.assert_allclose(analytic, fd, rtol=1e-4)
    face_grad = jax.tree_util.tree_leaves(g_params.face_net)
    assert any(float(jnp.abs(x).max()) > 0 for x in face_grad), "the face net is used"


@pytest.mark.parametrize("config", [pytest.param(SMALL, id="plain"),   # every optional part on: -m slow (10 s)
                                    pytest.param(FULL, id="full", marks=pytest.mark.slow)])
def test_jit_equals_eager_and_vmap_equals_a_loop(sphere, config):
    model = _randomised(init_model(config, 3))
    graph = face_graph(sphere)
    ys = jnp.stack([jaxmesh.add_noise(sphere, s, k).vertices for s, k in ((0.2, 0), (0.5, 1))])
    run = lambda y: learned_denoising(sphere.with_vertices(y), model, graph).vertices  # noqa: E731
    jitted = jax.jit(run)
    np.testing.assert_allclose(jitted(ys[0]), run(ys[0]), rtol=1e-10, atol=1e-12)
    loop = [jitted(y) for y in ys]
    batched = jitted(ys)                                     # the batch axis through the library's own batching
    vmapped = jax.vmap(jitted)(ys)
    for i in range(2):
        np.testing.assert_allclose(batched[i], loop[i], rtol=1e-9, atol=1e-12)
        np.testing.assert_allclose(vmapped[i], loop[i], rtol=1e-9, atol=1e-12)


def test_model_file_round_trip_and_checkpoint(tmp_path):
    import optax

    model = _randomised(init_model(SMALL, 4))
    path = tmp_path / "m.jxl"
    save_model(path, model, {"seed": 4})
    back = load_model(path)
    assert back.config == SMALL
    for a, b in zip(jax.tree_util.tree_leaves(model), jax.tree_util.tree_leaves(back)):
        np.testing.assert_array_equal(a, b)
    with pytest.raises(FileExistsError):
        save_model(path, model)
    opt = optax.adam(0.1)
    state = opt.init(eqx.filter(model, eqx.is_array))
    save_model(path, model, {"step": 3}, extra=state, overwrite=True)
    m2, s2, meta = load_model(path, extra=state)
    assert meta == {"step": 3}
    assert int(s2[0].count) == 0 and jax.tree_util.tree_structure(s2) == jax.tree_util.tree_structure(state)


def _taubin_loop(faces: np.ndarray, x: np.ndarray, lams, pairs: int) -> np.ndarray:
    """Taubin's pairs x ← x + λ K x, x ← x + μ K x (μ = −λ / (1 − 0.1 λ)), K x the mean of
    the neighbours minus x, as a plain loop over the edges."""
    nbrs = [set() for _ in range(len(x))]
    for a, b, c in faces:
        nbrs[a] |= {b, c}
        nbrs[b] |= {a, c}
        nbrs[c] |= {a, b}
    umb = lambda y: np.array([y[sorted(n)].mean(0) - y[i] for i, n in enumerate(nbrs)])  # noqa: E731
    for lam in lams:
        mu = -lam / (1 - 0.1 * lam)
        for _ in range(pairs):
            x = x + lam * umb(x)
            x = x + mu * umb(x)
    return x


def test_gates_shut_give_taubin_alone_and_the_repair_gate_open_gives_the_repair(sphere):
    """With the stages' steps shut the stack is Taubin's pairs alone (a plain loop); with λ
    and every gate shut it returns its input; with the repair gate open and the rest shut it
    is the registry's impulse repair with the model's α, exactly."""
    model = _randomised(init_model(FULL, 6))
    graph = face_graph(sphere)
    spikes = jaxmesh.add_noise(sphere, 0.5, 4, along_normals=True, fraction=0.3)
    z = roughness_features(spikes, spikes.vertices, True)
    steps_shut = eqx.tree_at(lambda m: (m.stage_base, m.repair_base), model,
                             (model.stage_base.at[:, 5].set(-60.0), model.repair_base.at[0].set(-60.0)))
    lams = np.asarray(stage_parameters(steps_shut, z)["lam"])
    assert lams.min() > 1e-3
    want = _taubin_loop(np.asarray(sphere.faces), np.asarray(spikes.vertices), lams, FULL.smooth_iterations)
    np.testing.assert_allclose(learned_denoising(spikes, steps_shut, graph).vertices, want, atol=1e-12)
    shut = eqx.tree_at(lambda m: m.stage_base, steps_shut, steps_shut.stage_base.at[:, 0].set(-60.0))
    np.testing.assert_allclose(learned_denoising(spikes, shut, graph).vertices, spikes.vertices, atol=1e-12)
    opened = eqx.tree_at(lambda m: m.repair_base, shut, shut.repair_base.at[0].set(60.0))
    alpha = repair_parameters(opened, z)["alpha"]
    want = impulse_repair(spikes, alpha, REPAIR_ALPHA0, FULL.repair_rounds).vertices
    np.testing.assert_allclose(learned_denoising(spikes, opened, graph).vertices, want, atol=1e-12)
    assert float(jnp.max(jnp.abs(want - spikes.vertices))) > 0.05, "the repair moves the spikes"
    with pytest.raises(ValueError, match="no repair stage"):
        repair_parameters(init_model(SMALL), z)


def test_the_log_objective_is_the_log_of_the_loss(sphere, noisy):
    model = _randomised(init_model(SMALL, 9))
    graph = face_graph(sphere)
    plain = training_loss(model, sphere, noisy.vertices, graph, 1.0)
    np.testing.assert_allclose(training_loss(model, sphere, noisy.vertices, graph, 1.0, "log"), np.log(plain),
                               rtol=1e-12)
    with pytest.raises(ValueError, match="objective must be one of"):
        TrainConfig(objective="l2").check()


def test_a_file_without_the_optional_parts_loads_as_the_plain_stack(tmp_path):
    """A model file whose config predates the optional parts (no ``repair_rounds``,
    ``gated``, ``tail_features`` keys) is the plain stack, and the full model round-trips."""
    plain, full = _randomised(init_model(SMALL, 7)), _randomised(init_model(FULL, 8))
    path = tmp_path / "old.jxl"
    save_model(path, plain)
    head, rest = path.read_bytes().split(b"\n", 1)
    header = json.loads(head)
    for key in ("repair_rounds", "gated", "tail_features"):
        del header["config"][key]
    path.write_bytes(json.dumps(header).encode() + b"\n" + rest)
    back = load_model(path)
    assert back.config == SMALL and back.repair_base is None
    save_model(tmp_path / "full.jxl", full)
    again = load_model(tmp_path / "full.jxl")
    assert again.config == FULL
    for a, b in zip(jax.tree_util.tree_leaves(full), jax.tree_util.tree_leaves(again)):
        np.testing.assert_array_equal(a, b)
    for key, value, message in (("gated", 1, "gated must be a bool|not a jaxmesh model config"),
                                ("repair_rounds", -1, r"repair_rounds must be an int in \[0, 64\]")):
        bad = json.loads(head)
        bad["config"][key] = value
        path.write_bytes(json.dumps(bad).encode() + b"\n" + rest)
        with pytest.raises(ValueError, match=message):      # the check (or, under the suite's type
            load_model(path)                                # checking, the constructor) refuses it


@pytest.mark.parametrize("damage,message", [
    (lambda b: b"hello\n" + b, "not a jaxmesh model file"),
    (lambda b: b[: len(b) // 2], "missing or damaged"),
    (lambda b: b + b"x", "data after the last array"),
    (lambda b: b.replace(b'"stages": 2', b'"stages": 0'), "model stages must be an int"),
    (lambda b: b.replace(b'"stages": 2', b'"stages": 3'), "array .* has shape"),
    (lambda b: b.replace(b'"version": 1', b'"version": 9'), "model file version 9"),
])
def test_a_damaged_model_file_is_a_clear_error(tmp_path, damage, message):
    path = tmp_path / "m.jxl"
    save_model(path, init_model(SMALL))
    path.write_bytes(damage(path.read_bytes()))
    with pytest.raises(ValueError, match=message):
        load_model(path)


def test_non_finite_weights_are_refused(tmp_path):
    model = init_model(SMALL)
    model = eqx.tree_at(lambda m: m.stage_base, model, model.stage_base.at[0, 0].set(jnp.nan))
    save_model(tmp_path / "nan.jxl", model)
    with pytest.raises(ValueError, match="non-finite"):
        load_model(tmp_path / "nan.jxl")
    with pytest.raises(ValueError, match="cannot read model file"):
        default_model(tmp_path / "absent.jxl")


def test_noise_draws_respect_the_range_and_the_holdout(sphere):
    noise = NoiseRange(sigma=(0.1, 0.6), kinds=("normal",), weights=(1.0,), holdout=(0.2, 0.5))
    labels = [draw_noise(sphere, np.random.default_rng(i), noise)[1] for i in range(40)]
    sigmas = [float(s.split()[1]) for s in labels]
    assert all(0.095 <= s <= 0.605 and not 0.205 <= s <= 0.495 for s in sigmas), sigmas   # labels: 2 decimals
    with pytest.raises(ValueError, match="holdout"):
        NoiseRange(sigma=(0.1, 0.6), holdout=(0.05, 0.9)).check()
    with pytest.raises(ValueError, match="noise kinds"):
        NoiseRange(kinds=("salt",), weights=(1.0,)).check()
    with pytest.raises(ValueError, match="steps must be a positive int"):
        TrainConfig(steps=0).check()


def test_example_refuses_a_noisy_copy_of_other_connectivity(sphere):
    other = trimesh.creation.icosphere(subdivisions=1)
    with pytest.raises(ValueError, match="ball: the noisy mesh does not have the clean mesh's connectivity"):
        example("ball", sphere, jaxmesh.Mesh.from_arrays(other.vertices, other.faces))


@pytest.mark.slow   # 10 s: compiles the training step for three mesh sizes; the CLI's refusals run by default
def test_training_lowers_the_loss_and_resumes_after_a_kill_exactly(sphere, tmp_path):
    """Four steps straight, and two steps killed then resumed from the checkpoint: the same
    weights and history (each step's data depend on (seed, step) only)."""
    s = trimesh.creation.icosphere(subdivisions=1)
    small = jaxmesh.Mesh.from_arrays(s.vertices * 2, s.faces, dtype=np.float64)
    examples = [example("sphere", sphere), example("small", small)]
    val = [example("val", jaxmesh.Mesh.from_arrays(s.vertices, s.faces, dtype=np.float64))]
    config = TrainConfig(steps=4, batch=2, validate_every=2, checkpoint_every=2, model=SMALL, learning_rate=0.05)
    straight = train(examples, val, config)

    class Killed(Exception):
        pass

    def kill(step, loss, record):
        if step == 2:
            raise Killed

    ckpt = tmp_path / "ckpt.jxl"
    with pytest.raises(Killed):
        train(examples, val, config, checkpoint=ckpt, report=kill)
    assert json.loads(ckpt.read_bytes().split(b"\n", 1)[0])["meta"]["step"] == 2
    resumed = train(examples, val, config, checkpoint=ckpt)
    assert resumed.history == straight.history and len(straight.history) == 2
    assert resumed.best_step == straight.best_step
    for a, b in zip(jax.tree_util.tree_leaves(straight.model), jax.tree_util.tree_leaves(resumed.model)):
        np.testing.assert_array_equal(a, b)
    changed = TrainConfig(steps=4, batch=2, validate_every=2, checkpoint_every=2, model=SMALL, seed=1)
    with pytest.raises(ValueError, match="written with other settings"):
        train(examples, val, changed, checkpoint=ckpt)
    with pytest.raises(ValueError, match="both the training and the validation set"):
        train(examples, examples[:1], config)


def test_the_registry_method_runs_a_model_file_and_refuses_a_bad_one(sphere, noisy, tmp_path):
    model = _randomised(init_model(SMALL, 5))
    path = tmp_path / "m.jxl"
    save_model(path, model)
    graph = face_graph(sphere)
    want = learned_denoising(noisy, model, graph).vertices
    got = denoise(noisy, "learned", model=str(path), graph=graph).vertices
    np.testing.assert_allclose(got, want, rtol=1e-12)
    # an eager call runs one kept program (the weights passed in, not baked in): another model of
    # the same shape gives its own result, and the graph built when not given changes nothing
    other, other_path = _randomised(init_model(SMALL, 6), seed=1), tmp_path / "other.jxl"
    save_model(other_path, other)
    np.testing.assert_allclose(denoise(noisy, "learned", model=str(other_path)).vertices,
                               learned_denoising(noisy, other, graph).vertices, rtol=1e-12)
    np.testing.assert_allclose(denoise(noisy, "learned", model=str(path)).vertices, want, rtol=1e-12)
    assert METHODS["learned"].params["model"].kind == "file"
    with pytest.raises(ValueError, match="model must be a file path"):
        denoise(noisy, "learned", model=3)
    with pytest.raises(ValueError, match="cannot read model file"):
        denoise(noisy, "learned", model=str(tmp_path / "none.jxl"))


def test_the_shipped_model_matches_its_record():
    """The packaged model file loads and has the SHA-256 its training record names."""
    record = json.loads(DEFAULT_MODEL.with_suffix(".json").read_text())
    assert file_sha256(DEFAULT_MODEL) == record["sha256"]
    model = default_model()
    assert isinstance(model, LearnedDenoiser) and record["seed"] == 0
    names = {n.split(" ")[0] for n, _ in record["training_meshes"]}
    assert not names & set(record["evaluation_meshes"]) and not names & set(record["validation_meshes"])


@pytest.mark.slow   # ~4 s of compiles; the registry test above runs the same program by default
def test_the_kept_program_is_stored_and_a_fresh_process_loads_it(sphere, noisy, tmp_path):
    """learned_program keeps a model of its config's shape between processes (jaxmesh._exported): the
    program's key is the config, not the weights, so one stored program serves two models (each
    with its own result), and a fresh wrapper (a new process) loads it and gives the same result."""
    from jaxmesh import _exported
    from jaxmesh.learn.model import _stored_vertices, learned_program

    graph = face_graph(sphere)
    models = [_randomised(init_model(SMALL, 7), seed=s) for s in (0, 1)]
    _exported.set_store(tmp_path / "exported")
    try:
        got = [learned_program(noisy, m, graph).vertices for m in models]
        assert len(list((tmp_path / "exported").iterdir())) == 1
        _stored_vertices._calls.clear()                       # as a new process finds it
        again = learned_program(noisy, models[0], graph).vertices
    finally:
        _exported.set_store(None)
    np.testing.assert_allclose(got[0], learned_denoising(noisy, models[0], graph).vertices, rtol=1e-12)
    np.testing.assert_array_equal(again, got[0])
    assert float(jnp.abs(got[0] - got[1]).max()) > 1e-6
