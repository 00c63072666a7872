"""Result and error types shared by the connectivity coders (:mod:`.traversal`,
the fallback in :mod:`.connectivity`)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["SYMBOLS", "ConnectivityCode", "ConnectivityError", "NotManifold"]

SYMBOLS = "NLRESM"


class ConnectivityError(ValueError):
    """A connectivity block that cannot be decoded (corrupt or truncated)."""


class NotManifold(ValueError):
    """The mesh cannot be coded by the traversal coder (the reason is the message)."""


@dataclass(frozen=True)
class ConnectivityCode:
    """Result of :func:`encode_connectivity`.

    ``data``: the coded bytes; ``fallback``: whether the fallback coder was used
    (and ``reason`` why); ``order``: (V,) original index of each decoded vertex;
    ``faces``: (F, 3) the faces exactly as the decoder will return them, in the
    decoded numbering; ``symbols``: count of each traversal symbol.
    """

    data: bytes
    fallback: bool
    order: np.ndarray
    faces: np.ndarray
    symbols: dict
    reason: str = ""
