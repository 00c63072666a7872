"""The blind chooser's second pilot: the race winner's own output.

The recorrupted estimate (:mod:`jaxmesh.tune.recorrupt`) sees a candidate's error
through a pilot's normals: the tilt operator A measures edges against the pilot's
face normals ν_f, and the noise of the draws is split along its vertex normals n_i.
The first pilot is guided normal filtering at its defaults, which keeps creases but
on smooth surfaces under heavy noise errs far more than the filters it judges (on
spot at 0.3ℓ̄ isotropic noise, even tuned with the clean mesh, 9.2° against the tuned
Taubin filter's 6.7°), and what moves with the pilot is the search paths' best counts
(judging the race's leaders again under a better pilot changed nothing there; picking
their counts again did).  So after the race
(:mod:`jaxmesh.tune.race`) the winner's output on the ranked mesh becomes a second
pilot, under which each search path's leader has its iteration count picked again
on fresh draws, as many as the race's (:func:`repick_counts`).  A leader whose count
moves joins, at its new count, the leaders that the blend's draws then judge under
the first pilot, as the race did (:mod:`jaxmesh.tune.blend`): the least of them is the
choice, blended where that pays.  Two bolder uses were tried and not kept: the new
counts replacing the race's, and the leaders judged under the second pilot too; each
made the cow at 0.1ℓ̄ isotropic worse by several percent.  Not the default
(``choose_denoiser(second_pilot=True)``): over the feature table it gains on the smooth
meshes under heavy isotropic noise and loses about as often elsewhere (the denoising
guide, *The second pilot*).
"""

from __future__ import annotations

import numpy as np

from ..mesh import Mesh
from .auto_result import Ranked
from .paths import SearchPath, path_risks

__all__ = ["SECOND_PILOT_SALT", "repick_counts"]

#: the salt of the fresh draws (as many as the race's) on which the path leaders' counts are picked again
SECOND_PILOT_SALT = 3


def _setting(path: SearchPath, params: dict) -> dict:
    """The path setting of a leader's parameters: its own, less the path's fixed ones and the count."""
    fixed = dict(path.fixed)
    return {k: v for k, v in params.items() if k != "iterations" and k not in fixed}


def repick_counts(mesh: Mesh, leaders: list, paths, inputs, targets, nu, ell, auxes: dict, constant: float,
                  pin=None) -> list:
    """The leaders with each search path's count picked again: t* = argmin_t Σ_d ‖A(f^t(ŷ_d) − ỹ_d)‖²/F
    over the draws given, one draw at a time (the race's programs), for the setting the race chose.

    Arguments:
        mesh: the ranked mesh (single).
        leaders: the race's best row of each family, the paths' last, in the order of ``paths``.
        paths: the search paths.
        inputs: the recorrupted inputs ŷ_d under the second pilot, (D, V, 3).
        targets: the targets ỹ_d, (D, V, 3).
        nu: the second pilot's face normals (zero rows: faces that do not count), (F, 3).
        ell: the mean edge length ℓ̄.
        auxes: each method's prepared arrays.
        constant: the noise constant of these draws.
        pin: as for :func:`~jaxmesh.tune.paths.path_risks`.

    Returns:
        A new list: the fixed families' leaders as they were, each path's with its new count and
        its estimate on these draws."""
    out = list(leaders)
    first = len(leaders) - len(paths)
    for j, path in enumerate(paths):
        lead = leaders[first + j]
        setting = _setting(path, lead.params)
        risks = sum(path_risks(mesh, path, setting, inputs[d:d + 1], targets[d:d + 1], nu, ell, auxes[path.method],
                               pin=pin) for d in range(len(inputs))) / len(inputs)
        t = int(np.argmin(risks))
        out[first + j] = Ranked(lead.method, {**lead.params, "iterations": t + 1}, float(risks[t]) - constant)
    return out
