"""Sample meshes shipped with jaxmesh (so demos and tests need no download).

* ``bunny``: the Stanford bunny (``bun_zipper``, 34 834 vertices, 5 holes in the
  base).  Stanford 3D Scanning Repository (Turk & Levoy 1994); redistributed
  for research use with credit to the Stanford Computer Graphics Laboratory.
* ``spot``: Keenan Crane's cow "spot" (2 930 vertices, genus 0), released by its
  author into the public domain.

Both were taken unmodified from the project's shared mesh set (binary PLY,
float64 vertices, original vertex order; see ``shared/meshes/MANIFEST.md``).
"""

from __future__ import annotations

from importlib import resources
from pathlib import Path

__all__ = ["SAMPLES", "sample_path", "load_sample"]

SAMPLES = {"bunny": "bunny.ply", "spot": "spot.ply"}


def sample_path(name: str) -> Path:
    """Path of the shipped sample file ``name`` (one of :data:`SAMPLES`).

    Arguments:
        name: a key of :data:`SAMPLES`.

    Returns:
        The file's path inside the installed package."""
    if name not in SAMPLES:
        raise ValueError(f"unknown sample {name!r}; available: {', '.join(sorted(SAMPLES))}")
    return Path(str(resources.files(__package__).joinpath(SAMPLES[name])))


def load_sample(name: str = "bunny", **kwargs):
    """Load a shipped sample mesh as a :class:`jaxmesh.Mesh` (kwargs go to
    :func:`jaxmesh.load`).

    Arguments:
        name: a key of :data:`SAMPLES` (``"bunny"`` or ``"spot"``).
        **kwargs: passed to :func:`jaxmesh.load`.

    Returns:
        The sample as a :class:`~jaxmesh.Mesh`."""
    from ..io import load

    return load(sample_path(name), **kwargs)
