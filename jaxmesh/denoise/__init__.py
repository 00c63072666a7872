"""Mesh denoising (thesis ch.2): the multivariate kernel flow and every baseline
the thesis compares against, behind one registry (:data:`METHODS`).

Every method is a pure function ``(mesh, **params) -> Mesh`` over the
edge-list segment-sum operators, with a ``lax.fori_loop`` over a static
iteration count: jittable, batched over leading vertex dimensions and
differentiable with respect to its continuous parameters and the positions.
"""

from ._loop import progress
from .anisotropic import anisotropic_diffusion
from .bilateral_normal import bilateral_normal_filtering, joint_bilateral_normals, spatial_weights
from .face_graph import FaceGraph, RingTier, centroid_spacing, face_centroids, face_graph
from .tiers import RING_TIERS, ring_tiers
from .guided import guidance_normals, guided_normal_filtering, patch_inconsistency
from .impulse_repair import impulse_repair, mixture_posterior, scale_mixture
from .l0 import edge_operator, l0_denoising, mean_dihedral_angle
from .vertex_update import vertex_update
from .bilateral import bilateral_denoising
from .curvature import cotangent_flow, implicit_diffusion_step
from .geometric_diffusion import anisotropic_stiffness, face_curvatures, geometric_diffusion
from .kernel_flow import (
    VARIANTS,
    kernel_diffusion,
    kernel_step,
    kernel_weights,
    neighborhood_covariances,
)
from .vertex_rings import VertexRings, VertexTier, ring_umbrella, vertex_rings
from .kde import kernel_density
from .laplacian import hc_smoothing, taubin_smoothing, umbrella_flow
from .normal_filtering import FaceRings, face_rings, filter_normals, normal_filtering, ring_sum
from .registry import METHODS, Method, Param, as_method, denoise, diverged
from .framed import denoise_in_unit_frame
from .packed import denoise_packed, packed_run, run_packed
from .selection import hold, pin_weights, region_weights, selection_mask

__all__ = [
    "METHODS", "Method", "Param", "as_method", "denoise", "diverged", "progress", "denoise_in_unit_frame",
    "denoise_packed", "packed_run", "run_packed",
    "VARIANTS", "kernel_diffusion", "kernel_step", "kernel_weights", "neighborhood_covariances",
    "VertexRings", "VertexTier", "vertex_rings", "ring_umbrella",
    "hold", "region_weights", "pin_weights", "selection_mask",
    "kernel_density",
    "anisotropic_diffusion", "umbrella_flow", "taubin_smoothing", "hc_smoothing", "cotangent_flow",
    "implicit_diffusion_step", "normal_filtering", "filter_normals", "face_rings", "FaceRings",
    "ring_sum", "bilateral_denoising", "geometric_diffusion", "anisotropic_stiffness",
    "face_curvatures",
    "FaceGraph", "RingTier", "RING_TIERS", "face_graph", "ring_tiers", "face_centroids", "centroid_spacing",
    "vertex_update",
    "bilateral_normal_filtering", "joint_bilateral_normals", "spatial_weights",
    "guided_normal_filtering", "guidance_normals", "patch_inconsistency",
    "l0_denoising", "edge_operator", "mean_dihedral_angle",
    "impulse_repair", "scale_mixture", "mixture_posterior",
]
