"""Real rigs built in Blender for the tests: Rigify, Mixamo-named, BVH-imported, and curves."""

import addon_utils
import bpy
import numpy as np

from trajevae_addon import mannequin

MIXAMO_BONES = {  # name: (head joint or point, tail joint or point, parent)
    "Hips": ("Hip", "Spine", None),
    "Spine": ("Spine", "Spine1", "Hips"),
    "Spine1": ("Spine1", "Spine2", "Spine"),
    "Spine2": ("Spine2", "Thorax", "Spine1"),
    "Neck": ("Thorax", "Neck", "Spine2"),
    "Head": ("Neck", "Head", "Neck"),
    "HeadTop_End": ("Head", "HeadTop", "Head"),
}
for side, word in (("L", "Left"), ("R", "Right")):
    MIXAMO_BONES.update({
        f"{word}UpLeg": (f"{side}Hip", f"{side}Knee", "Hips"),
        f"{word}Leg": (f"{side}Knee", f"{side}Foot", f"{word}UpLeg"),
        f"{word}Foot": (f"{side}Foot", f"{side}Toe", f"{word}Leg"),
        f"{word}Shoulder": (f"{side}Clavicle", f"{side}Shoulder", "Spine2"),
        f"{word}Arm": (f"{side}Shoulder", f"{side}Elbow", f"{word}Shoulder"),
        f"{word}ForeArm": (f"{side}Elbow", f"{side}Wrist", f"{word}Arm"),
        f"{word}Hand": (f"{side}Wrist", f"{side}Fingers", f"{word}ForeArm"),
    })


def action_keys(action):
    """{(data path, index): the keys' (frame, value) pairs as bytes}: an action's keys, for an
    exact comparison."""
    out = {}
    for layer in action.layers:
        for strip in layer.strips:
            for bag in strip.channelbags:
                for fcurve in bag.fcurves:
                    co = np.empty(len(fcurve.keyframe_points) * 2, dtype=np.float32)
                    fcurve.keyframe_points.foreach_get("co", co)
                    out[(fcurve.data_path, fcurve.array_index)] = co.tobytes()
    return out


def world_joints(rig):
    """The rig's 17 joints (17, 3) in world space as Blender shows it now."""
    from trajevae_addon import api, rig_state
    return rig_state.read(rig, api.map_rig(rig), bpy.context.evaluated_depsgraph_get())[1]


def played(rig, frames):
    """(joints (F, 17, 3), toes (F, 2, 3): right, left) in world space as Blender plays the rig on
    ``frames``, read from the bones the artist sees (a Rigify rig's ORG bones); a toe is the tail
    of the foot's bone."""
    from trajevae_addon import api, rig_mapping, rig_state
    scene, bones = bpy.context.scene, api.map_rig(rig)
    shown = rig_mapping.shown_by(rig_state.detected(rig)[0])
    feet = [shown.get(bones[foot], bones[foot]) for foot in ("RFoot", "LFoot")]
    joints, toes = [], []
    for frame in frames:
        scene.frame_set(int(frame))
        joints.append(rig_state.read(rig, bones, bpy.context.evaluated_depsgraph_get(), shown)[1])
        world = np.array(rig.matrix_world)
        toes.append([world[:3, :3] @ np.array(rig.pose.bones[foot].tail) + world[:3, 3] for foot in feet])
    return np.array(joints), np.array(toes)


def fresh_scene():
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    scene.frame_start, scene.frame_end = 1, 60
    return scene


def mannequin_rig(scene):
    return mannequin.build_mannequin(scene)


def _points():
    """Named points (metres, facing -Y) of the mannequin's proportions plus the extra Mixamo bones."""
    from model_runtime.skeleton import JOINT_INDEX
    joints = mannequin.REST_JOINTS
    points = {name: joints[index] for name, index in JOINT_INDEX.items()}
    spine, thorax = points["Spine"], points["Thorax"]
    points.update(Spine1=spine + (thorax - spine) / 3, Spine2=spine + 2 * (thorax - spine) / 3,
                  HeadTop=points["Head"] + [0.0, 0.0, 0.05])
    for side, sign in (("L", 1.0), ("R", -1.0)):
        points[f"{side}Clavicle"] = thorax + [sign * 0.03, 0.0, -0.05]
        points[f"{side}Toe"] = points[f"{side}Foot"] + [0.0, -0.15, -0.03]
        points[f"{side}Fingers"] = points[f"{side}Wrist"] + 0.18 * (points[f"{side}Wrist"] - points[f"{side}Elbow"]) / \
            np.linalg.norm(points[f"{side}Wrist"] - points[f"{side}Elbow"])
    return points


def mixamo_rig(scene, prefix="mixamorig:"):
    """A centimetre Mixamo-named armature as FBX imports make it (object scale 0.01), turned and
    moved, with axis-angle and Euler bones mixed in."""
    data = bpy.data.armatures.new("MixamoRig")
    rig = bpy.data.objects.new("MixamoRig", data)
    scene.collection.objects.link(rig)
    bpy.context.view_layer.objects.active = rig
    bpy.ops.object.mode_set(mode='EDIT')
    points = _points()
    for name, (head, tail, parent) in MIXAMO_BONES.items():
        bone = data.edit_bones.new(prefix + name)
        bone.head, bone.tail = points[head] * 100.0, points[tail] * 100.0
        if parent:
            bone.parent = data.edit_bones[prefix + parent]
    bpy.ops.object.mode_set(mode='OBJECT')
    rig.scale = (0.01, 0.01, 0.01)
    rig.rotation_euler = (0.0, 0.0, 0.7)
    rig.location = (1.5, -0.5, 0.0)
    rig.pose.bones[prefix + "LeftArm"].rotation_mode = 'AXIS_ANGLE'
    rig.pose.bones[prefix + "RightUpLeg"].rotation_mode = 'YXZ'
    return rig


def rigify_rig(scene):
    """A human rig generated by Rigify from its Human metarig."""
    addon_utils.enable("rigify", default_set=True)
    bpy.ops.object.armature_human_metarig_add()
    metarig = bpy.context.object
    bpy.ops.pose.rigify_generate()
    rig = bpy.context.object
    metarig.hide_set(True)
    return rig


def disable_rigify():
    addon_utils.disable("rigify", default_set=True)


def bvh_rig(path):
    bpy.ops.import_anim.bvh(filepath=str(path), global_scale=1.0, use_fps_scale=False)
    rig = bpy.context.object
    rig.animation_data_clear()
    return rig


def curve(scene, name, points):
    """A poly Curve object through world points (P, 3)."""
    data = bpy.data.curves.new(name, 'CURVE')
    data.dimensions = '3D'
    spline = data.splines.new('POLY')
    spline.points.add(len(points) - 1)
    spline.points.foreach_set("co", np.column_stack([points, np.ones(len(points))]).ravel())
    obj = bpy.data.objects.new(name, data)
    scene.collection.objects.link(obj)
    return obj
