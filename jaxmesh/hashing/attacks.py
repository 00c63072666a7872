"""Attacks on a mesh, for testing the robustness of a hash (thesis ch.4, table 4.1).

Each attack is a pure function ``attack(mesh, ..., seed=0) -> Mesh``: the same
mesh, parameters and seed always give the same result.  Attacks that only move
the vertices (scaling, rotation, translation, smoothing, noise) keep the
connectivity and the vertex order; the others rebuild the mesh on the host:

* :func:`simplify` runs quadric-error decimation (``fast-simplification``,
  a maintained binding of Sven Forstmann's Fast-Quadric-Mesh-Simplification);
* :func:`reorder_vertices` permutes the vertices (and the faces);
* :func:`crop` cuts away the faces around a seeded point.

:data:`TABLE_4_1` lists the thesis's attacks at the strengths used by
``experiments/hash`` (the thesis does not state its scaling factor, its
smoothing step or the unit of its noise σ; the choices are written there).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from ..denoise.laplacian import umbrella_flow
from ..mesh import Mesh
from ..noise import add_noise

__all__ = [
    "scale_axis",
    "rotate",
    "translate",
    "smooth",
    "add_gaussian_noise",
    "simplify",
    "reorder_vertices",
    "crop",
    "TABLE_4_1",
    "EXTRA_ATTACKS",
    "ALL_ATTACKS",
]

_AXES = {"x": 0, "y": 1, "z": 2}


def _axis(axis) -> int:
    if isinstance(axis, str) and axis in _AXES:
        return _AXES[axis]
    if axis in (0, 1, 2):
        return int(axis)
    raise ValueError(f"axis must be 'x', 'y', 'z' or 0, 1, 2, got {axis!r}")


def _single(mesh: Mesh) -> None:
    if mesh.batch_shape:
        raise ValueError(f"attacks take a single mesh, got batch shape {mesh.batch_shape}")


def _host(mesh: Mesh) -> tuple[np.ndarray, np.ndarray]:
    _single(mesh)
    return np.asarray(mesh.vertices, np.float64), np.asarray(mesh.faces, np.int64)


def _rebuild(vertices: np.ndarray, faces: np.ndarray, like: Mesh) -> Mesh:
    """A new mesh, dropping unreferenced vertices (order of the rest kept)."""
    used = np.zeros(len(vertices), bool)
    used[faces.ravel()] = True
    remap = np.cumsum(used) - 1
    return Mesh.from_arrays(vertices[used], remap[faces], dtype=like.vertices.dtype, warn=False)


def scale_axis(mesh: Mesh, axis="x", factor: float = 1.5, seed: int = 0) -> Mesh:
    """v' = v with coordinate ``axis`` multiplied by ``factor`` (about the origin).

    Arguments:
        mesh: a single mesh.
        axis: ``"x"``, ``"y"`` or ``"z"`` (or 0, 1, 2).
        factor: the scale factor.
        seed: the seed of the attack's random choices (ignored by deterministic attacks).

    Returns:
        The attacked mesh."""
    _single(mesh)
    if not np.isfinite(factor) or factor == 0:
        raise ValueError(f"factor must be finite and non-zero, got {factor}")
    s = np.ones(3)
    s[_axis(axis)] = factor
    return mesh.with_vertices(mesh.vertices * s[None, :].astype(mesh.vertices.dtype))


def rotation_matrix(axis, degrees: float) -> np.ndarray:
    """The 3×3 rotation by ``degrees`` about the coordinate ``axis`` (right-handed)."""
    k = _axis(axis)
    t = np.deg2rad(degrees)
    c, s = np.cos(t), np.sin(t)
    i, j = [a for a in range(3) if a != k]
    r = np.eye(3)
    r[i, i], r[i, j], r[j, i], r[j, j] = c, -s, s, c
    if k == 1:  # keep the right-handed sense z -> x about y
        r = r.T
    return r


def rotate(mesh: Mesh, axis="x", degrees: float = 45.0, seed: int = 0) -> Mesh:
    """v' = R v, R the rotation by ``degrees`` about coordinate ``axis`` through the origin.

    Arguments:
        mesh: a single mesh.
        axis: ``"x"``, ``"y"`` or ``"z"`` (or 0, 1, 2).
        degrees: the rotation angle.
        seed: the seed of the attack's random choices (ignored by deterministic attacks).

    Returns:
        The attacked mesh."""
    _single(mesh)
    r = rotation_matrix(axis, degrees).astype(mesh.vertices.dtype)
    return mesh.with_vertices(mesh.vertices @ r.T)


def translate(mesh: Mesh, offset=None, seed: int = 0) -> Mesh:
    """v' = v + t; by default t is a seeded random direction of length one
    bounding-box diagonal.

    Arguments:
        mesh: a single mesh.
        offset: the translation t, (3,) (default: a seeded direction, one diagonal long).
        seed: the seed of the attack's random choices (ignored by deterministic attacks).

    Returns:
        The attacked mesh."""
    v, _ = _host(mesh)
    if offset is None:
        d = np.random.default_rng(seed).standard_normal(3)
        offset = d / np.linalg.norm(d) * np.linalg.norm(v.max(0) - v.min(0))
    t = np.asarray(offset, np.float64)
    if t.shape != (3,) or not np.all(np.isfinite(t)):
        raise ValueError(f"offset must be 3 finite numbers, got {offset!r}")
    return mesh.with_vertices(mesh.vertices + t[None, :].astype(mesh.vertices.dtype))


def smooth(mesh: Mesh, iterations: int = 10, lam: float = 0.5, seed: int = 0) -> Mesh:
    """``iterations`` steps of Laplacian (umbrella) smoothing x <- x + λ K x.

    Arguments:
        mesh: a single mesh.
        iterations: the number of steps.
        lam: the step λ.
        seed: the seed of the attack's random choices (ignored by deterministic attacks).

    Returns:
        The attacked mesh."""
    _single(mesh)
    return umbrella_flow(mesh, lam=lam, iterations=iterations)


def add_gaussian_noise(mesh: Mesh, sigma: float = 0.25, seed: int = 0) -> Mesh:
    """Isotropic Gaussian noise of standard deviation σ = ``sigma`` · ℓ̄ (mean edge length).

    Arguments:
        mesh: a single mesh.
        sigma: the standard deviation, in units of the mean edge length ℓ̄.
        seed: the seed of the attack's random choices (ignored by deterministic attacks).

    Returns:
        The attacked mesh."""
    _single(mesh)
    return add_noise(mesh, sigma, seed)


def simplify(mesh: Mesh, keep: float = 0.3, seed: int = 0) -> Mesh:
    """Quadric-error decimation to about ``keep`` of the faces (``fast-simplification``).

    The result has new vertices and connectivity; its face count is within a
    few faces of ``keep · F`` (the decimator stops on whole edge collapses).

    Arguments:
        mesh: a single mesh.
        keep: the fraction of faces to keep.
        seed: the seed of the attack's random choices (ignored by deterministic attacks).

    Returns:
        The attacked mesh."""
    if not 0 < keep <= 1:
        raise ValueError(f"keep must be in (0, 1], got {keep}")
    v, f = _host(mesh)
    if keep == 1:
        return mesh
    import fast_simplification

    vs, fs = fast_simplification.simplify(np.array(v, order="C"), np.array(f, np.int32, order="C"),
                                          target_reduction=1.0 - keep)
    fs = np.asarray(fs, np.int64)
    fs = fs[(fs[:, 0] != fs[:, 1]) & (fs[:, 1] != fs[:, 2]) & (fs[:, 0] != fs[:, 2])]
    if len(fs) == 0:
        raise ValueError(f"simplification to {keep} of {len(f)} faces left no face")
    return _rebuild(np.asarray(vs, np.float64), fs, mesh)


def reorder_vertices(mesh: Mesh, seed: int = 0) -> Mesh:
    """The same surface with its vertices (and faces) in a seeded random order.

    Arguments:
        mesh: a single mesh.
        seed: the seed of the attack's random choices (ignored by deterministic attacks).

    Returns:
        The attacked mesh."""
    v, f = _host(mesh)
    rng = np.random.default_rng(seed)
    perm = rng.permutation(len(v))          # new vertex i is old vertex perm[i]
    inv = np.empty_like(perm)
    inv[perm] = np.arange(len(v))
    faces = inv[f][rng.permutation(len(f))]
    return Mesh.from_arrays(v[perm], faces, dtype=mesh.vertices.dtype, warn=False)


def crop(mesh: Mesh, fraction: float = 0.02, seed: int = 0) -> Mesh:
    """Cut away a small piece: the ``fraction`` of the vertices nearest (Euclidean)
    to a seeded random vertex, with every face touching them.

    Arguments:
        mesh: a single mesh.
        fraction: the fraction of vertices to cut away.
        seed: the seed of the attack's random choices (ignored by deterministic attacks).

    Returns:
        The attacked mesh."""
    if not 0 <= fraction < 1:
        raise ValueError(f"fraction must be in [0, 1), got {fraction}")
    v, f = _host(mesh)
    centre = v[np.random.default_rng(seed).integers(len(v))]
    count = int(round(fraction * len(v)))
    if count == 0:
        return mesh
    cut = np.zeros(len(v), bool)
    cut[np.argsort(np.linalg.norm(v - centre, axis=1), kind="stable")[:count]] = True
    keep = ~cut[f].any(axis=1)
    if not keep.any():
        raise ValueError(f"cropping {fraction} of the vertices removed every face")
    return _rebuild(v, f[keep], mesh)


def _named(fn: Callable, **kw) -> Callable[[Mesh, int], Mesh]:
    def attack(mesh: Mesh, seed: int = 0) -> Mesh:
        return fn(mesh, seed=seed, **kw)

    attack.__name__ = fn.__name__
    attack.params = dict(kw)  # type: ignore[attr-defined]
    attack.__doc__ = f"{fn.__name__}({', '.join(f'{k}={v!r}' for k, v in kw.items())})"
    return attack


#: The attacks of the thesis's table 4.1, at the strengths used in experiments/hash.
TABLE_4_1: dict[str, Callable[[Mesh, int], Mesh]] = {
    "scale x 1.5": _named(scale_axis, axis="x", factor=1.5),
    "scale y 1.5": _named(scale_axis, axis="y", factor=1.5),
    "scale z 1.5": _named(scale_axis, axis="z", factor=1.5),
    "rotate x 45°": _named(rotate, axis="x", degrees=45.0),
    "rotate y 45°": _named(rotate, axis="y", degrees=45.0),
    "rotate z 45°": _named(rotate, axis="z", degrees=45.0),
    "smooth 10 it": _named(smooth, iterations=10, lam=0.5),
    "simplify 30%": _named(simplify, keep=0.3),
    "noise 0.25ℓ̄": _named(add_gaussian_noise, sigma=0.25),
}

#: Attacks beyond the thesis's: relabelling, moving and cutting.
EXTRA_ATTACKS: dict[str, Callable[[Mesh, int], Mesh]] = {
    "reorder": _named(reorder_vertices),
    "translate": _named(translate),
    "crop 2%": _named(crop, fraction=0.02),
}

ALL_ATTACKS = {**TABLE_4_1, **EXTRA_ATTACKS}
