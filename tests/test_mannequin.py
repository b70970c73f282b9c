"""The mannequin in real (headless) Blender: bones, rest pose, hinges, skinning, operator."""

import math

import bpy
import numpy as np
import pytest
from mathutils import Quaternion

from model_runtime.skeleton import JOINT_NAMES
from trajevae_addon import mannequin

PARENTS = {
    "Hip": None, "Spine": "Hip", "Thorax": "Spine", "Neck": "Thorax",
    "RHip": "Hip", "RKnee": "RHip", "RFoot": "RKnee", "LHip": "Hip", "LKnee": "LHip", "LFoot": "LKnee",
    "LClavicle": "Spine", "LShoulder": "LClavicle", "LElbow": "LShoulder", "LWrist": "LElbow",
    "RClavicle": "Spine", "RShoulder": "RClavicle", "RElbow": "RShoulder", "RWrist": "RElbow",
}


@pytest.fixture
def scene():
    bpy.ops.wm.read_factory_settings(use_empty=True)
    return bpy.context.scene


@pytest.fixture
def armature(scene):
    return mannequin.build_mannequin(scene)


def _bend(armature, bone, degrees):
    """Rotate a pose bone about its local X and re-evaluate."""
    armature.pose.bones[bone].rotation_quaternion = Quaternion((1.0, 0.0, 0.0), math.radians(degrees))
    bpy.context.view_layer.update()


def test_bones_and_hierarchy(armature):
    bones = armature.data.bones
    assert {bone.name: bone.parent.name if bone.parent else None for bone in bones} == PARENTS
    assert set(JOINT_NAMES) - {"Head"} <= set(bones.keys())
    for name in ("Spine", "Thorax", "Neck", "LKnee", "LElbow", "RFoot", "RWrist"):
        assert bones[name].use_connect
    assert not bones["LHip"].use_connect and not bones["RClavicle"].use_connect
    assert all(pose_bone.rotation_mode == 'QUATERNION' for pose_bone in armature.pose.bones)


def test_rest_pose(armature):
    bones = armature.data.bones
    # Each canonical joint is its bone's head; the Head joint is the head bone's tail.
    for i, name in enumerate(JOINT_NAMES):
        point = bones["Neck"].tail_local if name == "Head" else bones[name].head_local
        np.testing.assert_allclose(point, mannequin.REST_JOINTS[i], atol=1e-6)
    assert 1.6 < bones["Neck"].tail_local.z < 1.8
    for side in "LR":
        assert 0.0 < bones[f"{side}Foot"].head_local.z < 0.1  # ankle
        assert 0.0 <= bones[f"{side}Foot"].tail_local.z < 0.05  # toe
        assert bones[f"{side}Foot"].tail_local.y < bones[f"{side}Foot"].head_local.y - 0.1  # facing -Y
    for joint in ("Hip", "Shoulder", "Elbow", "Wrist", "Knee"):
        assert bones[f"L{joint}"].head_local.x > 0.05 and bones[f"R{joint}"].head_local.x < -0.05
    body = armature.children[0]
    z = np.array([vertex.co.z for vertex in body.data.vertices])
    assert -0.01 < z.min() < 0.02


def test_rest_pose_at_location(scene):
    armature = mannequin.build_mannequin(scene, name="Other", location=(1.0, 2.0, 0.5))
    bpy.context.view_layer.update()
    assert armature.name == "Other"
    np.testing.assert_allclose(armature.matrix_world @ armature.data.bones["LFoot"].head_local,
                               np.array([1.0, 2.0, 0.5]) + mannequin.REST_JOINTS[JOINT_NAMES.index("LFoot")],
                               atol=1e-6)


def test_positive_x_bends_knees_back_and_elbows_forward(armature):
    pose = armature.pose.bones
    rest = {name: np.array(pose[name].tail) for name in ("LKnee", "RKnee", "LElbow", "RElbow")}
    for name in rest:
        _bend(armature, name, 60.0)
    for side in "LR":
        assert pose[f"{side}Knee"].tail.y - rest[f"{side}Knee"][1] > 0.2  # ankle swings behind
        assert pose[f"{side}Elbow"].tail.y - rest[f"{side}Elbow"][1] < -0.15  # wrist swings forward
        assert abs(pose[f"{side}Elbow"].tail.x - rest[f"{side}Elbow"][0]) < 0.1  # in its own plane


def test_body_deforms_with_armature(armature):
    body = armature.children[0]
    assert body.parent == armature
    assert [(m.type, m.object) for m in body.modifiers] == [('ARMATURE', armature)]
    assert {group.name for group in body.vertex_groups} == set(PARENTS)

    def evaluated():
        mesh = body.evaluated_get(bpy.context.evaluated_depsgraph_get()).to_mesh()
        co = np.empty(len(mesh.vertices) * 3)
        mesh.vertices.foreach_get("co", co)
        return co.reshape(-1, 3)

    rest = evaluated()
    _bend(armature, "LKnee", 60.0)
    moved = np.linalg.norm(evaluated() - rest, axis=1) > 1e-3
    group = {name: body.vertex_groups[name].index for name in ("LKnee", "LFoot", "Neck")}
    member = np.array([[g.group for g in vertex.groups] for vertex in body.data.vertices])[:, 0]
    assert moved[member == group["LKnee"]].any() and moved[member == group["LFoot"]].all()
    assert not moved[member == group["Neck"]].any()


def test_operator_adds_at_cursor_and_unregisters(scene):
    mannequin.register()
    try:
        scene.cursor.location = (0.5, -1.0, 0.0)
        assert bpy.ops.trajevae.add_mannequin() == {'FINISHED'}
        armature = bpy.context.view_layer.objects.active
        assert armature.type == 'ARMATURE' and armature.select_get()
        np.testing.assert_allclose(armature.location, (0.5, -1.0, 0.0))
        assert [child.type for child in armature.children] == ['MESH']
    finally:
        mannequin.unregister()
    assert not hasattr(bpy.types, "TRAJEVAE_OT_add_mannequin")
