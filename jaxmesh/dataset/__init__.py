"""Denoising whole datasets (``jaxmesh denoise --out-dir``): :mod:`.plan` decides
the files and the packed unions or padded batch shapes, :mod:`.runner` streams them
through one compiled program per shape."""

from .plan import (LADDER_RATIO, LADDER_START, MESH_SUFFIXES, PACK_SEGMENTS, PACK_VERTICES, Batch, default_batch_size,
                   expand_inputs, output_pairs, peek_sizes, plan_batches, plan_packs, rung)
from .runner import DatasetSummary, denoise_files

__all__ = ["LADDER_START", "LADDER_RATIO", "PACK_VERTICES", "PACK_SEGMENTS", "MESH_SUFFIXES", "default_batch_size",
           "rung", "Batch", "plan_batches", "plan_packs", "expand_inputs", "output_pairs",
           "peek_sizes", "DatasetSummary", "denoise_files"]
