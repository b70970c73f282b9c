"""TrajeVAE with the shipped weights on real validation windows, and the training command."""

import json

import numpy as np
import pytest
import torch

from model_runtime import masks, metrics, train, weights
from model_runtime.data import dataset
from model_runtime.model import ModelConfig, TrajeVAE


@pytest.fixture(scope="module")
def model():
    loaded, meta = weights.load_model()
    return loaded


@pytest.fixture(scope="module")
def validation_windows(all_clips, manifest):
    _, validation = dataset.split_by_subject(all_clips, manifest)
    return dataset.windows(validation, future=60, stride=60)[:24]


def test_shipped_weights_are_small_plain_arrays():
    assert weights.MODEL_WEIGHTS.stat().st_size < 30 * 2 ** 20
    with np.load(weights.MODEL_WEIGHTS, allow_pickle=False) as stored:
        meta = json.loads(str(stored["__meta__"]))
    assert meta["validation_subjects"] == list(dataset.VALIDATION_SUBJECTS)
    assert ModelConfig(**meta["config"]) == ModelConfig()


def test_samples_start_at_the_initial_pose_and_differ(model, validation_windows):
    initial = torch.from_numpy(validation_windows[:, 0])
    empty = torch.zeros(len(validation_windows), 60, 17)
    generator = torch.Generator().manual_seed(0)
    samples = model.sample(initial, torch.zeros(len(validation_windows), 60, 17, 3), empty, 5,
                           generator=generator).numpy()
    first_step = np.linalg.norm(samples[:, :, 0] - validation_windows[:, None, 0], axis=-1)
    assert first_step.mean() < 0.05  # 1/30 s after the initial pose
    assert np.mean([metrics.diversity(metrics.to_protocol(s))[0] for s in samples]) > 0.1
    again = model.sample(initial, torch.zeros(len(validation_windows), 60, 17, 3), empty, 5,
                         generator=torch.Generator().manual_seed(0)).numpy()
    np.testing.assert_array_equal(samples, again)


def test_given_trajectories_are_followed(model, validation_windows):
    """Conditioning on the four trajectories brings those joints far closer than none, in the
    decoder's own output (samples then set them exactly, so those are not what is measured)."""
    initial = torch.from_numpy(validation_windows[:, 0])
    future = validation_windows[:, 1:]
    mask = masks.evaluation_mask(4, 60)
    errors = {}
    for k in (0, 4):
        known = torch.from_numpy(np.broadcast_to(masks.evaluation_mask(k, 60), (len(future), 60, 17)).copy())
        with torch.no_grad():
            prior_mean, _, encoded = model.prior(initial, torch.from_numpy(future) * known[..., None], known)
            motion = model.decode(prior_mean, encoded)
        errors[k] = metrics.trajectory_error(motion.numpy(), future, mask)
    print(f"decoder's trajectory error of the conditioned joints: {errors}")
    assert errors[4] < 0.1
    assert errors[4] < 0.5 * errors[0]  # the product then puts them on the curves exactly (limb solve)


def test_training_runs_checkpoints_and_resumes(tmp_path):
    out, checkpoint = tmp_path / "model.npz", tmp_path / "run.pt"
    common = ["--out", str(out), "--checkpoint", str(checkpoint), "--batch", "8"]
    assert train.main(["--steps", "2", "--fresh"] + common) == 0
    assert out.exists() and checkpoint.exists()
    state = torch.load(checkpoint, weights_only=True)
    assert state["step"] == 2
    assert train.main(["--steps", "3"] + common) == 0
    assert torch.load(checkpoint, weights_only=True)["step"] == 3
    loaded, meta = weights.load(out, TrajeVAE, ModelConfig)
    assert meta["step"] in (2, 3)


def test_evaluate_prints_and_writes_every_method_and_k(tmp_path, capsys, mocap_root):
    from model_runtime import evaluate
    report = tmp_path / "eval.json"
    clip = mocap_root / "cmu_mb_01-09" / "02" / "02_01.bvh"
    assert evaluate.main(["--data", str(clip), "--samples", "4", "--stride", "30", "--json", str(report)]) == 0
    result = json.loads(report.read_text())
    assert set(result) == {"methods", "ground_truth", "windows", "samples", "seconds"}
    shipped = set(evaluate.METHODS) if weights.SAMPLER_WEIGHTS.exists() else set(evaluate.METHODS) - {"sampler"}
    assert set(result["methods"]) == shipped
    for method, by_k in result["methods"].items():
        assert set(by_k) == ({"0"} if method == "sampler" else {"0", "1", "2", "3", "4"})  # as the add-on uses it
        assert all(set(row) == set(evaluate.METRICS) for row in by_k.values())
    assert result["methods"]["pinned_pose"]["2"]["traj_err"] == 0.0
    assert result["methods"]["trajevae"]["0"]["APD"] > 0
    assert "nearest_neighbour" in capsys.readouterr().out
