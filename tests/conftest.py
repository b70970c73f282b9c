"""Shared fixtures: the real CMU/ACCAD motion capture beside the repository, and a Blender scene
with the add-on registered."""

import pytest

from model_runtime.data import dataset


@pytest.fixture(scope="session")
def mocap_root():
    root = dataset.DEFAULT_DATA_ROOT
    assert (root / "MANIFEST.csv").exists(), f"motion capture not found at {root}"
    return root


@pytest.fixture(scope="session")
def manifest(mocap_root):
    return dataset.read_manifest(mocap_root)


@pytest.fixture(scope="session")
def all_clips(mocap_root):
    loaded, errors = dataset.load_clips([mocap_root])
    assert errors == []
    return loaded


@pytest.fixture
def scene():
    """An empty scene (frames 1-60) with the add-on registered; unregistered afterwards."""
    import blender_rigs
    import trajevae_addon
    scene = blender_rigs.fresh_scene()
    trajevae_addon.register()
    yield scene
    trajevae_addon.unregister()
