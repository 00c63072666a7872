"""Steps 2–4 of :mod:`jaxmesh.tune.tuner`'s search: a coarse grid in the bounded
coordinates, a parabola start with a per-coordinate preconditioner, and BFGS
(``optimistix``) with forward-mode gradients.  ``loss`` maps (g, p) coordinates
to (g,) relative losses; ``cfg`` carries ``coords``, ``grid``, ``max_steps``,
``rtol`` and ``atol``."""

from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp
from jaxtyping import Array

__all__ = ["Found", "search", "grid_axis", "parabola_start"]


class Found(NamedTuple):
    """What :func:`search` found, in the search coordinates u (p of them): the
    minimiser ``u`` (p,), whether BFGS ``converged``, its ``steps``, the coarse
    grid's points ``grid_u`` (G, p) and losses ``grid_loss`` (G,), and the BFGS
    iterates ``history_u`` (max_steps, p) with their losses ``history_loss`` (NaN
    past the last step)."""

    u: Array
    converged: Array
    steps: Array
    grid_u: Array
    grid_loss: Array
    history_u: Array
    history_loss: Array


def grid_axis(n: int, dtype):
    """The search grid of one coordinate: n cell midpoints t_k = (k + ½)/n in (0, 1)
    and their logits u_k = log t_k − log(1 − t_k) (the unbounded coordinate).

    Arguments:
        n: the grid size.
        dtype: the float dtype.

    Returns:
        (t (n,), u (n,))."""
    t = (jnp.arange(n, dtype=dtype) + 0.5) / n
    return t, jnp.log(t) - jnp.log1p(-t)


def parabola_start(values, t, p: int):
    """Per-coordinate parabola through the best grid point and its neighbours:
    (u₀ (p,), curvature h in u (p,)).  values has shape (n,)*p.

    The parabola is fitted to log E, not E: next to an unstable setting (a
    Taubin λ below |μ|) the loss grows by orders of magnitude from one grid
    point to the next, and a parabola in E then puts its vertex half a cell
    from the best point with a curvature 10⁴× too large, which stops BFGS at
    once.  In log E that growth is close to quadratic; at the vertex
    d²E/du² = E · d²(log E)/du², since the slope vanishes there.

    Arguments:
        values: the grid losses, (n,)*p (positive).
        t: the grid midpoints, (n,).
        p: the number of coordinates.

    Returns:
        (u₀ (p,), curvature h (p,))."""
    n = t.shape[0]
    best = jnp.unravel_index(jnp.argmin(values), values.shape)
    log_values = jnp.log(jnp.maximum(values, jnp.finfo(values.dtype).tiny))
    u0, curv = [], []
    for a in range(p):
        c = jnp.clip(best[a], 1, n - 2)
        idx = [best[b] for b in range(p)]
        e = []
        for k in (c - 1, c, c + 1):
            idx[a] = k
            e.append(log_values[tuple(idx)])
        e0, e1, e2 = e
        h = t[1] - t[0]
        second = e0 - 2 * e1 + e2
        convex = second > 0
        shift = 0.5 * h * (e0 - e2) / jnp.where(convex, second, 1)
        ts = jnp.where(convex, jnp.clip(t[c] + shift, t[c] - h, t[c] + h), t[best[a]])
        e_tt = jnp.where(convex, second / h**2, 0)
        delta = ts - t[c]
        vertex = jnp.exp(e1 + 0.5 * (e2 - e0) / h * delta + 0.5 * e_tt * delta**2)   # E at the vertex
        h_u = vertex * e_tt * (ts * (1 - ts)) ** 2       # d²E/du² at the vertex (E_t = 0 there)
        u0.append(jnp.log(ts) - jnp.log1p(-ts))
        curv.append(jnp.where(convex, jnp.clip(h_u, 1e-4, 1e4), 1.0))
    return jnp.stack(u0), jnp.stack(curv)


#: vertices × grid points evaluated at once by the coarse grid: a SURE evaluation keeps
#: the linearised flow, ~10 kB per vertex (8.5 GB for 6 points on the 134k-vertex igea)
_GRID_BATCH_VERTICES = 150_000


def search(loss, cfg, dtype, num_vertices: int):
    """Steps 2–4 of the module docstring.

    Arguments:
        loss: maps (g, p) coordinates to (g,) relative losses.
        cfg: the search configuration (``coords``, ``grid``, ``max_steps``, ``rtol``, ``atol``).
        dtype: the float dtype.
        num_vertices: V, which sizes the grid's batches.

    Returns:
        The :class:`Found` minimiser, grid and history."""
    p, n = len(cfg.coords), cfg.grid
    t, u_axis = grid_axis(n, dtype)
    mesh_u = jnp.stack(jnp.meshgrid(*([u_axis] * p), indexing="ij"), axis=-1).reshape(-1, p)
    batch = max(1, min(len(mesh_u), _GRID_BATCH_VERTICES // max(num_vertices, 1)))
    grid_loss = jax.lax.map(lambda u: loss(u[None])[0], mesh_u, batch_size=batch)
    u0, h = parabola_start(grid_loss.reshape((n,) * p), t, p)
    scale = jax.lax.rsqrt(h)

    def fn(y, _):
        f = loss(u0 + scale * y)
        return f, f

    import optimistix as optx     # here: the blind default and the named methods never load it

    solver = optx.BFGS(rtol=cfg.rtol, atol=cfg.atol)
    options = {"autodiff_mode": "fwd"}
    y0 = jnp.zeros(p, dtype)
    f_struct = jax.ShapeDtypeStruct((), dtype)
    state = solver.init(fn, y0, None, options, f_struct, f_struct, frozenset())
    steps = cfg.max_steps
    hist_y = jnp.full((steps, p), jnp.nan, dtype)
    hist_f = jnp.full((steps,), jnp.nan, dtype)

    def cond(carry):
        _, state, k, _, _ = carry
        done, _ = solver.terminate(fn, carry[0], None, options, state, frozenset())
        return (k < steps) & ~done

    def body(carry):
        y, state, k, hy, hf = carry
        y_new, state, aux = solver.step(fn, y, None, options, state, frozenset())
        # a step returns the loss of the iterate accepted before it (y): record that pair.
        # The first step only evaluates y0 and accepts it again, so step k fills slot k - 1.
        slot = jnp.maximum(k - 1, 0)
        return y_new, state, k + 1, hy.at[slot].set(y), hf.at[slot].set(aux)

    y, state, k, hist_y, hist_f = jax.lax.while_loop(cond, body, (y0, state, 0, hist_y, hist_f))
    done, result = solver.terminate(fn, y, None, options, state, frozenset())
    u = u0 + scale * y
    return Found(u, done & (result == optx.RESULTS.successful), k, mesh_u, grid_loss,
                 u0[None] + scale[None] * hist_y, hist_f)
