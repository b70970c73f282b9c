"""The shipped networks, loaded once per session, run with numpy (Blender ships numpy, not torch).

Weights that cannot be read raise ``WeightsError``, one sentence naming the file and saying to
reinstall the extension; a missing sampler is not an error (the prior's own draws replace it) but
``missing_sampler_note`` says so for the generation report.
"""

import functools
import importlib.util
from pathlib import Path

from .runtime import ASSETS, numpy_model

MODEL_FILE = "trajevae.npz"
SAMPLER_FILE = "sampler.npz"
WeightsError = numpy_model.WeightsError


@functools.cache
def model(folder=ASSETS):
    """The TrajeVAE prior and decoder from ``folder`` (the shipped assets unless told)."""
    return numpy_model.NumpyTrajeVAE(Path(folder) / MODEL_FILE)


@functools.cache
def sampler(folder=ASSETS):
    """The diverse sampler, or None where its weights are not shipped."""
    path = Path(folder) / SAMPLER_FILE
    return numpy_model.NumpySampler(path) if path.exists() else None


def missing_sampler_note(folder=ASSETS):
    """The sentence for the generation report where the sampler's weights are missing, else None."""
    if (Path(folder) / SAMPLER_FILE).exists():
        return None
    return (f"the diverse sampler's weights ({SAMPLER_FILE}) are missing from {folder}, so the variants are "
            f"plain draws of the prior and may look more alike; {numpy_model.REINSTALL} to restore them")


def torch_installed():
    """Whether torch could be imported (only training needs it; shown in the panel)."""
    return importlib.util.find_spec("torch") is not None


def release():
    """Drop the loaded networks (on unregister)."""
    model.cache_clear()
    sampler.cache_clear()
