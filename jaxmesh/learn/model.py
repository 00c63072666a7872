"""A trainable denoiser: an unrolled stack of the registry's differentiable stages
whose parameters are set by two small networks.

The denoiser runs ``S`` stages on the noisy positions y.  Stage s, from the current
positions x:

1. ``smooth_iterations`` Taubin pairs x ← x + λ_s K x, x ← x + μ_s K x (K the umbrella
   operator, μ_s = −λ_s / (1 − 0.1 λ_s), the pass band k_PB = 0.1 of Taubin 1995);
   λ_s → 0 switches the smoothing off;
2. face normals n, areas, the spatial weights A_g W_s(f, g) with σ_s = σ_{s}·s̄ of the
   bilateral normal filter (:func:`~jaxmesh.denoise.bilateral_normal.spatial_weights`);
3. ``normal_iterations`` passes of the joint bilateral normal filter with the guidance
   g = normalize((1 − α_s) n + α_s ĝ), ĝ the guided filter's patch normals
   (:func:`~jaxmesh.denoise.guided.guidance_normals`) and the range width
   σ_r,f = σ_{r,s} · ρ_f per face;
4. ``vertex_iterations`` steps of the shared vertex update with tangential relaxation t_s.

With ``gated``, steps 2–4 move the smoothed positions x_T of step 1 only by a learned
step g_s ∈ (0, 1): x ← x_T + g_s (x_stage − x_T), so where feature-preserving filtering
does not pay (smooth scans under light noise) the stack can fall back to Taubin smoothing
alone.  With ``repair_rounds`` R > 0 an impulse-repair stage runs first,
y ← y + g_r (IR_α(y) − y), IR_α the registry's :func:`~jaxmesh.denoise.impulse_repair`
(R read-and-fit rounds with a learned thin-plate weight α), g_r ∈ (0, 1) a learned gate:
the robust refit impulsive noise needs, used as much as the mesh calls for.

The per-stage parameters θ_s = (log λ_s, log σ_s, log σ_r, logit α_s, logit t_s[, logit
g_s]) are θ̄_s + G(z), G a small MLP of the mesh's global roughness features z (three
medians, plus with ``tail_features`` two tail ratios; :func:`roughness_features`), so the
stack adapts to the noise level and the noise model without a search; the repair stage's
(logit g_r, log α) are r̄ + G(z) likewise.  The per-face factor ρ_f = exp(tanh(R(u_f)))
comes from a second MLP R of local features u_f (the face's normal deviation from its
ring, relative to the mesh's median deviation, and z).

Every step is a pure JAX function of the positions and of the networks' weights, so the
denoiser is jittable, batched over positions (vertices (*batch, V, 3)), and
differentiable in both; the guided patch choice is piecewise constant, as in
:mod:`jaxmesh.denoise.guided`.
"""

from __future__ import annotations

import dataclasses
import functools

import equinox as eqx
import jax
import jax.numpy as jnp
from jaxtyping import Array, Float

from .._exported import stored_jit
from .._private import dot, lift, one_program, safe_norm, safe_normalize
from ..denoise._loop import iterate
from ..denoise.bilateral_normal import joint_bilateral_normals, spatial_weights
from ..denoise.vertex_rings import ring_umbrella
from ..denoise.face_graph import FaceGraph, face_graph
from ..denoise.guided import guidance_normals
from ..denoise.impulse_repair import impulse_repair
from ..denoise.normal_filtering import ring_sum
from ..denoise.vertex_update import vertex_update
from ..geometry import face_areas, face_normals, mean_edge_length, vertex_normals
from ..mesh import Mesh, as_device_array
from ..operators import taubin_pair, umbrella

__all__ = ["ModelConfig", "LearnedDenoiser", "init_model", "roughness_features", "stage_parameters",
           "repair_parameters", "learned_denoising", "learned_program", "STAGE_PARAMETERS", "REPAIR_PARAMETERS",
           "REPAIR_ALPHA0"]

#: the per-stage parameters, in the order of :attr:`LearnedDenoiser.stage_base`'s columns
STAGE_PARAMETERS = ("log_lam", "log_sigma_s", "log_sigma_r", "logit_guidance", "logit_tangential")
#: the repair stage's parameters, in the order of :attr:`LearnedDenoiser.repair_base`
REPAIR_PARAMETERS = ("logit_repair", "log_alpha")
#: θ̄_s at initialisation: λ = 0.05, σ_s = 1, σ_r = 0.35, α = 0.5, t = 0.1 (the registry's
#: defaults), and with ``gated`` g_s = 0.95 (nearly the full normal filtering)
_INITIAL = (-3.0, 0.0, -1.05, 0.0, -2.2, 3.0)
#: r̄ at initialisation: g_r = 0.5, α = 0.3 (the registry's default)
_REPAIR_INITIAL = (0.0, -1.2)
#: the first impulse-repair fit's thin-plate weight α₀ (the registry's default)
REPAIR_ALPHA0 = 3.0


@dataclasses.dataclass(frozen=True)
class ModelConfig:
    """The static shape of a :class:`LearnedDenoiser`: ``stages`` S, the iteration counts
    of each stage, and the hidden width of both networks."""

    stages: int = 3
    smooth_iterations: int = 4
    normal_iterations: int = 6
    vertex_iterations: int = 10
    width: int = 16
    repair_rounds: int = 0
    gated: bool = False
    tail_features: bool = False

    def check(self) -> "ModelConfig":
        """Raise ``ValueError`` naming the field when a count is out of range (1–64, width
        1–256, repair_rounds 0–64) or a switch is not a bool."""
        for name in ("stages", "smooth_iterations", "normal_iterations", "vertex_iterations", "width",
                     "repair_rounds"):
            value = getattr(self, name)
            lo, top = (0 if name == "repair_rounds" else 1), (256 if name == "width" else 64)
            if isinstance(value, bool) or not isinstance(value, int) or not lo <= value <= top:
                raise ValueError(f"model {name} must be an int in [{lo}, {top}], got {value!r}")
        for name in ("gated", "tail_features"):
            if not isinstance(getattr(self, name), bool):
                raise ValueError(f"model {name} must be a bool, got {getattr(self, name)!r}")
        return self

    @property
    def features(self) -> int:
        """The number of global features z (:func:`roughness_features`)."""
        return 5 if self.tail_features else 3

    @property
    def stage_parameters(self) -> int:
        """The number of parameters of each stage (5, or 6 with ``gated``)."""
        return len(STAGE_PARAMETERS) + (1 if self.gated else 0)


class LearnedDenoiser(eqx.Module):
    """The trainable denoiser's weights (module docstring); ``config`` is static.

    ``stage_base``: θ̄, (S, P); ``stage_net``: G, global features → S·P (+ 2 with a repair
    stage) offsets; ``face_net``: R, per-face features → the log range factor;
    ``repair_base``: r̄, (2,), or None without a repair stage."""

    stage_base: Float[Array, "S P"]
    stage_net: eqx.nn.MLP
    face_net: eqx.nn.MLP
    repair_base: Float[Array, "2"] | None
    config: ModelConfig = eqx.field(static=True)


def init_model(config: ModelConfig = ModelConfig(), key=0) -> LearnedDenoiser:
    """A new denoiser: θ̄ at the registry's defaults, both networks' last layers at zero
    (so the initial stack is those defaults on every mesh).

    Arguments:
        config: the stack's shape.
        key: a ``jax.random`` key or an int seed for the hidden layers.

    Returns:
        The :class:`LearnedDenoiser`."""
    config.check()
    k = jax.random.PRNGKey(key) if isinstance(key, int) else key
    k1, k2 = jax.random.split(k)
    dtype = jnp.result_type(float)
    repair = config.repair_rounds > 0
    nparams = config.stages * config.stage_parameters + (len(REPAIR_PARAMETERS) if repair else 0)
    stage_net = eqx.nn.MLP(config.features, nparams, config.width, 1, activation=jnp.tanh, key=k1, dtype=dtype)
    face_net = eqx.nn.MLP(1 + config.features, 1, config.width, 1, activation=jnp.tanh, key=k2, dtype=dtype)

    def zero_last(net):
        last = net.layers[-1]
        return eqx.tree_at(lambda m: (m.layers[-1].weight, m.layers[-1].bias), net,
                           (jnp.zeros_like(last.weight), jnp.zeros_like(last.bias)))

    base = jnp.tile(jnp.asarray(_INITIAL[:config.stage_parameters], dtype), (config.stages, 1))
    repair_base = jnp.asarray(_REPAIR_INITIAL, dtype) if repair else None
    return LearnedDenoiser(base, zero_last(stage_net), zero_last(face_net), repair_base, config)


def _median(a: Float[Array, "*batch n"]) -> Float[Array, "*batch"]:
    return jnp.quantile(a, 0.5, axis=-1)


def _ring_deviation(mesh: Mesh, x: Float[Array, "*batch V 3"]) -> Float[Array, "*batch F"]:
    """‖n_f − normalize(Σ_{g∈N(f)} A_g n_g)‖: each face normal's deviation from its ring's mean."""
    geo = mesh.with_vertices(x)
    n, a = face_normals(geo), face_areas(geo)
    return safe_norm(n - safe_normalize(ring_sum(mesh, a[..., None] * n)))


def _tail(a: Float[Array, "*batch n"]) -> Float[Array, "*batch"]:
    """q₉₀ / q₅₀ of a non-negative sample: how heavy its upper tail is."""
    q = jnp.quantile(a, jnp.asarray([0.5, 0.9], a.dtype), axis=-1)
    return q[1] / (q[0] + 1e-9)


@one_program(static_argnames=("tails",))
def roughness_features(mesh: Mesh, x: Float[Array, "*batch V 3"], tails: bool = False
                       ) -> Float[Array, "*batch Z"]:
    """z = log of three medians of the noisy mesh: the face normals' deviation d_f from
    their rings' mean normal; |m_i · (K x)_i| / ℓ̄ (the umbrella vector along the vertex
    normal m_i); and ‖(K x)_i − (m_i · (K x)_i) m_i‖ / ℓ̄ (its part within the surface).
    With ``tails``, also log q₉₀/q₅₀ of |m_i · (K x)_i| and of d_f: heavy tails mark
    impulsive noise (a few vertices far out, the rest untouched) and sharp features.
    Scale- and rotation-invariant; the medians read the noise's amplitude and its
    tangential share.

    Arguments:
        mesh: the mesh (connectivity).
        x: its positions, (*batch, V, 3).
        tails: add the two tail ratios (Z = 5, else 3).

    Returns:
        z, (*batch, Z)."""
    geo = mesh.with_vertices(x)
    ell = mean_edge_length(geo)[..., None]
    k = umbrella(mesh, x)
    m = vertex_normals(geo, "area")
    normal_part = dot(k, m)
    along = jnp.abs(normal_part)
    across = safe_norm(k - normal_part[..., None] * m)
    dev = _ring_deviation(mesh, x)
    feats = [_median(dev), _median(along / ell), _median(across / ell)]
    if tails:
        feats += [_tail(along), _tail(dev)]
    return jnp.log(jnp.stack(feats, axis=-1) + 1e-6)


def _network_outputs(model: LearnedDenoiser, z: Float[Array, "*batch Z"]) -> Float[Array, "*batch N"]:
    net = model.stage_net
    for _ in range(z.ndim - 1):
        net = jax.vmap(net)
    return net(z)


def stage_parameters(model: LearnedDenoiser, z: Float[Array, "*batch Z"]) -> dict[str, Float[Array, "*batch S"]]:
    """The per-stage parameters θ_s = θ̄_s + G(z), mapped to their ranges: λ ∈ (0, 0.9),
    σ_s, σ_r > 0, α, t ∈ (0, 1) (t ≤ 0.5), and with ``gated`` the step g ∈ (0, 1).

    Arguments:
        model: the denoiser.
        z: the global features, (*batch, Z) (:func:`roughness_features`).

    Returns:
        ``{"lam", "sigma_s", "sigma_r", "guidance", "tangential"[, "step"]}``, each (*batch, S)."""
    s, p = model.config.stages, model.config.stage_parameters
    out = _network_outputs(model, z)[..., :s * p]
    theta = lift(model.stage_base, z.ndim + 1) + out.reshape(*z.shape[:-1], s, p)
    params = {"lam": 0.9 * jnp.minimum(jnp.exp(theta[..., 0]), 1.0),
              "sigma_s": jnp.exp(jnp.clip(theta[..., 1], -2.5, 2.5)),
              "sigma_r": jnp.exp(jnp.clip(theta[..., 2], -4.0, 1.5)),
              "guidance": jax.nn.sigmoid(theta[..., 3]),
              "tangential": 0.5 * jax.nn.sigmoid(theta[..., 4])}
    if model.config.gated:
        params["step"] = jax.nn.sigmoid(theta[..., 5])
    return params


def repair_parameters(model: LearnedDenoiser, z: Float[Array, "*batch Z"]) -> dict[str, Float[Array, "*batch"]]:
    """The repair stage's gate g_r = σ(r̄₀ + G(z)₀) ∈ (0, 1) and thin-plate weight
    α = exp(r̄₁ + G(z)₁) ∈ [0.01, 10].

    Arguments:
        model: a denoiser with ``repair_rounds`` > 0.
        z: the global features, (*batch, Z).

    Returns:
        ``{"gate", "alpha"}``, each (*batch,)."""
    if model.repair_base is None:
        raise ValueError("this model has no repair stage (repair_rounds = 0)")
    cfg = model.config
    r = lift(model.repair_base, z.ndim) + _network_outputs(model, z)[..., cfg.stages * cfg.stage_parameters:]
    return {"gate": jax.nn.sigmoid(r[..., 0]), "alpha": jnp.exp(jnp.clip(r[..., 1], -4.6, 2.3))}


def _face_factor(model: LearnedDenoiser, mesh: Mesh, x, z) -> Float[Array, "*batch F"]:
    """ρ_f = exp(tanh(R(u_f))), u_f = (log(d_f / median d), z), d the ring deviation."""
    d = _ring_deviation(mesh, x)
    rel = jnp.log((d + 1e-9) / (_median(d)[..., None] + 1e-9))
    u = jnp.concatenate([rel[..., None], jnp.broadcast_to(z[..., None, :], (*rel.shape, z.shape[-1]))], axis=-1)
    net = model.face_net
    for _ in range(u.ndim - 1):
        net = jax.vmap(net)
    return jnp.exp(jnp.tanh(net(u)[..., 0]))


def _stage(model: LearnedDenoiser, mesh: Mesh, graph: FaceGraph, x, z, theta: dict):
    """One stage (module docstring, steps 1–4) with one stage's parameters ``theta`` (each (*batch,))."""
    cfg = model.config
    lam = theta["lam"][..., None, None]
    mu = -lam / (1 - 0.1 * lam)
    x = iterate(lambda y: taubin_pair(y, lambda v: ring_umbrella(graph.vertex_rings, v), lam, mu), x,
                cfg.smooth_iterations)
    geo = mesh.with_vertices(x)
    w = spatial_weights(mesh, graph, x, theta["sigma_s"])
    areas = face_areas(geo)
    sigma_r = theta["sigma_r"][..., None] * _face_factor(model, mesh, x, z)
    alpha = theta["guidance"][..., None, None]

    def normal_pass(n):
        g = safe_normalize((1 - alpha) * n + alpha * guidance_normals(graph, n, areas))
        return joint_bilateral_normals(graph, n, g, w, sigma_r, per_face=True)

    n = iterate(normal_pass, face_normals(geo), cfg.normal_iterations)
    out = vertex_update(mesh, x, n, cfg.vertex_iterations, tangential=theta["tangential"], graph=graph)
    if not cfg.gated:
        return out
    return x + theta["step"][..., None, None] * (out - x)


def _repair(model: LearnedDenoiser, mesh: Mesh, x, z):
    """The gated impulse-repair stage y + g_r (IR_α(y) − y) (module docstring)."""
    r = repair_parameters(model, z)
    fixed = impulse_repair(mesh.with_vertices(x), r["alpha"], REPAIR_ALPHA0, model.config.repair_rounds).vertices
    return x + r["gate"][..., None, None] * (fixed - x)


def learned_denoising(mesh: Mesh, model: LearnedDenoiser, graph: FaceGraph | None = None) -> Mesh:
    """Denoise ``mesh`` with the learned stack (module docstring).

    Arguments:
        mesh: the noisy mesh (single, or with batched vertices (*batch, V, 3)).
        model: the trained weights (:func:`~jaxmesh.learn.load_model`, :func:`~jaxmesh.learn.train`).
        graph: the face graph from :func:`~jaxmesh.denoise.face_graph` (built from ``mesh``
            when None; pass it to call under ``jit``).

    Returns:
        The denoised mesh (same connectivity)."""
    graph = face_graph(mesh) if graph is None else graph
    x = mesh.vertices
    z = roughness_features(mesh, x, model.config.tail_features)
    if model.config.repair_rounds:
        x = _repair(model, mesh, x, z)
    # The stages share one traced body (a scan over the stage axis): one compile, not S.
    per_stage = jax.tree.map(lambda a: jnp.moveaxis(a, -1, 0), stage_parameters(model, z))
    x, _ = jax.lax.scan(lambda y, theta: (_stage(model, mesh, graph, y, z, theta), None), x, per_stage)
    return mesh.with_vertices(x)


def is_weight(x) -> bool:
    """An array leaf of a model, or its shape and dtype alone (a template from ``eqx.filter_eval_shape``)."""
    return eqx.is_array(x) or isinstance(x, jax.ShapeDtypeStruct)


def fill_weights(template, weights):
    """``template`` (a model, or any pytree) with its array leaves (:func:`is_weight`), in tree order,
    replaced by ``weights``."""
    flat, treedef = jax.tree_util.tree_flatten(template)
    it = iter(weights)
    return jax.tree_util.tree_unflatten(treedef, [as_device_array(next(it)) if is_weight(x) else x for x in flat])


@functools.lru_cache(maxsize=8)
def _skeleton(config: ModelConfig) -> tuple:
    """The leaves of the model of ``config`` (shapes for arrays: nothing drawn), and its tree."""
    leaves, treedef = jax.tree_util.tree_flatten(eqx.filter_eval_shape(init_model, config))
    return tuple(leaves), treedef


@stored_jit(static_argnames=("config",))
def _stored_vertices(mesh: Mesh, weights: list, graph: FaceGraph, config: ModelConfig):
    leaves, treedef = _skeleton(config)
    return learned_denoising(mesh, fill_weights(jax.tree_util.tree_unflatten(treedef, leaves), weights), graph).vertices


@eqx.filter_jit
def _any_vertices(mesh: Mesh, model: LearnedDenoiser, graph: FaceGraph):
    return learned_denoising(mesh, model, graph).vertices


def learned_program(mesh: Mesh, model: LearnedDenoiser, graph: FaceGraph) -> Mesh:
    """:func:`learned_denoising` as one compiled program kept for later calls, the weights and the
    face graph passed in (a new model of the same shape does not compile again; a model of its
    config's shape is also kept between processes, :mod:`jaxmesh._exported`): what an eager call
    runs (called op by op, the stack's scan would be traced and compiled again on every call).

    Arguments:
        mesh: the noisy mesh (concrete).
        model: the trained weights.
        graph: its face graph (:func:`~jaxmesh.denoise.face_graph`).

    Returns:
        The denoised mesh."""
    weights = [x for x in jax.tree_util.tree_leaves(model) if eqx.is_array(x)]
    leaves, treedef = _skeleton(model.config)
    if treedef == jax.tree_util.tree_structure(model) and [w.shape for w in weights] == [
            x.shape for x in leaves if isinstance(x, jax.ShapeDtypeStruct)]:
        return mesh.with_vertices(_stored_vertices(mesh, weights, graph, config=model.config))
    return mesh.with_vertices(_any_vertices(mesh, model, graph))
