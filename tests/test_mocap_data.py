"""The motion pipeline on the real CMU/ACCAD sets in ../shared/mocap and ../shared/mocap-extra."""

import json
from pathlib import Path

import numpy as np
import pytest

from model_runtime import skeleton
from model_runtime.data import __main__ as data_cli
from model_runtime.data import clips, dataset


def _rows(manifest, all_clips):
    return [(clip, manifest[Path(clip.file).resolve()]) for clip in all_clips]


def _walks(manifest, all_clips):
    """Forward walks on flat ground longer than 2 s (descriptions from the manifest)."""
    excluded = ("back", "side", "terrain", "run", "jump")
    return [clip for clip, row in _rows(manifest, all_clips)
            if "walk" in row["description"].lower() and clip.seconds > 2
            and not any(word in row["description"].lower() for word in excluded)]


def test_every_manifest_clip_loads_with_its_convention(manifest, all_clips):
    assert {Path(c.file).resolve() for c in all_clips} == set(manifest)
    for clip, row in _rows(manifest, all_clips):
        assert clip.profile == row["naming"], clip.file
        assert clip.fps == clips.NATIVE_FPS


def test_rigid_bones_keep_their_length_within_1mm(all_clips):
    rigid = np.array(skeleton.indices(skeleton.RIGID_BONE_JOINTS)) - 1
    for clip in all_clips:
        lengths = skeleton.bone_lengths(clip.positions.astype(np.float64))[:, rigid]
        assert np.all(lengths.max(0) - lengths.min(0) < 1e-3), clip.file
        assert np.all(lengths > 0.03), clip.file


def test_heights_are_adult_and_real_ones_are_kept(manifest, all_clips):
    heights = np.array([clip.height_m for clip in all_clips])
    assert heights.min() >= 1.3 and heights.max() <= 2.0
    by_subject = {}
    for clip, row in _rows(manifest, all_clips):
        by_subject.setdefault(row["subject"], []).append(clip.height_m)
    assert 1.43 < np.median(by_subject["CMU 144"]) < 1.5  # short, as captured (not rescaled)
    assert 1.85 < np.median(by_subject["ACCAD Male1"]) < 1.97  # tall
    assert 1.55 < np.median(by_subject["CMU 94"]) < 1.65  # the DAZ files in centimetres


def test_units_are_detected_per_convention(manifest, all_clips):
    units = {}
    for clip, row in _rows(manifest, all_clips):
        units.setdefault(row["naming"], set()).add(clip.unit)
    assert units["cmu-motionbuilder"] == {"cgspeed"}
    assert units["cmu-3dsmax"] == {"cgspeed"}
    assert units["accad-22"] == {"centimetre"}
    # DAZ naming: rescaled by a publisher to 1.2 m adults in ../shared/mocap, centimetres in mocap-extra
    daz = {row["source"]: clip.unit for clip, row in _rows(manifest, all_clips) if row["naming"] == "daz"}
    assert daz == {"cmu_daz_60-61": "rescaled", "cmu_daz_94_135": "centimetre"}


def test_walking_feet_touch_the_floor(manifest, all_clips):
    """In every half second of a walk, the lowest foot point comes within 5 cm of z = 0."""
    walks = _walks(manifest, all_clips)
    assert len(walks) >= 40
    for clip in walks:
        lowest = clip.soles.min(axis=1)
        contacts = [lowest[start:start + 15].min() for start in range(0, clip.frames - 14, 15)]
        assert abs(np.median(contacts)) < 0.05, clip.file
        assert np.percentile(lowest, 1) > -0.05, clip.file
        ankles = clip.positions[:, skeleton.indices(skeleton.FEET), 2].min(axis=1)
        assert 0.0 < np.median(ankles) < 0.15, clip.file


def test_resampling_keeps_the_duration(manifest, all_clips):
    for clip, row in _rows(manifest, all_clips):
        assert abs(clip.seconds - (clip.source_frames - 1) / clip.source_fps) < 1.0 / clips.NATIVE_FPS, clip.file
        assert clip.source_fps == float(row["fps"])
        assert int(row["frames"]) - 9 <= clip.source_frames <= int(row["frames"]), clip.file


def test_a_converters_t_pose_frame_is_dropped_where_there_is_one(manifest, all_clips):
    """Most cgspeed conversions add a T-pose frame 0, some do not (mocap-extra's README: check each):
    the DAZ files of mocap-extra all have one (their acRNN source has one frame more than the
    same takes in ../shared/mocap), those of ../shared/mocap none; the MotionBuilder files of ../shared/mocap all one, most
    of mocap-extra's one."""
    dropped = {}
    for clip, row in _rows(manifest, all_clips):
        dropped.setdefault(row["source"], []).append(int(row["frames"]) - clip.source_frames)
    assert set(dropped["cmu_daz_94_135"]) == {1}
    assert set(dropped["cmu_daz_60-61"]) == {0}
    assert min(dropped["cmu_mb_01-09"]) >= 1
    assert 0.8 < np.mean(np.array(dropped["cmu_mb_90-144"]) >= 1) < 1.0


def test_left_and_right_are_not_swapped(manifest, all_clips):
    """Walkers move the way they face, where forward = cross(LHip - RHip, Z)."""
    agree, moving = 0, 0
    for clip in _walks(manifest, all_clips):
        root = clip.positions[:, 0, :2]
        velocity = (root[15:] - root[:-15]) * clip.fps / 15
        speed = np.linalg.norm(velocity, axis=-1)
        forward = skeleton.facing(clip.positions[:-15])[:, :2]
        mask = speed > 0.5
        agree += np.sum(np.sum(velocity[mask] * forward[mask], axis=-1) > 0)
        moving += mask.sum()
    assert moving > 1000
    assert agree / moving > 0.95
    # The same check fails on mirrored bodies, so it can tell.
    mirrored = clip.positions[:, skeleton.mirror_permutation()]
    assert np.mean(np.sum(skeleton.facing(mirrored)[:, :2] * skeleton.facing(clip.positions)[:, :2], -1)) < -0.9


def test_both_folders_load_whole(manifest, all_clips, mocap_roots):
    sources = {row["source"] for row in manifest.values()}
    assert {"cmu_mb_90-144", "cmu_daz_94_135", "accad_male1", "cmu_mb_01-09"} <= sources
    assert len(all_clips) == len(manifest) == 354
    minutes = sum(clip.seconds for clip in all_clips) / 60
    assert 55 < minutes < 59


def test_validation_subjects_are_held_out_whole(manifest, all_clips):
    train, validation = dataset.split_by_subject(all_clips, manifest)
    train_subjects = {manifest[Path(c.file).resolve()]["subject"] for c in train}
    validation_subjects = {manifest[Path(c.file).resolve()]["subject"] for c in validation}
    assert validation_subjects == set(dataset.VALIDATION_SUBJECTS)
    assert not train_subjects & validation_subjects
    assert len(train) + len(validation) == len(all_clips)


def test_windows_start_at_the_origin_and_keep_height(all_clips):
    sample = all_clips[:5]
    windows = dataset.windows(sample, future=60, stride=10)
    assert windows.shape[1:] == (61, 17, 3)
    np.testing.assert_allclose(windows[:, 0, 0, :2], 0, atol=1e-5)
    assert np.all(windows[:, 0, 0, 2] > 0.3)  # pelvis stays above the floor
    expected = sum(len(range(0, c.frames - 61 + 1, 10)) for c in sample if c.frames >= 61)
    assert windows.shape[0] == expected


def test_cache_returns_the_same_clip(tmp_path, monkeypatch, mocap_root):
    monkeypatch.setenv("TRAJEVAE_CACHE", str(tmp_path))
    path = mocap_root / "cmu_max_131" / "131_03.bvh"
    (cold,), _ = dataset.load_clips([path])
    assert list(tmp_path.rglob("*.npz"))
    (warm,), _ = dataset.load_clips([path])
    np.testing.assert_array_equal(cold.positions, warm.positions)
    assert (cold.profile, cold.height_m, cold.unit) == (warm.profile, warm.height_m, warm.unit)


def test_stats_cli_prints_json_and_names_bad_files(tmp_path, capsys, mocap_root):
    bad = tmp_path / "no_arms.bvh"
    text = (mocap_root / "cmu_max_131" / "131_03.bvh").read_text()
    bad.write_text(text.replace("LeftWrist", "LeftPaw"))
    good = mocap_root / "cmu_max_131" / "131_01.bvh"
    assert data_cli.main(["stats", str(good), str(bad), "--json"]) == 0
    captured = capsys.readouterr()
    report = json.loads(captured.out)
    assert [Path(c["file"]).name for c in report["clips"]] == ["131_01.bvh"]
    assert set(report["clips"][0]) == {"file", "frames", "seconds", "fps", "height_m", "min_foot_height_m", "profile"}
    assert report["total_seconds"] == pytest.approx(report["clips"][0]["seconds"])
    assert "no_arms.bvh" in captured.err and "LWrist (LeftWrist)" in captured.err
    assert len(captured.err.strip().splitlines()) == 1
