"""The shots an animator would try first, set up on any mapped rig: idle from the rest pose, a hand
reach, a foot's step, blocking keys, a slow hand wave, and walks along paths drawn on the floor. Shared by the
quality benchmark and the tests.

Each shot function takes the rig and returns ({joint: curve points (P, 3) world}, key frame or
None); it may key the rig (blocking)."""

import math

import bpy
import numpy as np
from mathutils import Matrix, Vector

import blender_rigs
from model_runtime.skeleton import JOINT_INDEX, facing
from trajevae_addon import api, rig_mapping, rig_state

J = JOINT_INDEX
HAND = "RWrist"  # the joint the curves move
REACH_SHARE = 0.85  # curves stay within this share of the arm's length from the shoulder
KEY_FRAME = 45
UP = np.array([0.0, 0.0, 1.0])


def _arm(joints, side="R"):
    """(shoulder (3,), wrist (3,), arm length, outward horizontal direction (3,)) of a pose (17, 3)."""
    shoulder, elbow, wrist = (joints[J[side + part]] for part in ("Shoulder", "Elbow", "Wrist"))
    outward = shoulder - joints[J["Thorax"]]
    outward[2] = 0.0
    length = np.linalg.norm(elbow - shoulder) + np.linalg.norm(wrist - elbow)
    return shoulder, wrist, length, outward / np.linalg.norm(outward)


def idle(rig):
    """No curves, no keys: the motion the model proposes from the rest pose."""
    return {}, None


def reach(rig):
    """One hand curve, straight from the wrist to in front of the shoulder, up and forward."""
    joints = blender_rigs.world_joints(rig)
    shoulder, wrist, length, outward = _arm(joints)
    end = shoulder + REACH_SHARE * length * _unit(facing(joints) + 0.6 * UP + 0.3 * outward)
    return {HAND: wrist + np.linspace(0.0, 1.0, 8)[:, None] * (end - wrist)}, None


def wave(rig):
    """One hand curve: the arm rises sideways to 60 degrees above horizontal over the first fifth,
    then sways 20 degrees either way 4 times (a 0.5 Hz wave over 300 frames)."""
    joints = blender_rigs.world_joints(rig)
    shoulder, wrist, length, outward = _arm(joints)
    share = np.linspace(0.0, 1.0, 160)
    rise = np.clip(share / 0.2, 0.0, 1.0)
    rise = rise * rise * (3.0 - 2.0 * rise)
    start, raised = Vector(_unit(wrist - shoulder)), Vector(_unit(0.5 * outward + 0.87 * UP))
    axis = start.cross(raised).normalized()
    angles = start.angle(raised) * rise + np.radians(20.0) * np.sin(2.0 * np.pi * 5.0 * np.clip(share - 0.2, 0, 1))
    radius = np.linalg.norm(wrist - shoulder) * (1.0 - rise) + REACH_SHARE * length * rise
    return {HAND: np.array([shoulder + r * np.array(Matrix.Rotation(angle, 3, axis) @ start)
                            for r, angle in zip(radius, angles)])}, None


def step(rig):
    """One foot curve: the right foot steps forward 0.6 of its leg's length along the rig's facing,
    lifting to 0.15 of it halfway; the rest of the body is the model's (it has to follow the foot)."""
    joints = blender_rigs.world_joints(rig)
    hip, knee, foot = (joints[J["R" + part]] for part in ("Hip", "Knee", "Foot"))
    leg = np.linalg.norm(knee - hip) + np.linalg.norm(foot - knee)
    share = np.linspace(0.0, 1.0, 16)[:, None]
    return {"RFoot": foot + share * 0.6 * leg * facing(joints) + np.sin(np.pi * share) * 0.15 * leg * UP}, None


def _unit(vector):
    return vector / np.linalg.norm(vector)


def _set_armature_matrix(rig, bone, matrix):
    """Give a pose bone an armature-space matrix (4, 4) and let its children follow."""
    rig.pose.bones[bone].matrix = Matrix(matrix.tolist())
    bpy.context.view_layer.update()


def _turn(rig, bone, rotation):
    """Pose ``bone`` turned by ``rotation`` (3, 3, armature space) from its rest direction,
    its head where its parents put it."""
    pose_bone = rig.pose.bones[bone]
    matrix = np.array(rig.data.bones[bone].matrix_local)
    matrix[:3, :3] = rotation @ matrix[:3, :3]
    matrix[:3, 3] = np.array(pose_bone.head)
    _set_armature_matrix(rig, bone, matrix)


def _rotation(axis, degrees):
    return np.array(Matrix.Rotation(math.radians(degrees), 3, Vector(axis)))


def _key_pose(rig, bones, frame):
    """Key every mapped bone's rotation and the root's location on ``frame``."""
    paths = {'QUATERNION': "rotation_quaternion", 'AXIS_ANGLE': "rotation_axis_angle"}
    for bone in filter(None, bones.values()):
        pose_bone = rig.pose.bones[bone]
        pose_bone.keyframe_insert(paths.get(pose_bone.rotation_mode, "rotation_euler"), frame=frame)
    rig.pose.bones[bones["Hip"]].keyframe_insert("location", frame=frame)


def blocking(rig):
    """Keys an artist blocks in: the rest pose at frame 1, at KEY_FRAME a crouch (trunk leaning
    20 degrees, thighs 75 forward, shins 55 back, feet level where they stood) with both arms up.
    The rig's FK controls show (its profile's switches), as when an artist keys them."""
    bones = api.map_rig(rig)
    rig_state.apply_switches(rig, rig_mapping.switches(rig_state.detected(rig)[0]))
    rest = blender_rigs.world_joints(rig)
    forward = facing(rest)
    side = np.cross(UP, forward)  # turning about it takes up toward forward, down toward back
    _key_pose(rig, bones, 1)
    _turn(rig, bones["Hip"], _rotation(side, 20.0))
    for leg in "RL":
        _turn(rig, bones[leg + "Hip"], _rotation(side, -75.0))
        _turn(rig, bones[leg + "Knee"], _rotation(side, 55.0))
        _turn(rig, bones[leg + "Foot"], np.eye(3))
    for arm in "RL":
        shoulder, wrist, _, outward = _arm(blender_rigs.world_joints(rig), arm)
        up = np.array((Vector(wrist - shoulder).normalized()).rotation_difference(
            Vector(_unit(UP + 0.25 * outward + 0.15 * forward))).to_matrix())
        for part in ("Shoulder", "Elbow", "Wrist"):
            _turn(rig, bones[arm + part], up)
    crouched = blender_rigs.world_joints(rig)
    feet = [J["RFoot"], J["LFoot"]]
    root = np.array(rig.pose.bones[bones["Hip"]].matrix)
    root[:3, 3] += (rest[feet] - crouched[feet]).mean(axis=0)  # the feet back where they stood
    _set_armature_matrix(rig, bones["Hip"], root)
    _key_pose(rig, bones, KEY_FRAME)
    return {}, KEY_FRAME


def _ground_path(rig, length, bend_degrees):
    """A path on the floor from under the hips along the rig's facing, ``length`` metres long,
    turning ``bend_degrees`` in all at a steady rate (an arc; 0: a straight line)."""
    joints = blender_rigs.world_joints(rig)
    forward = facing(joints)
    side = np.cross(UP, forward)
    share = np.linspace(0.0, 1.0, 60)
    if bend_degrees == 0:
        offsets = share[:, None] * length * forward
    else:
        radius = length / math.radians(bend_degrees)
        angle = share * math.radians(bend_degrees)
        offsets = radius * (np.sin(angle)[:, None] * forward + (1.0 - np.cos(angle))[:, None] * side)
    start = joints[J["Hip"]].copy()
    start[2] = min(joints[J["RFoot"], 2], joints[J["LFoot"], 2]) - 0.08  # the floor, under the ankles
    return start + offsets


def walk(rig):
    """A ground path: 4 m on the floor, gently curved (30 degrees), bound to the hips."""
    return {"Hip": _ground_path(rig, 4.0, 30.0)}, None


def quarter_turn(rig):
    """A ground path: a quarter circle of radius 2.5 m."""
    return {"Hip": _ground_path(rig, 2.5 * math.pi / 2, 90.0)}, None


def long_walk(rig):
    """A ground path: 10 m on the floor, gently curved (45 degrees)."""
    return {"Hip": _ground_path(rig, 10.0, 45.0)}, None


def run(rig):
    """A ground path: 10 m on the floor, gently curved (15 degrees), to be covered in 4 s: a run."""
    return {"Hip": _ground_path(rig, 10.0, 15.0)}, None


SHOTS = (("idle", 150, idle), ("reach", 90, reach), ("step", 60, step), ("keys", 60, blocking), ("wave", 300, wave))
WALKS = (("walk", 120, walk), ("quarter turn", 120, quarter_turn), ("long walk", 300, long_walk), ("run", 120, run))
