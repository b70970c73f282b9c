"""Shipped weights as .npz: arrays plus the config as JSON. No pickled code is ever loaded."""

import json
from pathlib import Path

import numpy as np
import torch

from . import numpy_model

# A weights folder: what the add-on needs, as the training commands write it (--out DIR).
MODEL_FILE, SAMPLER_FILE, LIMITS_FILE = numpy_model.MODEL_FILE, numpy_model.SAMPLER_FILE, numpy_model.LIMITS_FILE
CARD_FILE = "MODEL_CARD.md"
ASSETS = Path(__file__).resolve().parents[1] / "assets"  # the bundled weights folder
MODEL_WEIGHTS = ASSETS / MODEL_FILE
SAMPLER_WEIGHTS = ASSETS / SAMPLER_FILE
RESTORE = "restore it from the repository (git) or train it again (make train, make train-sampler)"


def model_file(path):
    """The model's .npz: ``path`` itself if it is one, else in the weights folder ``path``."""
    path = Path(path)
    return path if path.suffix == ".npz" else path / MODEL_FILE


def save(path, module, config, extra=None):
    """Write a module's parameters (float32) with its config and any extra JSON-able facts."""
    arrays = {name: tensor.detach().cpu().numpy().astype(np.float32)
              for name, tensor in module.state_dict().items()}
    meta = {"config": config.to_dict(), **(extra or {})}
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    temporary = path.with_suffix(".tmp.npz")
    np.savez_compressed(temporary, __meta__=np.array(json.dumps(meta)), **arrays)
    temporary.replace(path)


def load_state(path):
    """(state dict of tensors, meta dict) from a file written by ``save``; the add-on's checked,
    unpickle-free reader, so a missing or damaged file is one sentence (``WeightsError``)."""
    arrays, meta = numpy_model.load_arrays(path, remedy=RESTORE)
    return {name: torch.from_numpy(array) for name, array in arrays.items()}, meta


def load(path, module_class, config_class):
    """(module in eval mode, meta dict) from a file written by ``save``."""
    state, meta = load_state(path)
    module = module_class(config_class(**meta["config"]))
    module.load_state_dict(state)
    return module.eval(), meta


def load_model(path=MODEL_WEIGHTS):
    from .model import ModelConfig, TrajeVAE
    return load(path, TrajeVAE, ModelConfig)


def load_sampler(path=SAMPLER_WEIGHTS):
    from .sampler import DiverseSampler, SamplerConfig
    return load(path, DiverseSampler, SamplerConfig)
