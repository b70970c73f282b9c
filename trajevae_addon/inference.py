"""The shipped networks, loaded once per session, run with numpy (Blender ships numpy, not torch)."""

import functools
import importlib.util

from .runtime import ASSETS, numpy_model

MODEL_FILE = ASSETS / "trajevae.npz"
SAMPLER_FILE = ASSETS / "sampler.npz"


@functools.cache
def model():
    return numpy_model.NumpyTrajeVAE(MODEL_FILE)


@functools.cache
def sampler():
    """The diverse sampler, or None where its weights are not shipped."""
    return numpy_model.NumpySampler(SAMPLER_FILE) if SAMPLER_FILE.exists() else None


def torch_installed():
    """Whether torch could be imported (only training needs it; shown in the panel)."""
    return importlib.util.find_spec("torch") is not None


def release():
    """Drop the loaded networks (on unregister)."""
    model.cache_clear()
    sampler.cache_clear()
