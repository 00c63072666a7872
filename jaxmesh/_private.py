"""Small numerical helpers shared by the modules (not public API)."""

from __future__ import annotations

import dataclasses
import functools
import os
import sys

import jax
import jax.numpy as jnp
import jaxtyping
import numpy as np
from jaxtyping import Array, ArrayLike, Float, Int, Shaped

#: the folders of run-time annotation checkers' wrappers (jaxtyping's import hook, when it checks jaxmesh)
_CHECKERS = (os.path.dirname(os.path.abspath(jaxtyping.__file__)) + os.sep,)
#: frames in these folders are the library's: jaxmesh's own, and the checkers' wrappers of them
_LIBRARY = (os.path.dirname(os.path.abspath(__file__)) + os.sep, *_CHECKERS)

#: a continuous denoiser parameter: a number, or a float array (one value per batch element; traced under jit)
Scalar = Float[ArrayLike, "..."] | float | int


def one_program(fun=None, *, static_argnames: tuple[str, ...] = ()):
    """``fun`` with its body run as one jitted program: called eagerly, it compiles one
    XLA program per argument shapes and static values instead of one per primitive (each
    eager primitive is its own program, compiled per shape); under ``jit``, ``vmap`` or
    ``grad`` it is traced in place, as any jitted function.  Usable as a decorator, with or
    without ``static_argnames`` (the string options of a formula)."""
    if fun is None:
        return functools.partial(one_program, static_argnames=tuple(static_argnames))
    jitted = jax.jit(fun, static_argnames=tuple(static_argnames))

    @functools.wraps(fun)
    def run(*args, **kwargs):
        return jitted(*args, **kwargs)

    return run


def caller_stacklevel() -> int:
    """The ``stacklevel`` for a ``warnings.warn`` made by the function calling this one that
    names the first frame outside the library (jaxmesh, and jaxtyping's run-time checks): the
    user's line, however many library frames (a compiled call, a framed run) lie between."""
    frame, level = sys._getframe(1), 1
    while frame.f_code.co_filename.startswith(_CHECKERS):      # a checker's wrapper of this function
        frame = frame.f_back
    while frame is not None and frame.f_code.co_filename.startswith(_LIBRARY):
        frame, level = frame.f_back, level + 1
    return level


def segment_sum_rows(
    data: Shaped[Array, "*batch N d"], segment_ids: Int[Array, " N"], num_segments: int
) -> Shaped[Array, "*batch S d"]:
    """out[..., s, :] = sum over n with ids[n] == s of data[..., n, :]."""
    moved = jnp.moveaxis(data, -2, 0)
    out = jax.ops.segment_sum(moved, segment_ids, num_segments=num_segments)
    return jnp.moveaxis(out, 0, -2)


def slot_sum(term, slots, init: Array) -> Array:
    """init + Σ_k term(slots[k]), the k-th slice of every array of the pytree ``slots`` along its
    leading axis, as a ``lax.scan`` (one loop, whatever the slot count).

    The layout of the library's sums over padded neighbourhoods (each slot k a column of a
    padded table): one gather of rows per slot and an accumulation runs several times faster
    on XLA's CPU backend than a scatter-add or than gathering the whole table and reducing over
    its slots, and as a loop it compiles in a fraction of the time of the slots written out
    (``benchmarks/bench_ring_sums.py``)."""
    return jax.lax.scan(lambda total, slot: (total + term(slot), None), init, slots)[0]


def segment_sum_scalars(
    data: Shaped[Array, "*batch N"], segment_ids: Int[Array, " N"], num_segments: int
) -> Shaped[Array, "*batch S"]:
    """out[..., s] = sum over n with ids[n] == s of data[..., n]."""
    moved = jnp.moveaxis(data, -1, 0)
    out = jax.ops.segment_sum(moved, segment_ids, num_segments=num_segments)
    return jnp.moveaxis(out, 0, -1)


#: the longest last axis :func:`dot` writes out component by component
DOT_UNROLL = 4


def dot(a: Array, b: Array) -> Array:
    """Σ_c a[..., c] b[..., c] over the last axis (shapes broadcast as in ``a * b``).

    A last axis of at most :data:`DOT_UNROLL` components is written out, one
    product per component: XLA's CPU backend can run ``jnp.sum(a * b, axis=-1)``
    over a minor axis of 3 several times slower, most when one operand is a
    broadcast and in float32 (``benchmarks/bench_dot.py``).  Not always faster
    inside a larger fused loop: used where measured."""
    d = max(jnp.shape(a)[-1], jnp.shape(b)[-1])
    if d > DOT_UNROLL:
        return jnp.sum(a * b, axis=-1)
    return sum(a[..., min(c, jnp.shape(a)[-1] - 1)] * b[..., min(c, jnp.shape(b)[-1] - 1)] for c in range(d))


def safe_norm(x: Float[Array, "*batch d"], axis: int = -1) -> Float[Array, "*batch"]:
    """Euclidean norm whose gradient at the zero vector is 0 instead of NaN."""
    sq = jnp.sum(x * x, axis=axis)
    positive = sq > 0
    return jnp.where(positive, jnp.sqrt(jnp.where(positive, sq, 1)), 0)


def safe_normalize(x: Float[Array, "*batch d"], axis: int = -1) -> Float[Array, "*batch d"]:
    """x / ||x||, and the zero vector (with zero gradient) where ||x|| == 0."""
    n = safe_norm(x, axis=axis)
    n = jnp.expand_dims(n, axis)
    return jnp.where(n > 0, x / jnp.where(n > 0, n, 1), 0)


@one_program(static_argnames=("empty",))
def filled_mass(mass: Float[Array, "*batch V"], empty: float = 1.0) -> Float[Array, "*batch V"]:
    """The lumped mass of the vertices without area (isolated, or only on zero-area faces),
    the one rule of every mass matrix: m_i where m_i > 0, else the mean of the positive
    m_j of the same mesh (``empty`` where none is positive), so that M stays definite.  Such
    a vertex has no stiffness either: its row only keeps it where it is."""
    positive = mass > 0
    count = jnp.sum(positive, axis=-1, keepdims=True)
    mean = jnp.sum(jnp.where(positive, mass, 0), axis=-1, keepdims=True) / jnp.maximum(count, 1).astype(mass.dtype)
    return jnp.where(positive, mass, jnp.where(count > 0, mean, jnp.asarray(empty, mass.dtype)))


def lift(a: Array, ndim: int) -> Array:
    """``a`` with leading singleton axes so that it has ``ndim`` axes.

    The explicit form of NumPy's rank promotion: per-vertex data of shape (V, d)
    meets a batch (*batch, V, d) as ``lift(a, x.ndim)``.  The library writes its
    broadcasts this way, so it runs under ``jax_numpy_rank_promotion="raise"``
    (the test suite's setting)."""
    have = jnp.ndim(a)
    return jnp.reshape(a, (1,) * (ndim - have) + jnp.shape(a)) if have < ndim else a


def lift_all(*arrays: Array) -> tuple[Array, ...]:
    """Each array lifted (see :func:`lift`) to the largest rank among them."""
    ndim = max(jnp.ndim(a) for a in arrays)
    return tuple(lift(a, ndim) for a in arrays)


def safe_divide(num: Array, den: Array) -> Array:
    """num / den where den != 0, else 0 (double ``where``: no NaN in gradients).
    ``num`` and ``den`` of different ranks broadcast as NumPy would (leading axes)."""
    num, den = lift_all(num, den)
    ok = den != 0
    return jnp.where(ok, num / jnp.where(ok, den, 1), 0)


def det_adjugate_3x3(h: Float[Array, "... 3 3"]):
    """Closed-form determinant and adjugate of 3×3 matrices (inverse = adjugate / det)."""
    a, b, c = h[..., 0, 0], h[..., 0, 1], h[..., 0, 2]
    d, e, f = h[..., 1, 0], h[..., 1, 1], h[..., 1, 2]
    g, k, i = h[..., 2, 0], h[..., 2, 1], h[..., 2, 2]
    co = jnp.stack([
        jnp.stack([e * i - f * k, c * k - b * i, b * f - c * e], -1),
        jnp.stack([f * g - d * i, a * i - c * g, c * d - a * f], -1),
        jnp.stack([d * k - e * g, b * g - a * k, a * e - b * d], -1),
    ], -2)
    det = a * co[..., 0, 0] + b * co[..., 1, 0] + c * co[..., 2, 0]
    return det, co


#: stream tags of :func:`library_key`, one per use of randomness inside the library
PROBE_STREAM, RECORRUPTION_STREAM, PATCH_STREAM, HELD_OUT_STREAM = 1, 2, 3, 4


def x64_context(enabled: bool = True):
    """JAX's 64-bit setting, ``enabled``, for the duration of a ``with`` block, in this thread only
    (JAX >= 0.7 ``jax.enable_x64``, else the older ``jax.experimental`` contexts)."""
    enable = getattr(jax, "enable_x64", None)
    if enable is None:   # pragma: no cover - older JAX
        from jax.experimental import disable_x64, enable_x64
        return enable_x64() if enabled else disable_x64()
    return enable(enabled)


def library_key(key, stream: int, salt: int = 0):
    """The key the library draws its own randomness from (SURE probes,
    recorruptions), given the user's ``key`` (an int seed or a key): folded with
    ``stream`` so it never reproduces noise drawn with the same seed.  Without
    it the draws coincided: ``jax.random`` is prefix-consistent, so
    ``normal(PRNGKey(0), (2, V, 1))[0]`` *is* ``normal(PRNGKey(0), (V, 1))``
    (``add_noise(..., 0, along_normals=True)``'s draw), and
    ``rademacher(PRNGKey(0), s) == -sign(normal(PRNGKey(0), s))``: an estimator's
    own noise equal to the noise it estimates is no estimate.  A nonzero ``salt`` is folded in
    after the stream (an independent set of draws from the same stream)."""
    return _folded_key(key_argument(key), stream, salt)


@functools.partial(jax.jit, static_argnames=("stream", "salt"))
def _folded_key(key, stream: int, salt: int):
    k = jax.random.fold_in(seed_key(key), stream)
    return jax.random.fold_in(k, salt) if salt else k


def key_argument(key):
    """A ``jax.random`` key as it is; an int seed as an integer array for :func:`seed_key` to turn
    into ``jax.random.PRNGKey(seed)`` inside a program (made eagerly, the key costs programs of its
    own); a seed outside the integer type's range as ``PRNGKey(seed)`` itself."""
    if isinstance(key, int):
        seed = seed_array(key)
        return seed if seed is not None else jax.random.PRNGKey(key)
    return key


def seed_array(seed: int) -> np.ndarray | None:
    """The int ``seed`` as the integer array JAX's key functions make of it (int64 with 64-bit types
    on, else int32); None where it lies outside that type's range."""
    dtype = np.int64 if jax.config.jax_enable_x64 else np.int32
    info = np.iinfo(dtype)
    return np.asarray(seed, dtype) if info.min <= seed <= info.max else None


def seed_key(k):
    """``jax.random.PRNGKey`` of an int seed array (:func:`key_argument`); a key as it is."""
    if k.ndim == 0 and jnp.issubdtype(k.dtype, jnp.integer):
        return jax.random.PRNGKey(k)
    return k


def frozen_pytree(cls=None, *, static: tuple[str, ...] = ()):
    """Register the frozen dataclass ``cls`` as a JAX pytree: its fields are the children, in
    order, except those named in ``static``, which travel in the tree's (hashable) structure.
    Rebuilding it from children does not run ``__init__``, so any leaves will do (``vmap`` axes,
    ``ShapeDtypeStruct`` s, None), as for an ``equinox.Module``, without importing equinox.
    Usable as a decorator, with or without ``static``."""
    if cls is None:
        return functools.partial(frozen_pytree, static=tuple(static))
    names = tuple(f.name for f in dataclasses.fields(cls))
    children = tuple(n for n in names if n not in static)
    keys = tuple(jax.tree_util.GetAttrKey(n) for n in children)

    def flatten_with_keys(obj):
        return tuple(zip(keys, (getattr(obj, n) for n in children))), tuple(getattr(obj, n) for n in static)

    def flatten(obj):
        return tuple(getattr(obj, n) for n in children), tuple(getattr(obj, n) for n in static)

    def unflatten(aux, leaves):
        obj = object.__new__(cls)
        for name, value in (*zip(static, aux, strict=True), *zip(children, leaves, strict=True)):
            object.__setattr__(obj, name, value)
        return obj

    jax.tree_util.register_pytree_with_keys(cls, flatten_with_keys, unflatten, flatten_func=flatten)
    return cls
