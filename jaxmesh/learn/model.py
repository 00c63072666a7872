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

The per-stage parameters θ_s = (log λ_s, log σ_s, log σ_r, logit α_s, logit t_s) are
θ̄_s + G(z), G a small MLP of the mesh's global roughness features z (three medians,
:func:`roughness_features`), so the stack adapts to the noise level and the noise
model without a search.  The per-face factor ρ_f = exp(tanh(R(u_f))) comes from a second
MLP R of local features u_f (the face's normal deviation from its ring, relative to the
mesh's median deviation, and z).

Every step is a pure JAX function of the positions and of the networks' weights, so the
denoiser is jittable, batched over positions (vertices (*batch, V, 3)), and
differentiable in both; the guided patch choice is piecewise constant, as in
:mod:`jaxmesh.denoise.guided`.
"""

from __future__ import annotations

import dataclasses

import equinox as eqx
import jax
import jax.numpy as jnp
from jaxtyping import Array, Float

from .._private import dot, lift, safe_norm, safe_normalize
from ..denoise._loop import iterate
from ..denoise.bilateral_normal import joint_bilateral_normals, spatial_weights
from ..denoise.face_graph import FaceGraph, face_graph
from ..denoise.guided import guidance_normals
from ..denoise.normal_filtering import ring_sum
from ..denoise.vertex_update import vertex_update
from ..geometry import face_areas, face_normals, mean_edge_length, vertex_normals
from ..mesh import Mesh
from ..operators import taubin_pair, umbrella

__all__ = ["ModelConfig", "LearnedDenoiser", "init_model", "roughness_features", "stage_parameters",
           "learned_denoising", "STAGE_PARAMETERS"]

#: the per-stage parameters, in the order of :attr:`LearnedDenoiser.stage_base`'s columns
STAGE_PARAMETERS = ("log_lam", "log_sigma_s", "log_sigma_r", "logit_guidance", "logit_tangential")
#: θ̄_s at initialisation: λ = 0.05, σ_s = 1, σ_r = 0.35, α = 0.5, t = 0.1 (the registry's defaults)
_INITIAL = (-3.0, 0.0, -1.05, 0.0, -2.2)
_FEATURES = 3
_FACE_FEATURES = 1 + _FEATURES


@dataclasses.dataclass(frozen=True)
class ModelConfig:
    """The static shape of a :class:`LearnedDenoiser`: ``stages`` S, the iteration counts
    of each stage, and the hidden width of both networks."""

    stages: int = 3
    smooth_iterations: int = 4
    normal_iterations: int = 6
    vertex_iterations: int = 10
    width: int = 16

    def check(self) -> "ModelConfig":
        """Raise ``ValueError`` naming the field when a count is out of range (1–64, width 1–256)."""
        for name in ("stages", "smooth_iterations", "normal_iterations", "vertex_iterations", "width"):
            value = getattr(self, name)
            top = 256 if name == "width" else 64
            if isinstance(value, bool) or not isinstance(value, int) or not 1 <= value <= top:
                raise ValueError(f"model {name} must be an int in [1, {top}], got {value!r}")
        return self


class LearnedDenoiser(eqx.Module):
    """The trainable denoiser's weights (module docstring); ``config`` is static.

    ``stage_base``: θ̄, (S, 5); ``stage_net``: G, global features → (S·5) offsets;
    ``face_net``: R, per-face features → the log range factor."""

    stage_base: Float[Array, "S P"]
    stage_net: eqx.nn.MLP
    face_net: eqx.nn.MLP
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
    nparams = config.stages * len(STAGE_PARAMETERS)
    stage_net = eqx.nn.MLP(_FEATURES, nparams, config.width, 1, activation=jnp.tanh, key=k1, dtype=dtype)
    face_net = eqx.nn.MLP(_FACE_FEATURES, 1, config.width, 1, activation=jnp.tanh, key=k2, dtype=dtype)

    def zero_last(net):
        last = net.layers[-1]
        return eqx.tree_at(lambda m: (m.layers[-1].weight, m.layers[-1].bias), net,
                           (jnp.zeros_like(last.weight), jnp.zeros_like(last.bias)))

    base = jnp.tile(jnp.asarray(_INITIAL, dtype), (config.stages, 1))
    return LearnedDenoiser(base, zero_last(stage_net), zero_last(face_net), config)


def _median(a: Float[Array, "*batch n"]) -> Float[Array, "*batch"]:
    return jnp.quantile(a, 0.5, axis=-1)


def _ring_deviation(mesh: Mesh, x: Float[Array, "*batch V 3"]) -> Float[Array, "*batch F"]:
    """‖n_f − normalize(Σ_{g∈N(f)} A_g n_g)‖: each face normal's deviation from its ring's mean."""
    geo = mesh.with_vertices(x)
    n, a = face_normals(geo), face_areas(geo)
    return safe_norm(n - safe_normalize(ring_sum(mesh, a[..., None] * n)))


def roughness_features(mesh: Mesh, x: Float[Array, "*batch V 3"]) -> Float[Array, "*batch 3"]:
    """z = log of three medians of the noisy mesh: the face normals' deviation from their
    rings' mean normal; |m_i · (K x)_i| / ℓ̄ (the umbrella vector along the vertex normal
    m_i); and ‖(K x)_i − (m_i · (K x)_i) m_i‖ / ℓ̄ (its part within the surface).  Scale-
    and rotation-invariant; the last two read the noise's amplitude and its tangential share.

    Arguments:
        mesh: the mesh (connectivity).
        x: its positions, (*batch, V, 3).

    Returns:
        z, (*batch, 3)."""
    geo = mesh.with_vertices(x)
    ell = mean_edge_length(geo)[..., None]
    k = umbrella(mesh, x)
    m = vertex_normals(geo, "area")
    along = dot(k, m)
    across = safe_norm(k - along[..., None] * m)
    feats = [_median(_ring_deviation(mesh, x)), _median(jnp.abs(along) / ell), _median(across / ell)]
    return jnp.log(jnp.stack(feats, axis=-1) + 1e-6)


def stage_parameters(model: LearnedDenoiser, z: Float[Array, "*batch 3"]) -> dict[str, Float[Array, "*batch S"]]:
    """The per-stage parameters θ_s = θ̄_s + G(z), mapped to their ranges: λ ∈ (0, 0.9),
    σ_s, σ_r > 0, α, t ∈ (0, 1) (t ≤ 0.5).

    Arguments:
        model: the denoiser.
        z: the global features, (*batch, 3) (:func:`roughness_features`).

    Returns:
        ``{"lam", "sigma_s", "sigma_r", "guidance", "tangential"}``, each (*batch, S)."""
    s, p = model.config.stages, len(STAGE_PARAMETERS)
    net = model.stage_net
    for _ in range(z.ndim - 1):
        net = jax.vmap(net)
    theta = lift(model.stage_base, z.ndim + 1) + net(z).reshape(*z.shape[:-1], s, p)
    return {"lam": 0.9 * jnp.minimum(jnp.exp(theta[..., 0]), 1.0),
            "sigma_s": jnp.exp(jnp.clip(theta[..., 1], -2.5, 2.5)),
            "sigma_r": jnp.exp(jnp.clip(theta[..., 2], -4.0, 1.5)),
            "guidance": jax.nn.sigmoid(theta[..., 3]),
            "tangential": 0.5 * jax.nn.sigmoid(theta[..., 4])}


def _face_factor(model: LearnedDenoiser, mesh: Mesh, x, z) -> Float[Array, "*batch F"]:
    """ρ_f = exp(tanh(R(u_f))), u_f = (log(d_f / median d), z), d the ring deviation."""
    d = _ring_deviation(mesh, x)
    rel = jnp.log((d + 1e-9) / (_median(d)[..., None] + 1e-9))
    u = jnp.concatenate([rel[..., None], jnp.broadcast_to(z[..., None, :], (*rel.shape, z.shape[-1]))], axis=-1)
    net = model.face_net
    for _ in range(u.ndim - 1):
        net = jax.vmap(net)
    return jnp.exp(jnp.tanh(net(u)[..., 0]))


def _stage(model: LearnedDenoiser, mesh: Mesh, graph: FaceGraph, x, z, theta: dict, s: int):
    """One stage (module docstring, steps 1–4) with the parameters of stage ``s``."""
    cfg = model.config
    lam = theta["lam"][..., s, None, None]
    mu = -lam / (1 - 0.1 * lam)
    x = iterate(lambda y: taubin_pair(y, lambda v: umbrella(mesh, v), lam, mu), x, cfg.smooth_iterations)
    geo = mesh.with_vertices(x)
    w = spatial_weights(mesh, graph, x, theta["sigma_s"][..., s])
    areas = face_areas(geo)
    sigma_r = theta["sigma_r"][..., s, None] * _face_factor(model, mesh, x, z)
    alpha = theta["guidance"][..., s, None, None]

    def normal_pass(n):
        g = safe_normalize((1 - alpha) * n + alpha * guidance_normals(graph, n, areas))
        return joint_bilateral_normals(graph, n, g, w, sigma_r, per_face=True)

    n = iterate(normal_pass, face_normals(geo), cfg.normal_iterations)
    return vertex_update(mesh, x, n, cfg.vertex_iterations, tangential=theta["tangential"][..., s])


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
    z = roughness_features(mesh, x)
    theta = stage_parameters(model, z)
    for s in range(model.config.stages):
        x = _stage(model, mesh, graph, x, z, theta, s)
    return mesh.with_vertices(x)
