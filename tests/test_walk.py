"""Walking along a path drawn on the floor (issue 17), measured as Blender plays each variant on a
generated Rigify rig and the mannequin: steps, planted feet, the hips on the path and upright, the
body facing along it, no foot through the floor."""

import bpy  # noqa: F401  (first: blender_rigs imports Blender's own modules)
import numpy as np
import pytest

import blender_rigs
import shots
from model_runtime import animation_quality as quality
from model_runtime.generation import WINDOW_OVERLAP
from trajevae_addon import api

FPS = 30
VARIANTS = 3
WINDOW = 60  # the model's window, frames at its 30 fps (the scene's here)


def _walk(scene, rig, setup, frames):
    """Bind the shot's ground path with Walk Along, generate, play: (per variant (joints, toes), the
    path (P, 3), the floor height)."""
    scene.render.fps, scene.frame_start, scene.frame_end = FPS, 1, frames
    curves, _ = setup(rig)
    _, toes = blender_rigs.played(rig, [1])
    api.walk_along(rig, blender_rigs.curve(scene, "floor path", curves["Hip"]))
    played = []
    for action in api.generate_variants(rig, VARIANTS, 0):
        api.set_active_variant(rig, action)
        played.append(blender_rigs.played(rig, range(1, frames + 1)))
    return played, curves["Hip"], quality.floor_height(toes)


def _figures(played, path, floor):
    rows = []
    for joints, toes in played:
        away, facing = quality.path_following(joints, path)
        rows.append({"steps": quality.steps(toes, floor), "planted": quality.planted_toe_speed(toes, FPS, floor),
                     "away": away, "facing": float(facing.max()), "hips": quality.hip_height_share(joints, floor),
                     "sink": quality.floating(toes, floor)[2]})
    for row in rows:
        print(", ".join(f"{name} {value}" if name == "steps" else f"{name} {value:.2f}" for name, value in row.items()))
    return rows


@pytest.fixture
def rigify(scene):
    rig = blender_rigs.rigify_rig(scene)
    yield rig
    blender_rigs.disable_rigify()


def test_a_4_m_floor_path_is_a_walk_with_steps_on_rigify(scene, rigify):
    rows = _figures(*_walk(scene, rigify, shots.walk, 120))
    for row in rows:
        assert min(row["steps"]) >= 2 and max(row["steps"]) <= 5
        assert row["planted"] <= 0.2 and row["away"] <= 0.1 and row["hips"] >= 0.85 and row["sink"] <= 0.01


def test_a_quarter_circle_turns_the_body_along_it(scene, rigify):
    rows = _figures(*_walk(scene, rigify, shots.quarter_turn, 120))
    for row in rows:
        assert row["facing"] <= 20.0 and row["away"] <= 0.1


def test_a_10_m_path_over_300_frames_is_one_walk(scene):
    rig = blender_rigs.mannequin_rig(scene)
    played, path, floor = _walk(scene, rig, shots.long_walk, 300)
    rows = _figures(played, path, floor)
    for (joints, _), row in zip(played, rows):
        per_frame = quality.accelerations(joints, FPS)
        near = np.zeros(len(per_frame), bool)  # within 5 frames of where a window's new frames begin
        for join in range(WINDOW, 300, WINDOW - WINDOW_OVERLAP):
            near[max(join - 6, 0):join + 4] = True
        print(f"acceleration near window joins: median {np.median(per_frame[near]):.1f}, "
              f"elsewhere {np.median(per_frame[~near]):.1f} m/s^2")
        assert np.median(per_frame[near]) <= 1.25 * np.median(per_frame[~near])
        assert min(row["steps"]) >= 5 and row["planted"] <= 0.2 and row["away"] <= 0.1
