"""Automatic tuning of the denoisers' parameters (λ of the kernel flow first).

Supervised (a clean mesh in hand) or blind (Stein's unbiased risk estimate of
the visual error, with the noise σ given or estimated from the mesh), for one
mesh, a batch of meshes in one vmapped call, or one setting shared by a
training set.  See :mod:`jaxmesh.tune.tuner` for the search.
"""

from .auto import (CANDIDATES, IMPULSIVE_CANDIDATES, NOISE_MODELS, PATHS, RACE_KEEP, AutoResult, Candidate,
                   SearchPath, choose_denoiser, edge_tilt)
from .auto_result import Component, Ranked
from .impulsive import ImpulsiveNoise, estimate_impulsive_noise
from .patches import Patches, sample_patches
from .ladder import SEARCH_LADDER
from .noise_level import (
    LOW_NOISE,
    NOISE_ESTIMATORS,
    SIGMA_RANGE,
    BlindTuningWarning,
    blind_caveats,
    checked_sigma,
    estimate_noise,
    estimate_tangential_noise,
    noise_sigma,
    umbrella_square_row_norms,
)
from .objectives import OBJECTIVES, noisy_visual_error_expectation, relative_error, sure_visual_error
from .space import Coordinate, search_space
from .batched import tune_batch, tune_shared
from .options import TuneOptions
from .tuner import TuneResult, tune, tune_lambda
from .run import AUTO, DenoiseRun, denoise_with_tuning, split_auto

__all__ = [
    "tune", "tune_lambda", "tune_batch", "tune_shared", "TuneOptions", "TuneResult",
    "AUTO", "DenoiseRun", "denoise_with_tuning", "split_auto",
    "estimate_noise", "estimate_tangential_noise", "noise_sigma", "checked_sigma", "SIGMA_RANGE",
    "umbrella_square_row_norms", "NOISE_ESTIMATORS",
    "blind_caveats", "BlindTuningWarning", "LOW_NOISE",
    "choose_denoiser", "AutoResult", "Ranked", "Component", "Candidate", "CANDIDATES", "IMPULSIVE_CANDIDATES", "SearchPath", "PATHS",
    "NOISE_MODELS", "RACE_KEEP", "edge_tilt", "estimate_impulsive_noise", "ImpulsiveNoise", "sample_patches", "Patches",
    "SEARCH_LADDER",
    "OBJECTIVES", "relative_error", "sure_visual_error", "noisy_visual_error_expectation",
    "Coordinate", "search_space",
]
