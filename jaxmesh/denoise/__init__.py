"""Mesh denoising (thesis ch.2).  Work in progress: the kernel flow is here;
the baselines, the method registry and batching helpers follow (issue 3)."""

from .kernel_flow import (
    VARIANTS,
    kernel_diffusion,
    kernel_step,
    kernel_weights,
    neighborhood_covariances,
)

__all__ = ["VARIANTS", "kernel_diffusion", "kernel_step", "kernel_weights", "neighborhood_covariances"]
