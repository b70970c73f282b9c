"""The networks in use, loaded once per weights folder, run with numpy (Blender ships numpy, not torch).

The bundled weights (the extension's assets) unless the artist picks another weights folder
(a studio's own training, ``python -m model_runtime.train --out FOLDER``) in the add-on's
preferences or with ``api.use_weights``. A folder is checked when it is picked (a trial run:
arrays that do not fit their configuration, a sampler made for another model, non-finite
numbers) and refused with one sentence, ``WeightsError``, the weights in use left as they were.
A missing sampler is not an error (the prior's own draws replace it), but
``missing_sampler_note`` says so for the generation report.
"""

import functools
import importlib.util
from pathlib import Path

from .runtime import ASSETS, numpy_model

MODEL_FILE = numpy_model.MODEL_FILE
SAMPLER_FILE = numpy_model.SAMPLER_FILE
WeightsError = numpy_model.WeightsError

_in_use = {"folder": ASSETS.resolve(), "refused": None}


def _remedy(folder):
    if folder == ASSETS.resolve():
        return numpy_model.REINSTALL
    return (f"train it again (python -m model_runtime.train --out {folder}, then python -m "
            f"model_runtime.train_sampler --weights {folder}) or pick another weights folder in the add-on's preferences")


@functools.cache
def _loaded(folder):
    return numpy_model.load_folder(folder, _remedy(folder))


def _folder(folder):
    return _in_use["folder"] if folder is None else Path(folder).resolve()


def networks(folder=None):
    """(model, sampler or None) of a weights folder, the one in use unless told."""
    return _loaded(_folder(folder))


def model(folder=None):
    """The TrajeVAE prior and decoder of a weights folder (the one in use unless told)."""
    return networks(folder)[0]


def sampler(folder=None):
    """The diverse sampler of a weights folder (the one in use unless told), or None where it has none."""
    return networks(folder)[1]


def use_weights(folder=None):
    """Check a weights folder and generate with it from now on (None or "": the bundled weights).
    Returns the folder; a folder that cannot be used raises WeightsError and is remembered
    (``refused``) for the panel, the weights in use unchanged."""
    folder = ASSETS.resolve() if folder in (None, "") else Path(folder).resolve()
    try:
        networks(folder)
    except WeightsError as error:
        _in_use["refused"] = str(error)
        raise
    _in_use.update(folder=folder, refused=None)
    return folder


def in_use():
    """The weights folder generations use."""
    return _in_use["folder"]


def bundled():
    """Whether the weights in use are the extension's own."""
    return _in_use["folder"] == ASSETS.resolve()


def refused():
    """The sentence of the last weights folder that could not be used, else None."""
    return _in_use["refused"]


def missing_sampler_note(folder=None):
    """The sentence for the generation report where the sampler's weights are missing, else None."""
    folder = _folder(folder)
    if (folder / SAMPLER_FILE).exists():
        return None
    return (f"the diverse sampler's weights ({SAMPLER_FILE}) are missing from {folder}, so the variants are "
            f"plain draws of the prior and may look more alike; {_remedy(folder)} to restore them")


def torch_installed():
    """Whether torch could be imported (only training needs it; shown in the panel)."""
    return importlib.util.find_spec("torch") is not None


def release():
    """Drop the loaded networks and go back to the bundled weights (on unregister)."""
    _loaded.cache_clear()
    _in_use.update(folder=ASSETS.resolve(), refused=None)
