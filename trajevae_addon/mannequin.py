"""A rigged mannequin of the model's own skeleton, so generated motion can be seen without an artist's rig.

Convention. Bones are named after the canonical joints: a bone's head sits on
its joint, as in the rig profiles (``model_runtime.data.profiles``), so the
joint-to-bone mapping is the identity:

- Hip: the pelvis and root, pelvis centre -> Spine joint.
- RHip / LHip: thighs, hip -> knee. RKnee / LKnee: shins, knee -> ankle.
  RFoot / LFoot: feet, ankle -> toe tip.
- Spine: chest, Spine joint -> Thorax (neck base). Thorax: the neck, neck base
  -> skull base. Neck: the head, skull base -> head top (the Head joint).
- RClavicle / LClavicle (not canonical joints): neck base -> shoulder, children
  of Spine so the shoulders do not follow the neck.
- RShoulder / LShoulder: upper arms, shoulder -> elbow. RElbow / LElbow:
  forearms, elbow -> wrist. RWrist / LWrist: hands, wrist -> finger tips.

Rest pose: standing, feet on the floor (z = 0 at the object's origin), facing
-Y as Blender characters do (the character's left is +X), straight legs and
arms in an A-pose 45 degrees below horizontal. Every bone's local X axis is
its hinge: a positive rotation about X bends the knees back and folds the
elbows forward, on both sides.

Proportions (``REST_JOINTS``) are the model's: measured once over the 201
training clips (validation subjects excluded) of the CMU/ACCAD set, each
scaled to the loader's 1.7 m stature, as the per-clip median of each
distance averaged over clips, left and right averaged: ankle above the sole
0.056, hip width 0.190, thigh 0.434, shin 0.430, pelvis centre to neck base
0.475, neck 0.142, skull base to head top 0.121, neck base to shoulder 0.206,
shoulder width 0.370, upper arm 0.267, forearm 0.219. Legs and torso are
stacked upright, so the head top stands at 1.658 m (the loader's stature also
weighs the 0.53 hip-height rule). Feet, hands and clavicle heads are not
canonical joints; their sizes follow Drillis and Contini's segment fractions
of stature.
"""

import bpy
import numpy as np

from .runtime import skeleton

# Rest joint positions (17, 3), metres, armature space, in skeleton.JOINT_NAMES order.
REST_JOINTS = np.array([
    (0.0, 0.0, 0.920),  # Hip
    (-0.095, 0.0, 0.920), (-0.095, 0.0, 0.486), (-0.095, 0.0, 0.056),  # RHip, RKnee, RFoot
    (0.095, 0.0, 0.920), (0.095, 0.0, 0.486), (0.095, 0.0, 0.056),  # LHip, LKnee, LFoot
    (0.0, 0.0, 1.1575), (0.0, 0.0, 1.395), (0.0, 0.0, 1.537), (0.0, 0.0, 1.658),  # Spine, Thorax, Neck, Head
    (0.185, 0.0, 1.303), (0.374, 0.0, 1.114), (0.529, 0.0, 0.959),  # LShoulder, LElbow, LWrist
    (-0.185, 0.0, 1.303), (-0.374, 0.0, 1.114), (-0.529, 0.0, 0.959),  # RShoulder, RElbow, RWrist
])
TOE_FORWARD = 0.20  # ankle to toe tip along -Y: 0.152 x stature foot, less the heel behind the ankle
TOE_HEIGHT = 0.035
HAND_LENGTH = 0.18  # wrist to finger tips: 0.108 x stature
CLAVICLE_HEAD = np.array([0.02, 0.0, -0.02])  # left sternoclavicular joint from the neck base

_HINGE_X = np.array([1.0, 0.0, 0.0])
_ARM_HINGE = {"L": np.array([-1.0, 0.0, -1.0]) / np.sqrt(2.0), "R": np.array([-1.0, 0.0, 1.0]) / np.sqrt(2.0)}
# Body pieces: bone -> (half width along the bone's X, half depth along its Z, metres it reaches
# beyond the head, beyond the tail); limb entries are named without their side.
_BODY = {"Hip": (0.15, 0.10, 0.12, 0.0), "Spine": (0.16, 0.11, 0.02, 0.02),
         "Thorax": (0.05, 0.05, 0.0, 0.0), "Neck": (0.075, 0.09, 0.08, 0.0)}
_LIMB_BODY = {"Hip": (0.07, 0.07, 0.02, 0.02), "Knee": (0.05, 0.05, 0.02, 0.02), "Foot": (0.045, 0.035, 0.06, 0.02),
              "Clavicle": (0.04, 0.04, 0.0, 0.0), "Shoulder": (0.045, 0.045, 0.03, 0.02),
              "Elbow": (0.038, 0.038, 0.02, 0.02), "Wrist": (0.02, 0.045, 0.0, 0.0)}
_SIDES = 8
_LATITUDES = np.radians([-70.0, -35.0, 0.0, 0.0, 35.0, 70.0])  # rings (R,): head cap, shaft, tail cap


def _bones():
    """Bone table: name -> (parent, head (3,), tail (3,), wanted X axis (3,), connected)."""
    j = {name: REST_JOINTS[i] for i, name in enumerate(skeleton.JOINT_NAMES)}
    bones = {
        "Hip": (None, j["Hip"], j["Spine"], _HINGE_X, False),
        "Spine": ("Hip", j["Spine"], j["Thorax"], _HINGE_X, True),
        "Thorax": ("Spine", j["Thorax"], j["Neck"], _HINGE_X, True),
        "Neck": ("Thorax", j["Neck"], j["Head"], _HINGE_X, True),
    }
    for side, sign in (("L", 1.0), ("R", -1.0)):
        toe = j[f"{side}Foot"] + np.array([0.0, -TOE_FORWARD, TOE_HEIGHT - j[f"{side}Foot"][2]])
        forearm = j[f"{side}Wrist"] - j[f"{side}Elbow"]
        hand = j[f"{side}Wrist"] + HAND_LENGTH * forearm / np.linalg.norm(forearm)
        arm = _ARM_HINGE[side]
        bones.update({
            f"{side}Hip": ("Hip", j[f"{side}Hip"], j[f"{side}Knee"], _HINGE_X, False),
            f"{side}Knee": (f"{side}Hip", j[f"{side}Knee"], j[f"{side}Foot"], _HINGE_X, True),
            f"{side}Foot": (f"{side}Knee", j[f"{side}Foot"], toe, _HINGE_X, True),
            f"{side}Clavicle": ("Spine", j["Thorax"] + CLAVICLE_HEAD * (sign, 1.0, 1.0), j[f"{side}Shoulder"], arm, False),
            f"{side}Shoulder": (f"{side}Clavicle", j[f"{side}Shoulder"], j[f"{side}Elbow"], arm, True),
            f"{side}Elbow": (f"{side}Shoulder", j[f"{side}Elbow"], j[f"{side}Wrist"], arm, True),
            f"{side}Wrist": (f"{side}Elbow", j[f"{side}Wrist"], hand, arm, True),
        })
    return bones


def _capsule(head, tail, x_axis, half_width, half_depth, before, after):
    """A closed low-poly capsule around a bone: vertices (R*S, 3) and faces (quads, then two S-gon caps).

    It runs from ``before`` metres behind the head to ``after`` past the tail,
    its cross-section an ellipse with axes along x_axis and the bone's Z.
    """
    length = np.linalg.norm(tail - head)
    y = (tail - head) / length
    z = np.cross(x_axis, y)
    start, end = -before, length + after
    cap = min(half_width, half_depth, (end - start) / 2.0)
    centres = np.where(np.arange(len(_LATITUDES)) < len(_LATITUDES) // 2, start + cap, end - cap)
    along = centres + cap * np.sin(_LATITUDES)  # (R,)
    theta = 2.0 * np.pi * np.arange(_SIDES) / _SIDES  # (S,)
    ring = np.cos(_LATITUDES)[:, None, None]
    vertices = (head + along[:, None, None] * y
                + ring * half_width * np.cos(theta)[None, :, None] * x_axis
                + ring * half_depth * np.sin(theta)[None, :, None] * z)
    k = np.arange(_SIDES)
    faces = [(r * _SIDES + s, (r + 1) * _SIDES + s, (r + 1) * _SIDES + (s + 1) % _SIDES, r * _SIDES + (s + 1) % _SIDES)
             for r in range(len(_LATITUDES) - 1) for s in k]
    last = (len(_LATITUDES) - 1) * _SIDES
    faces += [tuple(k), tuple(last + k[::-1])]
    return vertices.reshape(-1, 3), faces


def _add_bones(armature, scene, view_layer):
    """Create the bones in edit mode, rolled so each bone's X axis is its hinge.

    Edit mode enters on the view layer's active object, so the armature is
    made active for the while.
    """
    previous = view_layer.objects.active
    view_layer.objects.active = armature
    with bpy.context.temp_override(scene=scene, view_layer=view_layer, active_object=armature, object=armature):
        bpy.ops.object.mode_set(mode='EDIT')
        edit_bones = armature.data.edit_bones
        for name, (parent, head, tail, x_axis, connected) in _bones().items():
            bone = edit_bones.new(name)
            bone.head, bone.tail = head, tail
            y = (tail - head) / np.linalg.norm(tail - head)
            x = x_axis - np.dot(x_axis, y) * y
            bone.align_roll(np.cross(x / np.linalg.norm(x), y))  # the Z axis that leaves X on the hinge
            if parent:
                bone.parent = edit_bones[parent]
                bone.use_connect = connected
        bpy.ops.object.mode_set(mode='OBJECT')
    view_layer.objects.active = previous
    for pose_bone in armature.pose.bones:
        pose_bone.rotation_mode = 'QUATERNION'


def _add_body(armature, scene):
    """A mesh of one rigid capsule per bone, skinned to it, child of the armature."""
    vertices, faces, groups = [], [], {}
    for bone in armature.data.bones:
        piece, piece_faces = _capsule(np.array(bone.head_local), np.array(bone.tail_local),
                                      np.array(bone.matrix_local)[:3, 0],
                                      *(_BODY.get(bone.name) or _LIMB_BODY[bone.name[1:]]))
        offset = sum(len(v) for v in vertices)
        groups[bone.name] = range(offset, offset + len(piece))
        vertices.append(piece)
        faces += [tuple(offset + i for i in face) for face in piece_faces]
    mesh = bpy.data.meshes.new(f"{armature.name} Body")
    mesh.from_pydata(np.concatenate(vertices), [], faces)
    body = bpy.data.objects.new(mesh.name, mesh)
    scene.collection.objects.link(body)
    body.parent = armature
    for bone, indices in groups.items():
        body.vertex_groups.new(name=bone).add(list(indices), 1.0, 'REPLACE')
    body.modifiers.new("Armature", 'ARMATURE').object = armature
    return body


def build_mannequin(context_or_scene, name="Mannequin", location=(0.0, 0.0, 0.0)):
    """Add the mannequin (armature object, with its body mesh as a child) to a scene's collection.

    Takes a Context (its scene and view layer) or a Scene (its first view
    layer); the view layer's mode must be Object mode. Returns the armature.
    """
    if isinstance(context_or_scene, bpy.types.Scene):
        scene, view_layer = context_or_scene, context_or_scene.view_layers[0]
    else:
        scene, view_layer = context_or_scene.scene, context_or_scene.view_layer
    armature = bpy.data.objects.new(name, bpy.data.armatures.new(name))
    armature.location = location
    armature.show_in_front = True
    scene.collection.objects.link(armature)
    _add_bones(armature, scene, view_layer)
    _add_body(armature, scene)
    return armature


class TRAJEVAE_OT_add_mannequin(bpy.types.Operator):
    """Add a mannequin rigged with the motion model's skeleton at the 3D cursor"""

    bl_idname = "trajevae.add_mannequin"
    bl_label = "Add Mannequin"
    bl_options = {'REGISTER', 'UNDO'}

    @classmethod
    def poll(cls, context):
        return context.mode == 'OBJECT'

    def execute(self, context):
        armature = build_mannequin(context, location=context.scene.cursor.location)
        for selected in context.selected_objects:
            selected.select_set(False)
        armature.select_set(True)
        context.view_layer.objects.active = armature
        return {'FINISHED'}


def menu_func(self, context):
    """Entry for Add > Armature (VIEW3D_MT_armature_add)."""
    self.layout.operator(TRAJEVAE_OT_add_mannequin.bl_idname, icon='OUTLINER_OB_ARMATURE')


_register_classes, _unregister_classes = bpy.utils.register_classes_factory((TRAJEVAE_OT_add_mannequin,))


def register():
    _register_classes()
    bpy.types.VIEW3D_MT_armature_add.append(menu_func)


def unregister():
    bpy.types.VIEW3D_MT_armature_add.remove(menu_func)
    _unregister_classes()
