"""Shared fixtures: the real CMU/ACCAD motion capture beside the repository (../shared/mocap and
../shared/mocap-extra), and a Blender scene with the add-on registered."""

import pytest

from model_runtime.data import dataset


@pytest.fixture(scope="session")
def mocap_roots():
    for root in dataset.DATA_ROOTS:
        assert (root / "MANIFEST.csv").exists(), f"motion capture not found at {root}"
    return dataset.DATA_ROOTS


@pytest.fixture(scope="session")
def mocap_root(mocap_roots):
    """../shared/mocap, whose files some tests name."""
    return mocap_roots[0]


@pytest.fixture(scope="session")
def manifest(mocap_roots):
    return dataset.read_manifest(mocap_roots)


@pytest.fixture(scope="session")
def all_clips(mocap_roots):
    loaded, errors = dataset.load_clips(mocap_roots)
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
