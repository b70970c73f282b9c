"""Training on a studio's own motion library: a naming of its own with a mapping file, data-parallel
training under torchrun (two CPU processes) with resume on one, fine-tuning the bundled weights into
a weights folder, evaluating it beside the bundled ones, and generating with it in Blender."""

import json
import re
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import torch

from model_runtime import evaluate, train, train_sampler, weights
from model_runtime.data import dataset, profiles

ROOT = Path(__file__).resolve().parents[1]
# A game-engine naming no built-in profile knows: the CMU MotionBuilder bone -> the studio's name.
STUDIO_NAMES = {"RightUpLeg": "thigh_r", "RightLeg": "calf_r", "RightFoot": "foot_r", "LeftUpLeg": "thigh_l",
                "LeftLeg": "calf_l", "LeftFoot": "foot_l", "Neck": "neck_01", "Head": "head_01",
                "LeftArm": "upperarm_l", "LeftForeArm": "lowerarm_l", "LeftHand": "hand_l",
                "RightArm": "upperarm_r", "RightForeArm": "lowerarm_r", "RightHand": "hand_r"}
MAPPING = {"RHip": "thigh_r", "RKnee": "calf_r", "RFoot": "foot_r", "LHip": "thigh_l", "LKnee": "calf_l",
           "LFoot": "foot_l", "Thorax": "neck_01", "Neck": "head_01", "LShoulder": "upperarm_l",
           "LElbow": "lowerarm_l", "LWrist": ["wrist_l", "hand_l"], "RShoulder": "upperarm_r",
           "RElbow": "lowerarm_r", "RWrist": "hand_r"}


def _renamed(source, target):
    """A copy of a BVH file with its bones renamed to ``STUDIO_NAMES`` (the motion unchanged)."""
    pattern = re.compile(r"^(\s*(?:ROOT|JOINT)\s+)(\S+)(\s*)$", re.MULTILINE)
    text = pattern.sub(lambda m: m.group(1) + STUDIO_NAMES.get(m.group(2), m.group(2)) + m.group(3),
                       source.read_text())
    target.parent.mkdir(parents=True, exist_ok=True)
    target.write_text(text)


@pytest.fixture(scope="module")
def library(tmp_path_factory, mocap_root):
    """Four CMU clips in the studio's naming (three to train on, one held out) and its mapping file."""
    folder = tmp_path_factory.mktemp("studio_library")
    subject = mocap_root / "cmu_mb_01-09" / "01"
    for name in ("01_01", "01_02", "01_03"):
        _renamed(subject / f"{name}.bvh", folder / "train" / f"{name}.bvh")
    _renamed(mocap_root / "cmu_mb_01-09" / "02" / "02_01.bvh", folder / "held_out" / "02_01.bvh")
    (folder / "mapping.json").write_text(json.dumps(MAPPING, indent=1))
    return folder


def _data(library):
    return ["--data", str(library / "train"), "--validation", str(library / "held_out"),
            "--mapping", str(library / "mapping.json")]


def _losses(output):
    """The mean training losses of the progress lines (each over the steps since the previous line)."""
    return [float(value) for value in re.findall(r"step \d+/\d+ loss ([\d.]+)", output)]


def test_a_library_in_its_own_naming_is_read_through_its_mapping_file(library):
    custom = (profiles.read_mapping(library / "mapping.json"),)
    split = dataset.training_split([library / "train"], [library / "held_out"], custom)
    assert (len(split.train), len(split.validation), split.errors) == (3, 1, [])
    assert all(clip.profile == "mapping mapping.json" for clip in split.train + split.validation)
    # The same motion as the original naming: mapping changes names, not joints.
    original, _ = dataset.load_clips([ROOT.parent / "shared" / "mocap" / "cmu_mb_01-09" / "01" / "01_01.bvh"])
    mapped = next(clip for clip in split.train if clip.file.endswith("01_01.bvh"))
    np.testing.assert_allclose(mapped.positions, original[0].positions, atol=1e-5)

    unmapped = subprocess.run([sys.executable, "-m", "model_runtime.train", "--data", str(library / "train"),
                               "--out", str(library / "never")], cwd=ROOT, capture_output=True, text=True)
    assert unmapped.returncode == 2
    assert "cannot map joints" in unmapped.stderr and "0 training and 0 validation clips" in unmapped.stderr

    broken = dict(MAPPING)
    del broken["LWrist"]
    broken["Tail"] = "tail_01"
    (library / "broken.json").write_text(json.dumps(broken))
    with pytest.raises(ValueError, match="names unknown joints Tail; lacks LWrist"):
        profiles.read_mapping(library / "broken.json")


def test_two_processes_train_in_step_and_one_process_resumes_their_checkpoint(tmp_path, library):
    checkpoint = tmp_path / "run.pt"
    common = _data(library) + ["--out", str(tmp_path / "weights"), "--checkpoint", str(checkpoint), "--batch", "4",
                               "--learning-rate", "1e-3", "--warmup", "5", "--log-every", "10", "--completion-steps", "0",
                               "--threads", "1"]
    two = subprocess.run([sys.executable, "-m", "torch.distributed.run", "--standalone", "--nproc_per_node=2",
                          "-m", "model_runtime.train", "--steps", "20", "--fresh"] + common,
                         cwd=ROOT, capture_output=True, text=True, timeout=600)
    assert two.returncode == 0, two.stderr[-3000:]
    print(two.stdout)
    assert "2 process(es), global batch 8" in two.stdout
    assert "2 processes: weights identical after each of 20 steps" in two.stdout  # checked after every step
    assert two.stdout.count("TrajeVAE 1,") == 1  # rank 0 alone logs
    losses = _losses(two.stdout)
    assert len(losses) == 2 and losses[1] < losses[0]
    assert torch.load(checkpoint, weights_only=True)["step"] == 20

    one = subprocess.run([sys.executable, "-m", "model_runtime.train", "--steps", "30"] + common,
                         cwd=ROOT, capture_output=True, text=True, timeout=600)
    assert one.returncode == 0, one.stderr[-3000:]
    print(one.stdout)
    assert f"resumed from {checkpoint} at step 20" in one.stdout
    assert "1 process(es), global batch 4" in one.stdout
    assert torch.load(checkpoint, weights_only=True)["step"] == 30
    assert _losses(one.stdout)[0] < losses[0]


@pytest.fixture(scope="module")
def studio_weights(tmp_path_factory, library):
    """The bundled weights fine-tuned for a few steps on the library without dropout (the bundled
    trained with it), and its sampler: a weights folder."""
    out = tmp_path_factory.mktemp("studio_weights")
    runs = tmp_path_factory.mktemp("runs")
    assert train.main(_data(library) + ["--init", str(weights.ASSETS), "--out", str(out), "--steps", "3",
                                        "--completion-steps", "1", "--batch", "4", "--dropout", "0", "--checkpoint",
                                        str(runs / "model.pt")]) == 0
    assert train_sampler.main(_data(library) + ["--weights", str(out), "--steps", "2", "--batch", "2",
                                                "--checkpoint", str(runs / "sampler.pt")]) == 0
    return out


def test_fine_tuning_writes_a_weights_folder_with_everything_the_addon_needs(studio_weights, library):
    assert {path.name for path in studio_weights.iterdir()} == {
        weights.MODEL_FILE, weights.SAMPLER_FILE, weights.LIMITS_FILE, weights.CARD_FILE}
    _, meta = weights.load_state(studio_weights / weights.MODEL_FILE)
    assert meta["init"] == str(weights.ASSETS) and meta["data"]["train_clips"] == 3
    assert meta["config"]["dropout"] == 0.0
    card = (studio_weights / weights.CARD_FILE).read_text()
    assert f"Fine-tuned from the weights then in `{weights.ASSETS}`" in card and f"files under {library / 'held_out'}" in card
    assert "Not evaluated yet" in card


def test_evaluate_compares_a_weights_folder_with_the_bundled_weights(studio_weights, library, tmp_path):
    report = tmp_path / "eval.json"
    assert evaluate.main(["--weights", str(studio_weights), "--data", str(library / "held_out"), "--mapping",
                          str(library / "mapping.json"), "--samples", "3", "--stride", "60",
                          "--json", str(report)]) == 0
    methods = json.loads(report.read_text())["methods"]
    assert {"trajevae", "sampler", "bundled:trajevae", "bundled:sampler"} <= set(methods)
    assert methods["trajevae"]["k"]["0"]["ADE"] != methods["bundled:trajevae"]["k"]["0"]["ADE"]


def _damaged_copy(folder, target, file_name, array_name):
    """A copy of a weights folder with one array of one file cut by a row: a shape its configuration
    does not give."""
    shutil.copytree(folder, target)
    with np.load(target / file_name, allow_pickle=False) as stored:
        arrays = dict(stored)
    arrays[array_name] = arrays[array_name][:-1]
    np.savez(target / file_name, **arrays)
    return target


def test_blender_generates_with_a_chosen_weights_folder_and_refuses_a_broken_one(scene, studio_weights, tmp_path):
    import blender_rigs
    from trajevae_addon import api, inference
    rig = blender_rigs.mannequin_rig(scene)
    scene.frame_end = 30
    assert api.use_weights(studio_weights) == str(studio_weights.resolve())
    assert inference.in_use() == studio_weights.resolve() and not inference.bundled()
    made = api.generate_variants(rig, n=2)
    assert len(made) == 2 and rig.animation_data.action == made[0]
    assert inference.networks()[0].meta["init"] == str(weights.ASSETS)

    misfit = _damaged_copy(studio_weights, tmp_path / "misfit", weights.MODEL_FILE, "decoder_output.2.weight")
    with pytest.raises(ValueError) as refused:
        api.use_weights(misfit)
    message = str(refused.value)
    assert str(misfit) in message and "does not fit its own configuration" in message and "\n" not in message
    assert inference.in_use() == studio_weights.resolve() and inference.refused() == message

    other = _damaged_copy(studio_weights, tmp_path / "other_sampler", weights.SAMPLER_FILE, "condition.0.bias")
    with pytest.raises(ValueError, match="was not trained for its model"):
        api.use_weights(other)
    with pytest.raises(ValueError, match="does not exist"):
        api.use_weights(tmp_path / "nowhere")
    assert api.use_weights(None) == str(weights.ASSETS.resolve()) and inference.bundled()
    assert inference.refused() is None
