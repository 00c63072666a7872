"""Trainable denoisers: an unrolled stack of the registry's differentiable filters whose
parameters are learned from data (:mod:`~jaxmesh.learn.model`), their files
(:mod:`~jaxmesh.learn.modelfile`) and their training (:mod:`~jaxmesh.learn.training`)."""

from .model import *  # noqa: F401,F403
from .modelfile import *  # noqa: F401,F403
from .training import *  # noqa: F401,F403
from . import model as _model, modelfile as _modelfile, training as _training

__all__ = [*_model.__all__, *_modelfile.__all__, *_training.__all__]
