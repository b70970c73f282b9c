"""Missing, truncated or corrupt weights: the shipped files, copied to a temporary folder and
damaged there, give one sentence naming the file and what to do, never a numpy or zipfile
traceback, and nothing pickled is ever loaded."""

import shutil

import numpy as np
import pytest

from model_runtime import numpy_model, weights
from trajevae_addon import inference
from trajevae_addon.runtime import ASSETS


@pytest.fixture
def assets(tmp_path):
    for name in (inference.MODEL_FILE, inference.SAMPLER_FILE):
        shutil.copy(ASSETS / name, tmp_path / name)
    yield tmp_path
    inference.release()


def _flip_bytes(path):
    """Damage a file the way a bad download or disk does: a few bits flipped across it."""
    data = bytearray(path.read_bytes())
    for position in np.linspace(len(data) // 10, len(data) - 1000, 7).astype(int):
        data[position] ^= 0x10
    path.write_bytes(bytes(data))


class _Planted:
    """Unpickling this would create the file named (what a malicious weights file could do)."""

    def __init__(self, path):
        self.path = str(path)

    def __reduce__(self):
        return open, (self.path, "w")


DAMAGE = {
    "deleted": lambda path: path.unlink(),
    "cut in half": lambda path: path.write_bytes(path.read_bytes()[: path.stat().st_size // 2]),
    "last bytes cut": lambda path: path.write_bytes(path.read_bytes()[:-100]),
    "empty": lambda path: path.write_bytes(b""),
    "bits flipped": _flip_bytes,
    "not an archive": lambda path: path.write_text("<html>404 Not Found</html>"),
    "a pickled array": lambda path: np.savez(path, __meta__=np.array("{}"),
                                             weight=np.array([_Planted(path.with_name("planted"))], dtype=object)),
}


def _says(error, name):
    """One sentence naming the file and what to do: for a weights folder other than the extension's
    own, train it again or pick another (the extension's own say to reinstall: test_packaging)."""
    message = str(error)
    assert isinstance(error, ValueError)
    assert name in message and "train it again" in message and "\n" not in message


def test_shipped_weights_load_from_a_given_folder(assets):
    assert inference.model(assets).frames == inference.model().frames
    assert inference.sampler(assets) is not None and inference.missing_sampler_note(assets) is None
    assert inference.missing_sampler_note() is None


@pytest.mark.parametrize("damage", DAMAGE)
def test_damaged_model_weights_are_one_sentence(assets, damage):
    DAMAGE[damage](assets / inference.MODEL_FILE)
    with pytest.raises(inference.WeightsError) as refused:
        inference.model(assets)
    _says(refused.value, inference.MODEL_FILE)
    assert not (assets / "planted").exists()  # nothing was unpickled


@pytest.mark.parametrize("damage", [name for name in DAMAGE if name != "deleted"])
def test_damaged_sampler_weights_are_one_sentence(assets, damage):
    DAMAGE[damage](assets / inference.SAMPLER_FILE)
    with pytest.raises(inference.WeightsError) as refused:
        inference.sampler(assets)
    _says(refused.value, inference.SAMPLER_FILE)
    assert not (assets / "planted").exists()


LIMITS_DAMAGE = {
    "not JSON": lambda path: path.write_text("<html>404 Not Found</html>"),
    "cut in half": lambda path: path.write_text(path.read_text()[: len(path.read_text()) // 2]),
    "other angles": lambda path: path.write_text(path.read_text().replace("right_elbow", "right_wrist")),
    "a limit short": lambda path: path.write_text(path.read_text().replace('"low": [', '"low": [0.0, ', 1)),
}


@pytest.mark.parametrize("damage", LIMITS_DAMAGE)
def test_damaged_joint_angle_limits_are_one_sentence(assets, damage):
    """The limits beside the weights screen the variants (``selection``): damaged, they are refused
    with the weights, not used half-read."""
    shutil.copy(ASSETS / numpy_model.LIMITS_FILE, assets / numpy_model.LIMITS_FILE)
    assert inference.model(assets) is not None
    inference.release()
    LIMITS_DAMAGE[damage](assets / numpy_model.LIMITS_FILE)
    with pytest.raises(inference.WeightsError) as refused:
        inference.model(assets)
    _says(refused.value, numpy_model.LIMITS_FILE)


def test_a_missing_sampler_is_said_in_the_report_not_silently_replaced(assets):
    (assets / inference.SAMPLER_FILE).unlink()
    assert inference.sampler(assets) is None  # generation goes on with the prior's own draws
    note = inference.missing_sampler_note(assets)
    assert inference.SAMPLER_FILE in note and "model_runtime.train_sampler" in note and "\n" not in note
    assert inference.model(assets) is not None


def test_the_training_loader_reads_through_the_same_checks(assets):
    _flip_bytes(assets / inference.MODEL_FILE)
    with pytest.raises(numpy_model.WeightsError, match=inference.MODEL_FILE):
        weights.load_model(assets / inference.MODEL_FILE)
    loaded, meta = weights.load_sampler(ASSETS / inference.SAMPLER_FILE)
    assert meta["config"] and not loaded.training
