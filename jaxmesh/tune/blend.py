"""Blending denoisers, with the weights chosen blind (aggregation).

Where two denoisers err differently, the average of their outputs can beat
both.  Choosing weights by an unbiased estimate of the risk is Blu & Luisier's
SURE-LET (2007); here the estimate is :mod:`jaxmesh.tune.auto`'s recorrupted
edge-tilt risk, which needs no derivative of either denoiser.

**The weight.**  For two denoisers f_i, f_j and one recorruption (ŷ, ỹ), let
T_i = A(f_i(ŷ) − ỹ) (the edge tilts of :func:`~jaxmesh.tune.edge_tilt`).  The
blend f_w = w f_i + (1 − w) f_j is a denoiser too, and A is linear, so its
recorrupted estimate is the quadratic

    R(w) = ‖T_j + w (T_i − T_j)‖² / F − c,    minimised at
    w* = clip(−⟨T_i − T_j, T_j⟩ / ‖T_i − T_j‖², 0, 1),

summed over the draws (c, the noise constant, is the same for every
denoiser).  The convex constraint keeps the blend between its two parents.

**The choice.**  The weight is fitted on ``BLEND_DRAWS`` recorruptions drawn
afresh (independent of those that ranked the candidates, so a lucky ranking
draw does not carry over), for every pair of *leaders* (the best setting of
each search path and of each method among the fixed candidates), and the
blend is kept only when its estimate on those draws is below the single
winner's by at least ``BLEND_MIN_GAIN`` (1%) of the winner's estimated risk: the
estimates carry biases of that order, so a smaller gain is not one the estimate can
see.  Under impulsive noise, where the chooser ranks by the held-out estimate
(:mod:`jaxmesh.tune.heldout`), nothing is blended: there the blends' estimated gains
(0.1–13% of the winner's risk) did not predict their true effect (from 4.4% less error
to 10.5% more, the largest gains among the worst; the denoising guide).  The estimate tracks
the mean *squared* tilt, so a blend may trade a few large angle errors for many
small ones.

**Larger mixtures.**  The same estimate is the quadratic wᵀGw of any convex
weights w over K denoisers (G_kl = Σ_draws ⟨T_k, T_l⟩), so
:func:`best_mixture` takes its exact minimum over the blends of up to
``size`` rows: a convex quadratic's minimum over the simplex lies inside
one of its faces, where G_S w = ν1 (:func:`mixture_weights`), so the faces
are enumerated.  ``choose_denoiser``'s ``snapshots`` adds each search path's
leader at other iteration counts (a Taubin filter at t and 2t passes blends
into another polynomial low-pass filter).  Pairs without snapshots are the
default.

What blending gains and costs on the shared meshes, and how the larger mixtures
measured: the denoising guide (*Feature-preserving denoising*, the blending and
larger-mixture items).
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence

import numpy as np

from .auto_result import Ranked

__all__ = ["BLEND_DRAWS", "BLEND_SIZE", "SNAPSHOT_FACTORS", "BLEND_MIN_GAIN", "mixture_weights", "worth_blending",
           "best_mixture", "check_snapshots", "snapshot_rows", "tilt_gram"]

#: fresh recorruptions on which the blend weights are fitted and the blend is judged
BLEND_DRAWS = 6
#: folded into the recorruption key for the blend's draws (the ranking's are unsalted)
BLEND_SALT = 2
#: the most denoisers one blend mixes (pairs: larger mixtures measured no better, the denoising guide)
BLEND_SIZE = 2
#: the iteration counts, as multiples of its leader's, at which each search path is also blended (none by default)
SNAPSHOT_FACTORS: tuple[float, ...] = ()
#: a blend replaces the single winner only when its estimate is lower by at least this share of the winner's
#: estimated risk on the same draws (the estimates carry biases of that order: a smaller gain is not seen)
BLEND_MIN_GAIN = 0.01


def mixture_weights(gram: np.ndarray, rows: Sequence[int]) -> tuple[np.ndarray, float] | None:
    """The convex weights of the denoisers ``rows`` that minimise the blend's summed
    squared tilt wᵀGw over the simplex's interior (w > 0, Σw = 1), by the Lagrange
    condition G_S w = ν 1: w = G_S⁻¹1 / 1ᵀG_S⁻¹1; None where G_S is singular or
    a weight comes out ≤ 0 (the optimum then lies on a face: a smaller set).

    Arguments:
        gram: (K, K) the Gram matrix of the tilts.
        rows: the subset S of the denoisers, two or more.

    Returns:
        (w over S, wᵀG_S w), or None."""
    g = np.asarray(gram, np.float64)[np.ix_(rows, rows)]
    ones = np.ones(len(rows))
    try:
        v = np.linalg.solve(g, ones)
    except np.linalg.LinAlgError:
        return None
    if not np.all(np.isfinite(v)) or v.sum() <= 0 or np.any(v <= 0):
        return None
    w = v / v.sum()
    return w, float(w @ g @ w)


def best_mixture(gram: np.ndarray, winner: int, size: int = BLEND_SIZE) -> tuple[tuple[tuple[int, float], ...], float]:
    """The best of the single ``winner`` and every convex blend of two to ``size``
    denoisers (Σw = 1, w > 0): the exact minimum of the quadratic wᵀGw over
    those faces of the simplex, each face by :func:`mixture_weights` (a convex
    quadratic's minimum over the simplex lies in the interior of one face).

    Arguments:
        gram: (K, K) the Gram matrix of the K denoisers' recorrupted edge tilts, on the same draws.
        winner: the row of the single winner the blends must beat.
        size: the most denoisers in one blend (≥ 1; 1: the winner alone).

    Returns:
        ((row, weight), ...) of the choice, heaviest first (one row with weight 1.0, or
        up to ``size`` rows whose weights sum to 1), and its summed squared tilt."""
    g = np.asarray(gram, np.float64)
    if isinstance(size, bool) or not isinstance(size, int) or size < 1:
        raise ValueError(f"size must be a positive int, got {size!r}")
    best: tuple = (((winner, 1.0),), float(g[winner, winner]))
    for k in range(2, min(size, len(g)) + 1):
        for rows in itertools.combinations(range(len(g)), k):
            fit = mixture_weights(g, rows)
            if fit is not None and fit[1] < best[1]:
                order = np.argsort(-fit[0], kind="stable")
                best = (tuple((rows[i], float(fit[0][i])) for i in order), fit[1])
    return best


def worth_blending(gram: np.ndarray, winner: int, total: float, constant: float, count: int,
                   min_gain: float = BLEND_MIN_GAIN) -> bool:
    """Whether a blend whose summed squared tilt is ``total`` replaces the single ``winner``
    (module docstring, *The choice*): its estimate, total/count − c, is below the winner's,
    G_ww/count − c, by at least ``min_gain`` of the winner's (where that is positive).

    Arguments:
        gram: (K, K) the Gram matrix of the tilts on the blend's draws (:func:`tilt_gram`).
        winner: the single winner's row.
        total: the blend's summed squared tilt (:func:`best_mixture`).
        constant: c, the estimate's noise constant (0 for the held-out estimate).
        count: what the sums are averaged over (faces × draws).
        min_gain: the least share of the winner's estimated risk the blend must gain.

    Returns:
        True to take the blend."""
    alone = float(gram[winner, winner])
    return bool(total < alone and (alone - total) / count >= min_gain * max(alone / count - constant, 0.0))


def check_snapshots(snapshots) -> None:
    """Refuse ``snapshots`` unless it is a sequence of positive finite numbers.

    Arguments:
        snapshots: the iteration multiples of :func:`snapshot_rows`.

    Returns:
        None; raises ValueError naming the value."""
    try:
        factors = [float(f) for f in snapshots]
    except (TypeError, ValueError):
        factors = [float("nan")]
    if isinstance(snapshots, (str, bytes)) or not all(np.isfinite(f) and f > 0 for f in factors):
        raise ValueError(f"snapshots must be a sequence of positive numbers, got {snapshots!r}")


def snapshot_rows(path_leaders: list, factors: Sequence[float], have: list) -> list:
    """Each search path's leader at other iteration counts, as more rows to blend
    (module docstring, *Larger mixtures*).

    Arguments:
        path_leaders: (method, params, risk) rows, each with ``params["iterations"]``.
        factors: the multiples of each leader's count (rounded, at least 1).
        have: rows already blended; a (method, params) among them is not repeated.

    Returns:
        :class:`~jaxmesh.tune.auto_result.Ranked` rows with risk ``None``, leader by leader, factor by factor."""
    seen = [(r[0], r[1]) for r in have]
    out = []
    for method, params, _ in path_leaders:
        for f in factors:
            p = {**params, "iterations": max(1, int(round(params["iterations"] * f)))}
            if (method, p) not in seen:
                seen.append((method, p))
                out.append(Ranked(method, p, None))
    return out


def tilt_gram(tilts) -> np.ndarray:
    """G_kl = Σ_d ⟨T_k(z_d), T_l(z_d)⟩: the Gram matrix of the recorrupted edge
    tilts of K denoisers over the draws z_d (module docstring; the blend's draws
    are fresh, independent of the ranking's).

    Arguments:
        tilts: T_k(z_d) = A(f_k(y + a z_d) − (y − z_d/a)), (K, D, ...) for K denoisers and D draws.

    Returns:
        (K, K) float64."""
    t = np.asarray(tilts, np.float64)
    t = t.reshape(t.shape[0], -1)
    return t @ t.T
