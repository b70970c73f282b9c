"""Hostile input (issue 14): degenerate, huge, far and non-finite curves, odd rig transforms and
parents, odd arguments, and rigs edited between the steps of a generation. For every one, with
real bpy and the shipped weights: no traceback reaches the user, no non-finite key is written,
the artist's actions and pose are as they were afterwards, and nothing is left behind."""

import math

import bpy
import numpy as np
import pytest

import blender_rigs
from model_runtime.skeleton import JOINT_INDEX
from trajevae_addon import api, pipeline, rig_state

NAN, INF = float("nan"), float("inf")


def _hand(rig):
    return rig_state.read(rig, api.map_rig(rig), bpy.context.evaluated_depsgraph_get())[1][JOINT_INDEX["RWrist"]]


def _bind(scene, rig, points, name="hostile path"):
    api.bind_curve(rig, "RWrist", blender_rigs.curve(scene, name, np.asarray(points, dtype=np.float64)))
    return bpy.data.objects[name]


def _reach(rig, length=0.4, samples=12):
    return _hand(rig) + np.linspace(0.0, 1.0, samples)[:, None] * [0.0, -length, 0.3 * length]


def _curve(points):
    """A case binding the hand to ``points(rig)`` (P, 3)."""
    def mutate(scene, rig):
        _bind(scene, rig, points(rig))
    return mutate


def _with_point(value):
    def mutate(scene, rig):
        points = _reach(rig)
        points[5, 1] = value
        _bind(scene, rig, points)
    return mutate


def _curve_object(change):
    def mutate(scene, rig):
        change(_bind(scene, rig, _reach(rig)))
    return mutate


def _rig_object(change):
    def mutate(scene, rig):
        change(rig)
        bpy.context.view_layer.update()
        _bind(scene, rig, _reach(rig))
    return mutate


def _two_splines(scene, rig):
    curve = _bind(scene, rig, _reach(rig))
    spline = curve.data.splines.new('POLY')
    spline.points.add(1)


def _empty_curve(scene, rig):
    curve = _bind(scene, rig, _reach(rig))
    curve.data.splines.clear()


def _spinning_parent(scene, rig):
    carrier = bpy.data.objects.new("spinner", None)
    scene.collection.objects.link(carrier)
    carrier.keyframe_insert("rotation_euler", frame=1)
    carrier.rotation_euler = (0.0, 0.0, 40.0)
    carrier.keyframe_insert("rotation_euler", frame=60)
    rig.parent = carrier
    _bind(scene, rig, _reach(rig))


def _rename(rig):
    rig.data.bones["LKnee"].name = "knee"


def _delete_bone(rig):
    bpy.context.view_layer.objects.active = rig
    bpy.ops.object.mode_set(mode='EDIT')
    rig.data.edit_bones.remove(rig.data.edit_bones["LWrist"])
    bpy.ops.object.mode_set(mode='OBJECT')


def _rotation_mode(rig):
    rig.pose.bones["LKnee"].rotation_mode = 'ZYX'


def _frames(first, last, fps=24):
    def mutate(scene, rig):
        scene.frame_start, scene.frame_end, scene.render.fps = first, last, fps
        _bind(scene, rig, _reach(rig))
    return mutate


def _sized(scale):
    def change(rig):
        rig.scale = (scale, scale, scale)
    return change


CASES = {  # name: mutate(scene, rig) -> None, or a rig edit made between inference and writing
    "curve: every point the same": _curve(lambda rig: [_hand(rig)] * 6),
    "curve: two points a nanometre apart": _curve(lambda rig: [_hand(rig), _hand(rig) + 1e-9]),
    "curve: 10,000 km away": _curve(lambda rig: _reach(rig) + 1e7),
    "curve: 100 m away": _curve(lambda rig: _reach(rig) + [100.0, 0.0, 0.0]),
    "curve: 1 km long": _curve(lambda rig: _reach(rig, length=1000.0)),
    "curve: 3 m under the floor": _curve(lambda rig: _reach(rig) - [0.0, 0.0, 3.0]),
    "curve: a NaN point": _with_point(NAN),
    "curve: an infinite point": _with_point(INF),
    "curve: 20,000 points in a tight spiral": _curve(lambda rig: _hand(rig) + 0.05 * np.column_stack(
        [np.cos(np.linspace(0, 400, 20000)), np.sin(np.linspace(0, 400, 20000)), np.linspace(0, 1, 20000)])),
    "curve: object scaled to zero": _curve_object(lambda curve: setattr(curve, "scale", (0.0, 0.0, 0.0))),
    "curve: object mirrored": _curve_object(lambda curve: setattr(curve, "scale", (-1.0, 1.0, 1.0))),
    "curve: object location NaN": _curve_object(lambda curve: setattr(curve, "location", (NAN, 0.0, 0.0))),
    "curve: two splines": _two_splines,
    "curve: no spline": _empty_curve,
    "rig: a millimetre tall": _rig_object(_sized(0.001)),
    "rig: a hundred times too big": _rig_object(_sized(100.0)),
    "rig: lying on its back": _rig_object(lambda rig: setattr(rig, "rotation_euler", (math.pi / 2, 0.0, 0.0))),
    "rig: mirrored": _rig_object(lambda rig: setattr(rig, "scale", (-1.0, 1.0, 1.0))),
    "rig: flattened": _rig_object(lambda rig: setattr(rig, "scale", (1.0, 1.0, 0.0))),
    "rig: location NaN": _rig_object(lambda rig: setattr(rig, "location", (0.0, NAN, 0.0))),
    "rig: on a parent spinning 40 radians": _spinning_parent,
    "frames: a single frame": _frames(5, 5),
    "frames: end before start": _frames(30, 10),
    "frames: two frames at 1 fps": _frames(1, 2, fps=1),
    "frames: 60 frames at 240 fps": _frames(1, 60, fps=240),
    "between steps: a bone renamed": lambda scene, rig: _rename,
    "between steps: a bone deleted": lambda scene, rig: _delete_bone,
    "between steps: a rotation mode changed": lambda scene, rig: _rotation_mode,
}

ARGUMENTS = [dict(n=0), dict(n=-1), dict(n=2.5), dict(n="3"), dict(n=None), dict(seed=-1), dict(seed=NAN),
             dict(diversity=NAN), dict(diversity=-INF), dict(diversity=None)]


def _state(rig):
    """The artist's data as text (NaN-safe): actions and their keys, the assigned action, the pose,
    constraint states, and every other datablock count."""
    animation = rig.animation_data
    return repr({"actions": sorted((a.name, sorted(blender_rigs.action_keys(a).items()), a.use_fake_user)
                                   for a in bpy.data.actions),
                 "assigned": animation.action.name if animation and animation.action else None,
                 "pose": rig_state.pose_snapshot(rig),
                 "constraints": sorted((b.name, c.name, c.mute, c.influence) for b in rig.pose.bones
                                       for c in b.constraints),
                 "variants": len(rig.trajevae.variants), "recorded": rig.trajevae.has_original,
                 "data": [len(bpy.data.objects), len(bpy.data.curves), len(bpy.data.meshes)]})


def _artist_rig(scene):
    """The mannequin with the artist's work on it: a keyed action and an un-keyed pose."""
    rig = blender_rigs.mannequin_rig(scene)
    rig.pose.bones["Spine"].keyframe_insert("rotation_quaternion", frame=1)
    rig.pose.bones["LElbow"].rotation_quaternion = (0.9, 0.4, 0.0, 0.0)
    rig.pose.bones["LElbow"].keyframe_insert("rotation_quaternion", frame=30)
    rig.pose.bones["Hip"].location = (0.0, 0.0, 0.05)
    scene.frame_set(1)
    bpy.context.view_layer.objects.active = rig
    return rig


def _generate(rig, between):
    """Generate as the artist would (the operator), or with ``between`` run on the rig between
    inference and writing; returns the error sentence shown, or None when it worked."""
    if between is None:
        try:
            bpy.ops.trajevae.generate()
        except RuntimeError as error:  # how bpy.ops hands over an operator's error report
            return str(error)
        return None
    job = pipeline.prepare(rig, 2, 0)
    pipeline.infer(job)
    between(rig)
    try:
        pipeline.finish(job, rig)
    except pipeline.USER_ERRORS as error:
        return str(error)
    return None


@pytest.mark.parametrize("case", CASES)
def test_hostile_input_leaves_the_artists_work_as_it_was(scene, case):
    rig = _artist_rig(scene)
    rig.trajevae.variant_count = 2
    between = CASES[case](scene, rig)
    before = _state(rig)
    error = _generate(rig, between)
    print(f"{case}: {error or 'generated'}")
    if error is not None:
        assert "Traceback" not in error and "\n" not in error.strip() and len(error) < 600
        if between is not None:
            assert [a for a in bpy.data.actions if "variant" in a.name] == []
            return  # the rig itself was edited, so it cannot be compared with before
    else:
        made = [item.action for item in rig.trajevae.variants]
        assert len(made) == 2
        for action in made:
            assert all(np.isfinite(np.frombuffer(keys, np.float32)).all()
                       for keys in blender_rigs.action_keys(action).values())
        assert bpy.ops.trajevae.discard_variants() == {'FINISHED'}
    assert _state(rig) == before


@pytest.mark.parametrize("arguments", ARGUMENTS, ids=str)
def test_odd_arguments_are_refused_with_a_sentence(scene, arguments):
    rig = _artist_rig(scene)
    before = _state(rig)
    with pytest.raises(pipeline.InputError, match=r" must be .*, not "):
        api.generate_variants(rig, **arguments)
    assert _state(rig) == before
