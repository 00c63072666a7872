"""Blind choice of the denoiser and its parameters (``--method auto``).

Every candidate (method, parameters) pair, fixed (``CANDIDATES``) or searched
over its iteration count (:mod:`jaxmesh.tune.paths`), is ranked by the
recorrupted estimate of its normal error (:mod:`jaxmesh.tune.recorrupt`),
which needs no derivative of the denoiser.

**The noise law.**  With ``noise_model="auto"`` the mesh is first read for
impulsive noise (:func:`~jaxmesh.tune.estimate_impulsive_noise`).  When found,
``IMPULSIVE_CANDIDATES`` (impulse repair) join the search and the candidates
are ranked by the held-out estimate (:mod:`jaxmesh.tune.heldout`): the
vertices read as untouched are the clean surface, so each draw displaces some
of them at the law read (p̂, σ̂₁) and the error is measured on the faces whose
three vertices were untouched.  Where fewer than ``HELD_OUT_MIN_FACES`` faces
qualify (noise forced impulsive on a mesh that is not), the recorruption draws
each vertex's normal noise at its own level s_i instead (the two-level law
with the posteriors of :func:`~jaxmesh.tune.impulsive.read_after_repair`, none
within the surface).  Otherwise the noise is
Gaussian: σ from :func:`~jaxmesh.tune.estimate_noise` unless given, split
along the pilot's vertex normals n_i as Σ_i = σ² n_i n_iᵀ + σ_t² (I − n_i n_iᵀ),
σ_t the noise within the surface: the mesh's own reading
:func:`~jaxmesh.tune.estimate_tangential_noise` capped at σ (``"auto"``), 0
(``"normal"``) or σ (``"isotropic"``).  The pilot is guided normal filtering
at its defaults; its face and vertex normals are held fixed.  Every candidate
sees the same draws (common random numbers).

**Racing.**  The settings are raced over the draws (:mod:`jaxmesh.tune.race`): all on the
first, the best ``RACE_KEEP`` of each family on the others.  With ``second_pilot``, the race
winner's output is then a second pilot, under which the search paths' leaders have their counts
picked again (:mod:`jaxmesh.tune.second_pilot`): a leader at a new count joins them.

**The decision.**  The race's winner wins (with ``second_pilot``: the leader least on the
blend's fresh draws), unless a convex blend of leaders (the best of each path and of each
fixed method) is estimated better on those draws (:mod:`jaxmesh.tune.blend`; not under the held-out
estimate, whose blend gains do not predict the true ones: the denoising guide).  It is compared
with doing nothing, whose error at the same noise level is (1 + a²) tr(AᵀAΣ) (held out: the
tilt of the draws' inputs themselves): if the choice does not beat it, ``improved`` is False.
**Large meshes.**  On a mesh of more than ``PATCH_FACTOR × search_vertices``
vertices the candidates are ranked on patches of it, a stratified sample of the
surface (:mod:`jaxmesh.tune.patches`), and only the choice runs on the whole
mesh; the noise law is read on the whole mesh.  The patches' rim (the vertices
next to the rest of the mesh) is held at the pilot's positions through the
search paths' iterations (``pin_rim``).
**Padding.**  With ``ladder`` the search mesh is padded to a ladder of sizes (:mod:`jaxmesh.tune.ladder`), so
that the programs compiled for one mesh serve every mesh whose sizes round alike; the estimates are unchanged.
Measurements and the alternatives tried: the denoising guide.
"""

from __future__ import annotations

import dataclasses
import itertools
import time
import warnings
from collections.abc import Sequence

import jax
import jax.numpy as jnp
import numpy as np

from .._exported import stored_jit
from .._private import PATCH_STREAM, caller_stacklevel, library_key
from .._threads import concurrent_map
from ..geometry import face_normals, mean_edge_length, vertex_normals
from ..host import HostMesh
from ..mesh import Mesh, to_device
from ..transforms import far_vertices
from .blend import (BLEND_DRAWS, BLEND_SALT, BLEND_SIZE, SNAPSHOT_FACTORS, best_mixture, check_snapshots,
                    snapshot_rows, tilt_gram, worth_blending)
from .heldout import held_out_estimate
from .impulsive import estimate_impulsive_noise, read_after_repair
from .ladder import check_ladder, pad_search
from .noise_level import (BlindTuningWarning, blind_caveats, estimate_noise, estimate_tangential_noise,
                          noise_sigma)
from .auto_result import AutoResult, Component, Ranked
from .paths import (BILATERAL_FEATURE_MAX_ITERATIONS, BILATERAL_FEATURE_SETTING, BILATERAL_PATH_FIXED,
                    BILATERAL_PATH_MAX_ITERATIONS, BILATERAL_PATH_SIGMAS, PATHS, TAUBIN_LAMS,
                    TAUBIN_MAX_ITERATIONS, TAUBIN_PASS_BANDS, SearchPath, taubin_mu)
from .patches import PATCH_COUNT, PATCH_FACTOR, SEARCH_VERTICES, sample_patches
from .race import RACE_KEEP, race, run_setting, setting_tilt
from .recorrupt import edge_tilt, recorruptions
from .second_pilot import SECOND_PILOT_SALT, repick_counts

__all__ = ["Candidate", "CANDIDATES", "IMPULSIVE_CANDIDATES", "RACE_KEEP", "SearchPath", "PATHS", "NOISE_MODELS",
           "AutoResult", "edge_tilt", "choose_denoiser", "TAUBIN_LAMS", "TAUBIN_PASS_BANDS",
           "TAUBIN_MAX_ITERATIONS", "taubin_mu", "BILATERAL_PATH_SIGMAS", "BILATERAL_PATH_FIXED",
           "BILATERAL_PATH_MAX_ITERATIONS", "BILATERAL_FEATURE_SETTING", "BILATERAL_FEATURE_MAX_ITERATIONS"]

#: the noise laws of the recorruption (module docstring): impulsive detected, else Gaussian with σ_t estimated;
#: Gaussian with σ_t = 0 or σ; impulsive forced
NOISE_MODELS = ("auto", "normal", "isotropic", "impulsive")


@dataclasses.dataclass(frozen=True)
class Candidate:
    """One (method, parameters) pair that :func:`choose_denoiser` may pick."""

    method: str
    params: dict


def _grid(method: str, **axes) -> list[Candidate]:
    keys = list(axes)
    return [Candidate(method, dict(zip(keys, vals))) for vals in itertools.product(*axes.values())]


#: the fixed candidates (the paths are searched on their own, module docstring)
CANDIDATES: tuple[Candidate, ...] = tuple(
    _grid("bilateral_normal", sigma_r=(0.2, 0.35, 0.6), sigma_s=(1.0, 2.0))
    + _grid("guided_normal", sigma_r=(0.15, 0.3, 0.45), sigma_s=(1.0, 2.0))
)
#: the candidates added when the noise is read as impulsive: impulse repair (L0 minimisation, the literature's
#: answer, is left out: on the shared meshes it did not beat guided filtering and cost the most)
IMPULSIVE_CANDIDATES: tuple[Candidate, ...] = tuple(_grid("impulse_repair", alpha=(0.1, 0.3, 1.0), iterations=(5, 10)))


@stored_jit
def _pilot_normals(pilot: Mesh):
    """The pilot's face normals ν_f and area-weighted vertex normals n_i."""
    return face_normals(pilot), vertex_normals(pilot, "area")


def _counted(nu, core):
    """ν with ν_f = 0 on the faces outside ``core`` (None: every face counts), which then tilt by nothing."""
    return nu if core is None else nu * jnp.asarray(core, nu.dtype)[:, None]


def _check(noisy: Mesh, candidates: Sequence[Candidate], paths: Sequence[SearchPath], draws, a, noise_model,
           blend_draws=0, blend_size=2, snapshots=(),
           search_vertices=None, antithetic=False, race_keep=None, pin_rim=True, second_pilot=False,
           ladder=None) -> None:
    from ..denoise import METHODS

    if not isinstance(noisy, Mesh):
        raise TypeError(f"noisy must be a jaxmesh.Mesh, got {type(noisy).__name__}")
    if noisy.batch_shape:
        raise ValueError("choose_denoiser takes one mesh; loop over a batch")
    far = far_vertices(noisy)
    if far.size:
        raise ValueError(f"vertex {int(far[0])} lies far from the rest ({far.size} such: a corrupt coordinate?); its "
                         "edges set the mean edge length the noise is read in: remove it first")
    if not candidates and not paths:
        raise ValueError("candidates: give at least one (method, params) pair, or a path to search")
    for path in paths:
        if (not isinstance(path, SearchPath) or path.method not in METHODS
                or "iterations" not in METHODS[path.method].params):
            raise ValueError(f"paths: each must be a SearchPath of a registered method with an 'iterations' "
                             f"parameter, got {path!r}")
        if isinstance(path.max_iterations, bool) or not isinstance(path.max_iterations, int) or path.max_iterations < 1:
            raise ValueError(f"paths: max_iterations must be a positive int, got {path.max_iterations!r}")
        for setting in path.settings:
            METHODS[path.method].resolve(**setting, **dict(path.fixed))
    for c in candidates:
        if c.method not in METHODS:
            raise ValueError(f"unknown method {c.method!r} in candidates; choose from {sorted(METHODS)}")
        METHODS[c.method].resolve(**c.params)
    for name, value, least in (("draws", draws, 1), ("blend_draws", blend_draws, 0), ("blend_size", blend_size, 1)):
        if isinstance(value, bool) or not isinstance(value, int) or value < least:
            raise ValueError(f"{name} must be an int >= {least}, got {value!r}")
    check_snapshots(snapshots)
    if not (np.isfinite(a) and a > 0):
        raise ValueError(f"a must be a positive number, got {a!r}")
    if noise_model not in NOISE_MODELS:
        raise ValueError(f"noise_model must be one of {NOISE_MODELS}, got {noise_model!r}")
    if search_vertices is not None and (isinstance(search_vertices, bool) or not isinstance(search_vertices, int)
                                        or search_vertices < PATCH_COUNT):
        raise ValueError(f"search_vertices must be None or an int >= {PATCH_COUNT}, got {search_vertices!r}")
    for name, value in (("antithetic", antithetic), ("pin_rim", pin_rim), ("second_pilot", second_pilot)):
        if not isinstance(value, bool):
            raise ValueError(f"{name} must be True or False, got {value!r}")
    check_ladder(ladder)
    if race_keep is not None and (isinstance(race_keep, bool) or not isinstance(race_keep, int) or race_keep < 1):
        raise ValueError(f"race_keep must be None or an int >= 1, got {race_keep!r}")


def choose_denoiser(noisy: Mesh, sigma: float | None = None, candidates: Sequence[Candidate] = CANDIDATES,
                    *, impulsive_candidates: Sequence[Candidate] = IMPULSIVE_CANDIDATES,
                    paths: Sequence[SearchPath] = PATHS, noise_model: str = "auto", draws: int = 2,
                    blend_draws: int = BLEND_DRAWS, blend_size: int = BLEND_SIZE,
                    snapshots: Sequence[float] = SNAPSHOT_FACTORS, a: float = 0.5, key=0,
                    search_vertices: int | None = SEARCH_VERTICES, antithetic: bool = False,
                    race_keep: int | None = RACE_KEEP, pin_rim: bool = True, second_pilot: bool = False,
                    ladder: float | None = None) -> AutoResult:
    """Pick the candidate with the least recorrupted normal-error estimate (module docstring), blind.

    Arguments:
        noisy: the mesh to denoise (single).
        sigma: the noise standard deviation in mesh units (default: estimated).
        candidates: the fixed candidates (method, parameters).
        impulsive_candidates: added to ``candidates`` when the noise law is impulsive.
        paths: the families also searched over their iteration count (``()`` for none).
        noise_model: the recorruption's noise law: ``"auto"`` (impulsive when detected, else
            Gaussian with the noise within the surface estimated, capped at σ), ``"normal"``
            (Gaussian along the normals), ``"isotropic"`` (Gaussian, σ in every direction) or
            ``"impulsive"`` (the two-level law, forced).
        draws: recorruptions per candidate.
        blend_draws: fresh recorruptions on which the blends of the leaders are fitted and judged
            (:mod:`jaxmesh.tune.blend`; the recorrupted estimate only); 0: no blending.
        blend_size: the most denoisers one blend mixes (1: no blending; 2: pairs).
        snapshots: each search path's leader is also blended at these multiples of its
            iteration count (``()``: the leaders alone).
        a: the recorruption strength.
        key: the key (or int seed) of the recorruptions and of the patches' draw.
        search_vertices: on a mesh of more than ``PATCH_FACTOR`` times this many vertices the
            candidates are ranked on patches whose cores hold about this many vertices in all
            (:mod:`jaxmesh.tune.patches`; default ``SEARCH_VERTICES``, the measured setting) and
            the winner runs on the whole mesh; ``None``: always rank on the whole mesh.
        antithetic: draw the recorruptions in (z, −z) pairs (:mod:`jaxmesh.tune.recorrupt`;
            measured no better than independent draws, the default: the denoising guide).
        race_keep: after the first draw, how many settings of each family (each method among
            the fixed candidates, each search path) go on to the other draws (module docstring,
            *Racing*); ``None``: every setting on every draw.
        pin_rim: on patches, hold their rim (the vertices next to the rest of the mesh) at the
            pilot's positions after every iteration of the search paths, as the denoised
            surface around them would be; False: a free edge (measured: the denoising guide).
        second_pilot: after the race, pick the search paths' counts again under the race winner's
            output as the pilot, leaders at new counts joining the others on the blend's draws
            (module docstring, *Racing*; with ``blend_draws`` > 0; measured: the denoising guide).
        ladder: pad the search mesh to this ladder of sizes (:mod:`jaxmesh.tune.ladder`, e.g.
            ``jaxmesh.tune.SEARCH_LADDER``; the same estimates); ``None`` (default, measured faster): unpadded.

    Returns:
        An :class:`AutoResult`: the method and parameters chosen (or the blend), the
        denoised mesh, the table of estimated risks."""
    _check(noisy, [*candidates, *impulsive_candidates], paths, draws, a, noise_model, blend_draws, blend_size,
           snapshots, search_vertices, antithetic, race_keep, pin_rim, second_pilot, ladder)
    clock = [time.perf_counter()]
    host = HostMesh(noisy)
    law = _noise_law(host, sigma, noise_model)
    clock.append(time.perf_counter())
    if law["law"] == "none":
        return _unchanged(noisy, clock[1] - clock[0])
    if law["law"] == "impulsive":
        candidates = list(candidates) + [c for c in impulsive_candidates if c not in candidates]
    search, s_vertex, core, rim, real = _search_mesh(host, law, search_vertices, key, pin_rim, ladder)
    clock.append(time.perf_counter())
    impulsive = (law["fraction"], law["sigma"]) if law["law"] == "impulsive" else None
    ranked = _rank(search, core, mean_edge_length(noisy), candidates, paths, s_vertex, law["tangential"], draws,
                   blend_draws, blend_size, snapshots, a, key, antithetic, race_keep, impulsive, rim, second_pilot,
                   real)
    components, risk, noisy_risk, table, estimator = ranked
    clock.append(time.perf_counter())
    y = noisy.vertices
    auxes = {c.method: host.aux(c.method) for c in components}
    runs = concurrent_map(lambda c: jax.block_until_ready(run_setting(noisy, y, c.method, c.params, auxes[c.method],
                                                                      _on_path(c, paths))), components)
    out = to_device(sum(c.weight * np.asarray(x) for c, x in zip(components, runs)))     # on the host: no programs
    clock.append(time.perf_counter())
    seconds = dict(zip(("noise_law", "patches", "ranking", "choice"), np.diff(clock).round(3).tolist()))
    method, params = (components[0].method, components[0].params) if len(components) == 1 else ("blend", {})
    blind_caveats(noisy, law["sigma"], law["estimated"], risk / noisy_risk if noisy_risk > 0 else np.inf)
    return AutoResult(method, params, noisy.with_vertices(out), law["sigma"], law["estimated"], law["tangential"],
                      risk, noisy_risk, bool(risk < noisy_risk), table, components, law["law"], law["fraction"],
                      real, seconds, estimator, draws)


def _search_mesh(host: HostMesh, law: dict, search_vertices: int | None, key, pin_rim: bool, ladder) -> tuple:
    """The mesh the candidates are ranked on (module docstring, *Large meshes*, *Padding*): (its host mesh,
    the noise level of each of its vertices (or one σ), the faces that count or None for all, the vertices
    held through the search paths' iterations or None, its real vertex count)."""
    noisy, s_vertex = host.mesh, law["vertex_sigma"]
    search, core, rim = host, None, None
    if search_vertices is not None and noisy.num_vertices > PATCH_FACTOR * search_vertices:
        seed = int(jax.random.randint(library_key(key, PATCH_STREAM), (), 0, np.iinfo(np.int32).max))
        patches = sample_patches(noisy, search_vertices, seed=seed)
        s_vertex = s_vertex if np.ndim(s_vertex) == 0 else np.asarray(s_vertex)[patches.vertices]
        search, core = HostMesh(patches.mesh), patches.core_faces
        rim = patches.rim if pin_rim and patches.rim.any() else None
    real = search.mesh.num_vertices
    if ladder is not None and law["law"] == "gaussian":
        search, core, rim = pad_search(search, core, rim, ladder)
    return search, s_vertex, core, rim, real


def _unchanged(noisy: Mesh, seconds: float) -> AutoResult:
    """The result for a mesh that reads as noise-free (σ̂ = 0): the input itself, with a warning."""
    warnings.warn(f"the mesh reads as noise-free (noise estimate 0 from {noisy.num_vertices} vertices: an exactly "
                  "smooth surface, or too few vertices), so it is returned unchanged; give the noise level to "
                  "denoise it anyway (CLI: --noise-sigma)", BlindTuningWarning, stacklevel=caller_stacklevel())
    return AutoResult("none", {}, noisy, 0.0, True, 0.0, 0.0, 0.0, False, [], (), "none", 0.0, 0,
                      {"noise_law": round(seconds, 3), "patches": 0.0, "ranking": 0.0, "choice": 0.0})


def _on_path(row, paths: Sequence[SearchPath]) -> bool:
    """Whether ``row`` (a method and its parameters) is a setting of one of ``paths`` at some count: run
    with its count traced (``run_setting(counted=True)``), as the race ran it; a fixed candidate runs whole."""
    rest = {k: v for k, v in row.params.items() if k != "iterations"}
    return any(path.method == row.method and rest == {**s, **dict(path.fixed)} for path in paths for s in path.settings)


def _tilts(noisy: Mesh, inputs, targets, candidates: Sequence[Candidate], auxes: dict, nu, ell,
           paths=(), pin=None) -> list[np.ndarray]:
    """T = A(f(ŷ_d) − ỹ_d) of every candidate f on every draw (ŷ_d, ỹ_d), one array (D, F, 3) per
    candidate, the candidates side by side on the host's cores (:mod:`jaxmesh._threads`; the settings
    of ``paths`` with their count traced, ``pin`` held after each of their iterations).  One mesh
    per call: batching the draws or the settings into one call ran slower on CPU under the
    ``jaxmesh`` command's XLA flags (:mod:`jaxmesh.compiler`) and compiled a program per batch size."""
    def tilts(c: Candidate) -> np.ndarray:
        return np.stack([np.asarray(setting_tilt(noisy, x, t, nu, ell, c.method, c.params, auxes[c.method],
                                                 _on_path(c, paths), pin)) for x, t in zip(inputs, targets)])
    return concurrent_map(tilts, candidates)


@jax.jit
def _recorrupted_pair(y, z, a):
    """The recorrupted inputs ŷ = y + a z and targets ỹ = y − z / a, one program."""
    return y[None] + a * z, y[None] - z / a


def _rank(host: HostMesh, core, ell, candidates, paths, s_vertex, s_t, draws, blend_draws, blend_size, snapshots, a,
          key, antithetic=False, race_keep=None, impulsive=None, rim=None, second_pilot=False, vertices=None) -> tuple:
    """The search of :func:`choose_denoiser` on ``host``'s mesh (the whole mesh or its patches, where only
    the faces of ``core`` count): (components, risk, doing nothing's risk, table), risks per counted face.
    ``impulsive``: (p̂, σ̂₁) to rank by the held-out estimate where it measures enough faces; ``rim``:
    the vertices held at the pilot's positions through the search paths' iterations, or None;
    ``second_pilot``: the paths' counts picked again under the race winner's output; ``vertices``: the
    real ones (the rest padding, :mod:`jaxmesh.tune.ladder`), None for all."""
    noisy = host.mesh
    y = noisy.vertices
    methods = ({c.method for c in candidates} | {"guided_normal"} | {path.method for path in paths}
               | ({"impulse_repair"} if impulsive else set()))
    auxes = {m: host.aux(m) for m in methods}
    pilot = noisy.with_vertices(run_setting(noisy, y, "guided_normal", {}, auxes["guided_normal"]))
    nu, n = _pilot_normals(pilot)
    pin = None if rim is None else (jnp.asarray(rim), pilot.vertices)
    counted = np.ones(noisy.num_faces, bool) if core is None else np.asarray(core, bool)
    held = held_out_estimate(noisy, pilot, nu, n, ell, counted, auxes, impulsive, key) if impulsive else None
    if held is not None:
        nu, draw, count = held
        inputs, targets = draw(draws)
        constant, per_face = 0.0, noisy.num_faces / count
        nothing = float(jnp.sum(edge_tilt(noisy, nu, ell, inputs - targets) ** 2)) / draws / noisy.num_faces
    else:
        nu, per_face = _counted(nu, core), noisy.num_faces / max(int(counted.sum()), 1)

        def draw(count: int, salt: int = 0, normals=None):      # normals: (ν, n) of another pilot
            nu_, n_ = (nu, n) if normals is None else normals
            zs = recorruptions(noisy, nu_, n_, ell, s_vertex, s_t, count, key, salt=salt, antithetic=antithetic,
                               vertices=vertices)
            return (*_recorrupted_pair(y, zs[0], a), zs[1])
        inputs, targets, trace = draw(draws)
        constant, nothing = (1 + 1 / a**2) * trace, (1 + a**2) * trace

    table, leaders = race(noisy, candidates, paths, inputs, targets, nu, ell, auxes, constant, race_keep, pin)
    components, risk = (Component(table[0].method, table[0].params, 1.0),), table[0].risk
    second = second_pilot and held is None and bool(blend_draws)
    if second:
        won = table[0]
        x = run_setting(noisy, y, won.method, won.params, auxes[won.method], _on_path(won, paths), pin)
        nu2, n2 = _pilot_normals(noisy.with_vertices(x))
        nu2 = _counted(nu2, core)
        inputs, targets, trace = draw(draws, SECOND_PILOT_SALT, (nu2, n2))
        again = repick_counts(noisy, leaders, paths, inputs, targets, nu2, ell, auxes, (1 + 1 / a**2) * trace, pin)
    rows = leaders + snapshot_rows(leaders[len(leaders) - len(paths):], snapshots, leaders)
    rows += [r for r, was in zip(again, leaders) if r.params != was.params] if second else []
    if second or (held is None and blend_draws and blend_size > 1 and len(rows) > 1):
        fresh = draw(blend_draws, BLEND_SALT)
        blended = [Candidate(*r[:2]) for r in rows]
        gram = tilt_gram(np.stack(_tilts(noisy, *fresh[:2], blended, auxes, nu, ell, paths, pin)))
        winner = int(np.argmin(np.diag(gram))) if second else next(i for i, r in enumerate(rows) if r is table[0])
        if second:
            components = (Component(rows[winner].method, rows[winner].params, 1.0),)
            risk = float(gram[winner, winner]) / noisy.num_faces / blend_draws - constant
        mix, total = best_mixture(gram, winner, blend_size)
        if len(mix) > 1 and worth_blending(gram, winner, total, constant, noisy.num_faces * blend_draws):
            components = tuple(Component(rows[i].method, rows[i].params, w) for i, w in mix)
            risk = total / noisy.num_faces / blend_draws - constant
    table = [Ranked(m, p, r * per_face) for m, p, r in table]
    return components, risk * per_face, nothing * per_face, table, "recorrupted" if held is None else "held_out"


def _noise_law(host: HostMesh, sigma, noise_model: str) -> dict:
    """The recorruption's law (module docstring): σ (σ₁ for impulsive noise), each vertex's
    normal level s_i (or σ), σ_t, whether σ was estimated, the law's name and p̂."""
    noisy = host.mesh
    if noise_model in ("auto", "impulsive"):
        found = estimate_impulsive_noise(host)
        if found.impulsive or noise_model == "impulsive":
            found = read_after_repair(noisy, found)
            s, estimated = noise_sigma(noisy, sigma) if sigma is not None else (found.sigma, True)
            if not (np.isfinite(s) and s > 0):
                raise ValueError("the impulsive noise of this mesh cannot be estimated (no heavy component); "
                                 "give the noise level (CLI: --noise-sigma) or another noise model")
            return {"sigma": s, "vertex_sigma": found.vertex_sigma() * (s / found.sigma), "tangential": 0.0,
                    "estimated": estimated, "law": "impulsive", "fraction": found.fraction}
    s, estimated = (estimate_noise(host), True) if sigma is None else noise_sigma(host, sigma)
    if s == 0:
        return {"sigma": 0.0, "law": "none"}
    if not np.isfinite(s):
        raise ValueError(f"the noise estimate of this mesh is {s}; give the noise level (CLI: --noise-sigma)")
    s_t = {"normal": 0.0, "isotropic": s}.get(noise_model)
    s_t = min(estimate_tangential_noise(host), s) if s_t is None else s_t
    return {"sigma": s, "vertex_sigma": s, "tangential": s_t, "estimated": estimated, "law": "gaussian",
            "fraction": 1.0}
