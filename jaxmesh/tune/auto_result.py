"""What :func:`~jaxmesh.tune.choose_denoiser` returns: its choice, the denoised mesh and why."""

from __future__ import annotations

import dataclasses
from typing import Any, NamedTuple

import numpy as np

from ..mesh import Mesh

__all__ = ["AutoResult", "Ranked", "Component"]


class Ranked(NamedTuple):
    """One row of the chooser's table: a setting and its estimated ``risk`` (mean squared
    edge tilt, radians²; ``None`` for a row not estimated on its own, a blend's snapshot)."""

    method: str
    params: dict
    risk: float | None


class Component(NamedTuple):
    """One denoiser of the chooser's output and its ``weight`` in the blend (1 when alone)."""

    method: str
    params: dict
    weight: float


@dataclasses.dataclass(frozen=True)
class AutoResult:
    """What :func:`choose_denoiser` chose and why.

    * ``method``, ``params``: the winner (the method's other parameters at
      their defaults), or ``"blend"`` and ``{}`` when two are blended, or
      ``"none"`` when the mesh reads as noise-free (σ̂ = 0: ``mesh`` is the input);
      ``components``: the :class:`Component` rows (method, params, weight) of what ``mesh``, the output, is
      made of (one with weight 1, or the blend's two, :mod:`jaxmesh.tune.blend`);
    * ``sigma``: the noise σ used (mesh units; impulsive noise: σ₁, the displaced
      vertices' level) and whether it was ``estimated``; ``tangential_sigma``: the
      σ_t within the surface of the recorruption; ``noise_law``: ``"gaussian"``,
      ``"impulsive"`` or ``"none"``, and ``fraction``: the share p̂ of displaced vertices (1 for Gaussian);
    * ``risk``: the winner's estimated mean squared edge tilt (radians²) at the
      recorrupted noise level, or, under impulsive noise, on the held-out draws (a blend's on its
      own draws), ``noisy_risk`` doing nothing's, and ``improved = risk < noisy_risk``;
    * ``table``: every candidate with its estimate (:class:`Ranked` rows), best first;
    * ``search_vertices``: the vertices of the mesh the candidates were ranked on (the
      whole mesh's, or its patches', :mod:`jaxmesh.tune.patches`);
    * ``estimator``: ``"recorrupted"`` (:mod:`jaxmesh.tune.recorrupt`) or ``"held_out"``
      (impulsive noise, :mod:`jaxmesh.tune.heldout`), the estimate that ranked the candidates,
      and ``draws``: on how many of its draws (0 when nothing was ranked);
    * ``seconds``: wall seconds of each stage: ``"noise_law"`` (read on the whole mesh),
      ``"patches"`` (sampling them; 0 on the whole mesh), ``"ranking"`` (the race and the
      blend's draws) and ``"choice"`` (the choice run on the whole mesh).
    """

    method: str
    params: dict
    mesh: Mesh
    sigma: float
    estimated: bool
    tangential_sigma: float
    risk: float
    noisy_risk: float
    improved: bool
    table: list[Ranked]
    components: tuple[Component, ...] = ()
    noise_law: str = "gaussian"
    fraction: float = 1.0
    search_vertices: int = 0
    seconds: dict = dataclasses.field(default_factory=dict)
    estimator: str = "recorrupted"
    draws: int = 0

    @property
    def rms_tilt_degrees(self) -> float:
        """√risk in degrees: the estimated RMS normal error of the winner."""
        return float(np.degrees(np.sqrt(max(self.risk, 0.0))))

    def summary(self) -> dict[str, Any]:
        """A JSON-ready account of the choice (``estimated_rms_normal_error_deg`` null where the
        estimate is negative, a noise level read too high: ``risk`` gives it)."""
        return {"method": self.method, "params": self.params, "noise_sigma": self.sigma,
                "noise_sigma_estimated": self.estimated, "tangential_noise_sigma": self.tangential_sigma,
                "noise_law": self.noise_law, "noise_fraction": self.fraction,
                "risk": self.risk, "noisy_risk": self.noisy_risk,
                "estimated_rms_normal_error_deg": self.rms_tilt_degrees if self.risk >= 0 else None,
                "noisy_rms_normal_error_deg": float(np.degrees(np.sqrt(max(self.noisy_risk, 0.0)))),
                "improved": self.improved, "search_vertices": self.search_vertices, "seconds": self.seconds,
                "estimator": self.estimator, "draws": self.draws,
                "components": [c._asdict() for c in self.components],
                "candidates": [r._asdict() for r in self.table]}
