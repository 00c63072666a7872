"""Denoising whole datasets (``jaxmesh denoise --out-dir``): :mod:`.plan` decides
the files and the padded batch shapes, :mod:`.runner` streams them through one
compiled program per shape."""

from .plan import (LADDER_RATIO, LADDER_START, MESH_SUFFIXES, Batch, default_batch_size, expand_inputs, output_pairs,
                   peek_sizes, plan_batches, rung)
from .runner import DatasetSummary, denoise_files

__all__ = ["LADDER_START", "LADDER_RATIO", "MESH_SUFFIXES", "default_batch_size", "rung", "Batch", "plan_batches",
           "expand_inputs", "output_pairs",
           "peek_sizes", "DatasetSummary", "denoise_files"]
