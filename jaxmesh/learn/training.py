"""Training a :class:`~jaxmesh.learn.LearnedDenoiser` end to end with optax.

**Loss.**  For a clean mesh u and its noisy copy y, with x = D_θ(y) the denoiser's output,

    L(θ) = mean-normal-angle(u, x) [degrees] + w · RMS(x − u) / ℓ̄(u),

(``position_weight`` = w), averaged over a batch of different meshes (one gradient per
mesh, summed: each mesh compiles its own program once).  With ``objective="log"`` each
example's loss is log L(θ): a relative error, so a light-noise draw whose error is 2°
weighs as much as a heavy one at 10°.  Adam with the gradient's global norm clipped to 1;
the step size decays from ``learning_rate`` to 5% of it on a cosine over the run
(``schedule="cosine"``) or stays constant.

**Noise.**  With no noisy copy given, each step draws one per mesh from :class:`NoiseRange`:
the noise model (isotropic Gaussian, Gaussian along the normals, impulsive) and σ
(log-uniform in ℓ̄) from a NumPy generator seeded by ``(seed, step)``, so a step's data
depend on the seed and the step alone.  Real noisy/clean pairs (same connectivity) are
used as they are.

**Validation** runs every ``validate_every`` steps on fixed draws over the validation
meshes (σ = 0.1, 0.3, 0.5ℓ̄ isotropic and along the normals, and impulsive p = 0.5,
σ = 0.5ℓ̄), or on their given noisy copies; the figure is the mean normal error in degrees.
With ``keep_best`` the model returned is the one of the validation with the least error
(early stopping on the validation meshes, never on evaluation data).

**Checkpoints.**  Every ``checkpoint_every`` steps, the model, the optimiser state, the
best model so far and the history go to the checkpoint file (atomically); :func:`train` with ``resume=True``
continues from it.  The step's data depend on (seed, step) only and XLA on CPU is
deterministic, so a resumed run ends where an uninterrupted one would.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import NamedTuple

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float

from ..denoise.face_graph import FaceGraph, face_graph
from ..geometry import mean_edge_length
from ..mesh import Mesh
from ..metrics import mean_normal_angle_error, rms_vertex_error
from ..noise import add_noise
from .model import LearnedDenoiser, ModelConfig, init_model, learned_denoising
from .modelfile import load_model, save_model

__all__ = ["NoiseRange", "TrainConfig", "OBJECTIVES", "Example", "example", "draw_noise", "validation_draws",
           "training_loss", "TrainResult", "train"]

NOISE_KINDS = ("isotropic", "normal", "impulsive")
#: the training objectives: L(θ), or log L(θ) (module docstring)
OBJECTIVES = ("angle", "log")


@dataclasses.dataclass(frozen=True)
class NoiseRange:
    """The synthetic noise drawn for training: ``kinds`` with probabilities ``weights``;
    Gaussian σ log-uniform in ``sigma`` (ℓ̄), redrawn while it falls in ``holdout`` (a band
    kept out of training to measure how the model generalises); impulsive σ uniform in
    ``impulsive_sigma`` and the displaced fraction p uniform in ``fraction``."""

    sigma: tuple[float, float] = (0.05, 0.8)
    kinds: tuple[str, ...] = NOISE_KINDS
    weights: tuple[float, ...] = (0.4, 0.4, 0.2)
    impulsive_sigma: tuple[float, float] = (0.3, 0.7)
    fraction: tuple[float, float] = (0.3, 0.6)
    holdout: tuple[float, float] | None = None

    def check(self) -> "NoiseRange":
        """Raise ``ValueError`` naming the field that is out of range."""
        if not set(self.kinds) <= set(NOISE_KINDS) or len(self.kinds) != len(self.weights) or not self.kinds:
            raise ValueError(f"noise kinds must be a non-empty subset of {NOISE_KINDS}, one weight each")
        if min(self.weights) < 0 or sum(self.weights) <= 0:
            raise ValueError(f"noise weights must be >= 0 with a positive sum, got {self.weights}")
        for name in ("sigma", "impulsive_sigma", "fraction"):
            lo, hi = getattr(self, name)
            top = 1.0 if name == "fraction" else 10.0
            if not 0 < lo <= hi <= top:
                raise ValueError(f"noise {name} must be an interval 0 < lo <= hi <= {top:g}, got {(lo, hi)}")
        if self.holdout is not None:
            lo, hi = self.holdout
            if not (lo < hi and (lo > self.sigma[0] or hi < self.sigma[1])):
                raise ValueError(f"noise holdout {self.holdout} must be an interval leaving part of {self.sigma}")
        return self


@dataclasses.dataclass(frozen=True)
class TrainConfig:
    """Training's settings (module docstring); ``model`` is the stack's shape."""

    steps: int = 300
    batch: int = 4
    learning_rate: float = 0.02
    position_weight: float = 1.0
    seed: int = 0
    schedule: str = "cosine"
    objective: str = "angle"
    keep_best: bool = True
    validate_every: int = 25
    checkpoint_every: int = 25
    noise: NoiseRange = NoiseRange()
    model: ModelConfig = ModelConfig()

    def check(self) -> "TrainConfig":
        """Raise ``ValueError`` naming the setting that is out of range."""
        for name in ("steps", "batch", "validate_every", "checkpoint_every"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int) or v < 1:
                raise ValueError(f"{name} must be a positive int, got {v!r}")
        if not (math.isfinite(self.learning_rate) and self.learning_rate > 0):
            raise ValueError(f"learning_rate must be > 0, got {self.learning_rate}")
        if not (math.isfinite(self.position_weight) and self.position_weight >= 0):
            raise ValueError(f"position_weight must be >= 0, got {self.position_weight}")
        if self.schedule not in ("cosine", "constant"):
            raise ValueError(f"schedule must be 'cosine' or 'constant', got {self.schedule!r}")
        if self.objective not in OBJECTIVES:
            raise ValueError(f"objective must be one of {OBJECTIVES}, got {self.objective!r}")
        self.noise.check()
        self.model.check()
        return self


class Example(NamedTuple):
    """One training or validation mesh: ``clean``, its ``noisy`` copy (None: synthetic
    noise), its face ``graph`` and a ``name`` for messages."""

    name: str
    clean: Mesh
    noisy: Mesh | None
    graph: FaceGraph


def example(name: str, clean: Mesh, noisy: Mesh | None = None) -> Example:
    """An :class:`Example`, its face graph built once (``noisy`` must share ``clean``'s connectivity).

    Arguments:
        name: shown in errors and progress.
        clean: the clean mesh.
        noisy: a real noisy copy with the same connectivity, or None for synthetic noise.

    Returns:
        The :class:`Example`."""
    if noisy is not None and not clean.same_connectivity(noisy):
        raise ValueError(f"{name}: the noisy mesh does not have the clean mesh's connectivity "
                         f"({noisy.num_vertices} vertices / {noisy.num_faces} faces against "
                         f"{clean.num_vertices} / {clean.num_faces}, or different faces)")
    return Example(name, clean, noisy, face_graph(clean))


def draw_noise(mesh: Mesh, rng: np.random.Generator, noise: NoiseRange = NoiseRange()) -> tuple[Mesh, str]:
    """One noisy copy of ``mesh`` drawn from ``noise`` with ``rng`` (module docstring).

    Arguments:
        mesh: the clean mesh.
        rng: the generator (its draws pick the model, σ, p and the key).
        noise: the ranges.

    Returns:
        (the noisy mesh, a label such as ``"normal 0.31"``)."""
    p = np.asarray(noise.weights, float)
    kind = noise.kinds[int(rng.choice(len(noise.kinds), p=p / p.sum()))]
    key = jax.random.PRNGKey(int(rng.integers(2 ** 31)))
    if kind == "impulsive":
        sigma, frac = float(rng.uniform(*noise.impulsive_sigma)), float(rng.uniform(*noise.fraction))
        return add_noise(mesh, sigma, key, along_normals=True, fraction=frac), f"impulsive {sigma:.2f} p={frac:.2f}"
    lo, hi = np.log(noise.sigma)
    sigma = float(np.exp(rng.uniform(lo, hi)))
    while noise.holdout is not None and noise.holdout[0] <= sigma <= noise.holdout[1]:
        sigma = float(np.exp(rng.uniform(lo, hi)))
    return add_noise(mesh, sigma, key, along_normals=kind == "normal"), f"{kind} {sigma:.2f}"


def validation_draws(ex: Example, seed: int) -> list[tuple[str, Mesh]]:
    """The fixed noisy copies of a validation mesh (module docstring): its given noisy copy,
    or seven synthetic ones keyed by ``seed``.

    Arguments:
        ex: the validation example.
        seed: the training seed.

    Returns:
        [(label, noisy mesh)]."""
    if ex.noisy is not None:
        return [("given", ex.noisy)]
    out = []
    for i, (kind, sigma) in enumerate([(k, s) for k in ("isotropic", "normal") for s in (0.1, 0.3, 0.5)]):
        out.append((f"{kind} {sigma}", add_noise(ex.clean, sigma, jax.random.PRNGKey(1000 * seed + i),
                                                 along_normals=kind == "normal")))
    out.append(("impulsive 0.5", add_noise(ex.clean, 0.5, jax.random.PRNGKey(1000 * seed + 99),
                                           along_normals=True, fraction=0.5)))
    return out


def training_loss(model: LearnedDenoiser, clean: Mesh, noisy: Float[Array, "V 3"], graph: FaceGraph,
                  position_weight: float, objective: str = "angle") -> jax.Array:
    """L(θ), or log L(θ) with ``objective="log"``, for one mesh (module docstring).

    Arguments:
        model: the denoiser.
        clean: the clean mesh.
        noisy: the noisy positions, (V, 3).
        graph: the clean mesh's face graph.
        position_weight: w.
        objective: ``"angle"`` or ``"log"``.

    Returns:
        The scalar loss."""
    out = learned_denoising(clean.with_vertices(noisy), model, graph).vertices
    angle = mean_normal_angle_error(clean, out)
    loss = angle + position_weight * rms_vertex_error(clean, out) / mean_edge_length(clean)
    return jnp.log(loss) if objective == "log" else loss



@eqx.filter_jit
def _loss_and_grad(model, clean, noisy, graph, position_weight, objective):
    return eqx.filter_value_and_grad(training_loss)(model, clean, noisy, graph, position_weight, objective)


@eqx.filter_jit
def _validation_error(model, clean, noisy, graph):
    return mean_normal_angle_error(clean, learned_denoising(clean.with_vertices(noisy), model, graph).vertices)


def _validate(model, draws) -> float:
    return float(np.mean([float(_validation_error(model, ex.clean, noisy.vertices, ex.graph))
                          for ex, noisy in draws]))


class TrainResult(NamedTuple):
    """``model``: the trained weights (with ``keep_best``, those of the validation with the
    least error); ``history``: one ``{"step", "loss", "validation"}`` per validation (loss:
    the mean training loss since the previous one); ``best_step``: the step ``model`` is from."""

    model: LearnedDenoiser
    history: list[dict]
    best_step: int


def _optimizer(config: TrainConfig):
    import optax

    rate = (optax.cosine_decay_schedule(config.learning_rate, config.steps, alpha=0.05)
            if config.schedule == "cosine" else config.learning_rate)
    return optax.chain(optax.clip_by_global_norm(1.0), optax.adam(rate))


def _resume(checkpoint: Path, state: dict, config: TrainConfig) -> dict:
    """The training state saved in ``checkpoint`` when a run of the same config wrote it,
    else ``state`` (the fresh one)."""
    if not checkpoint.exists():
        return state
    model, (opt_state, best), meta = load_model(checkpoint, extra=(state["opt_state"], _arrays_of(state["best"])))
    if meta.get("train_config") != repr(config):
        raise ValueError(f"checkpoint {checkpoint} was written with other settings; remove it or change "
                         f"the output name (it has {meta.get('train_config')})")
    return {"model": model, "opt_state": opt_state, "best": eqx.combine(best, state["best"]),
            "step": int(meta["step"]), "history": list(meta["history"]), "best_step": int(meta["best_step"]),
            "best_validation": meta["best_validation"]}


def _arrays_of(model):
    return eqx.filter(model, eqx.is_array)


def train(examples: Sequence[Example], validation: Sequence[Example], config: TrainConfig = TrainConfig(),
          checkpoint: str | Path | None = None, resume: bool = True,
          report: Callable[[int, float, dict | None], None] | None = None) -> TrainResult:
    """Train a :class:`~jaxmesh.learn.LearnedDenoiser` (module docstring).

    Arguments:
        examples: the training meshes (:func:`example`).
        validation: the validation meshes (none of them also in ``examples``).
        config: the settings.
        checkpoint: a file for checkpoints (None: none are written).
        resume: continue from ``checkpoint`` when it exists.
        report: called as ``report(step, loss, record)`` after each step (``record``: the
            history entry when the step validated, else None), e.g. a progress bar.

    Returns:
        The :class:`TrainResult`."""
    config.check()
    if not examples:
        raise ValueError("no training meshes")
    shared = {id(ex.clean) for ex in examples} & {id(ex.clean) for ex in validation}
    if shared:
        raise ValueError("a mesh is in both the training and the validation set")
    opt = _optimizer(config)
    model = init_model(config.model, config.seed)
    st = {"model": model, "opt_state": opt.init(_arrays_of(model)), "best": model, "step": 0, "history": [],
          "best_step": 0, "best_validation": None}
    ckpt = None if checkpoint is None else Path(checkpoint)
    if ckpt is not None and resume:
        st = _resume(ckpt, st, config)
    draws = [(ex, noisy) for ex in validation for _, noisy in validation_draws(ex, config.seed)]
    losses = []
    while st["step"] < config.steps:
        st["model"], st["opt_state"], loss = _step(st["model"], st["opt_state"], opt, examples, config, st["step"])
        losses.append(loss)
        st["step"] += 1
        step, record = st["step"], None
        if step % config.validate_every == 0 or step == config.steps:
            v = _validate(st["model"], draws) if draws else None
            record = {"step": step, "loss": float(np.mean(losses)), "validation": v}
            st["history"].append(record)
            losses = []
            if not config.keep_best or v is None or st["best_validation"] is None or v < st["best_validation"]:
                st["best"], st["best_step"], st["best_validation"] = st["model"], step, v
        if ckpt is not None and (step % config.checkpoint_every == 0 or step == config.steps):
            meta = {"step": step, "history": st["history"], "train_config": repr(config),
                    "best_step": st["best_step"], "best_validation": st["best_validation"]}
            save_model(ckpt, st["model"], meta, extra=(st["opt_state"], _arrays_of(st["best"])), overwrite=True)
        if report is not None:
            report(step, loss, record)
    return TrainResult(st["best"], st["history"], st["best_step"])


def _step(model, opt_state, opt, examples, config: TrainConfig, step: int):
    """One optimiser step on a batch drawn with the generator seeded by (seed, step)."""
    rng = np.random.default_rng([config.seed, step])
    picks = rng.choice(len(examples), size=min(config.batch, len(examples)), replace=False)
    total, grads = 0.0, None
    for i in sorted(int(p) for p in picks):
        ex = examples[i]
        noisy = ex.noisy if ex.noisy is not None else draw_noise(ex.clean, rng, config.noise)[0]
        loss, g = _loss_and_grad(model, ex.clean, noisy.vertices, ex.graph, config.position_weight, config.objective)
        total += float(loss)
        grads = g if grads is None else jax.tree_util.tree_map(jnp.add, grads, g)
    grads = jax.tree_util.tree_map(lambda a: a / len(picks), grads)
    model, opt_state = _apply(opt, grads, opt_state, model)
    return model, opt_state, total / len(picks)


@eqx.filter_jit
def _apply(opt, grads, opt_state, model):
    """The optimiser's update applied (optax mixes its int32 step count with floats, which
    JAX's strict dtype promotion refuses: standard promotion here)."""
    with jax.numpy_dtype_promotion("standard"):
        updates, opt_state = opt.update(eqx.filter(grads, eqx.is_array), opt_state, eqx.filter(model, eqx.is_array))
    return eqx.apply_updates(model, updates), opt_state
