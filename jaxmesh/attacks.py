"""Deprecated: the hash attacks moved to :mod:`jaxmesh.hash.attacks` (beside the
hashes they test) in 0.2; this alias is removed in 0.3."""

import warnings

from .hash import attacks as _attacks

__all__ = list(_attacks.__all__)
globals().update({name: getattr(_attacks, name) for name in __all__})

warnings.warn("jaxmesh.attacks moved to jaxmesh.hash.attacks (this alias is removed in 0.3)",
              DeprecationWarning, stacklevel=2)
