"""Shared fixtures: the real CMU/ACCAD motion capture beside the repository."""

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
