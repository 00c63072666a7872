"""jaxmesh.render: the painter's-algorithm renderer used by the figures."""

from __future__ import annotations

import numpy as np
import pytest

matplotlib = pytest.importorskip("matplotlib")
matplotlib.use("Agg")


def test_render_draws_every_face_and_center_moves_the_frame(tetra):
    import matplotlib.pyplot as plt

    from jaxmesh.render import render, view_rotation

    v = np.asarray(tetra.vertices)
    ax1 = render(tetra)
    assert len(ax1.collections[0].get_paths()) == tetra.num_faces
    mid = 0.5 * (v.min(0) + v.max(0))
    d = np.array([0.3, -0.2, 0.1])
    ax2 = render(tetra, center=mid + d)
    shift = view_rotation(15.0, 20.0) @ d  # view coordinates move by -R d
    np.testing.assert_allclose(np.subtract(ax2.get_xlim(), ax1.get_xlim()), -shift[0], atol=1e-12)
    np.testing.assert_allclose(np.subtract(ax2.get_ylim(), ax1.get_ylim()), -shift[1], atol=1e-12)
    plt.close("all")
