"""Walking along a path drawn on the floor (issue 17), measured as Blender plays each variant on a
generated Rigify rig: steps, planted feet, the hips on the path and upright, the body facing along
it, no foot through the floor."""

import bpy  # noqa: F401  (first: blender_rigs imports Blender's own modules)
import numpy as np
import pytest

import blender_rigs
import shots
from model_runtime import animation_quality as quality
from trajevae_addon import api

FPS = 30
VARIANTS = 3


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


def test_a_4_m_floor_path_steps_without_the_body_sinking_on_rigify(scene, rigify):
    """What a walk along a ground path holds today (issue 17's targets are in ``make bench-quality``):
    the hips follow the path exactly as played, both feet step, no foot goes through the floor, and
    the pelvis never drops to the floor between feet planted far apart (``retarget.MAX_PELVIS_DROP``;
    it fell 1 m and strayed up to 2.7 m off the path toward the feet before). The model does not yet
    walk along the path by itself: the hips are held on it and the feet partly dragged (planted toes
    0.7-1.3 m/s, hips down to 0.6-0.7 of their standing height, 1-4 steps per foot)."""
    rows = _figures(*_walk(scene, rigify, shots.walk, 120))
    for row in rows:
        assert min(row["steps"]) >= 1
        assert row["away"] <= 0.01 and row["sink"] <= 0.03 and row["hips"] >= 0.55


def test_the_body_faces_along_a_quarter_circle(scene):
    """Issue 17's facing target: within 20 degrees of the path's tangent on every frame, as played
    (``cleanup.facing_the_path``; the model's own body faced up to 86 degrees off it)."""
    scene.render.fps = FPS
    rows = _figures(*_walk(scene, blender_rigs.mannequin_rig(scene), shots.quarter_turn, 120))
    for row in rows:
        assert row["facing"] <= 20.0 and row["away"] <= 0.02
