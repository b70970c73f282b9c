"""Bindings on real bpy: they follow bone renames (pose and edit mode, through save and reload),
re-binding replaces the row, deleted curves and bones are warned about, and the scripting API
refuses bad arguments with one sentence and without writing anything."""

import bpy
import numpy as np
import pytest

import blender_rigs
import trajevae_addon
from trajevae_addon import api, bindings, rig_state


pytestmark = pytest.mark.usefixtures("scene")


@pytest.fixture
def rig(scene):
    return blender_rigs.mannequin_rig(scene)


def _curve(scene, name):
    return blender_rigs.curve(scene, name, np.linspace([0.3, -0.2, 1.0], [0.3, -0.6, 1.2], 8))


def _edit(rig, change):
    """Run ``change`` on the armature's edit bones, then go back to object mode."""
    bpy.context.view_layer.objects.active = rig
    rig.select_set(True)
    bpy.ops.object.mode_set(mode='EDIT')
    change(rig.data.edit_bones)
    bpy.ops.object.mode_set(mode='OBJECT')


def _paths(rig, **overrides):
    """joint_paths with the rig's mapping, after the artist mapped renamed bones ({joint: bone})."""
    for joint, bone in overrides.items():
        setattr(rig.trajevae.mapping, joint, bone)
    return bindings.joint_paths(rig, api.map_rig(rig))


def test_binding_follows_a_rename_in_pose_mode(scene, rig):
    path = _curve(scene, "right hand path")
    api.bind_curve(rig, "RWrist", path)
    rig.pose.bones["RWrist"].name = "hand_R"  # the Bone tab's name field in pose mode
    paths, warnings = _paths(rig, RWrist="hand_R")
    assert paths == {"RWrist": (path, True)} and warnings == []
    assert [b.bone for b in rig.trajevae.bindings] == ["hand_R"]
    rig.data.bones["hand_R"].name = "Hand.R"  # the same bone renamed through its armature data
    paths, warnings = _paths(rig, RWrist="Hand.R")
    assert paths == {"RWrist": (path, True)} and [b.bone for b in rig.trajevae.bindings] == ["Hand.R"]


def test_binding_follows_an_edit_mode_rename_and_not_a_duplicate_of_its_bone(scene, rig):
    path = _curve(scene, "right hand path")
    api.bind_curve(rig, "RWrist", path)
    order = [bone.name for bone in rig.data.bones]

    def duplicate(edit_bones):
        for bone in edit_bones:
            bone.select = bone.select_head = bone.select_tail = bone.name == "RWrist"
        edit_bones["RElbow"].select_tail = True  # a connected bone's head is its parent's tail
        edit_bones.active = edit_bones["RWrist"]
        assert bpy.ops.armature.duplicate() == {'FINISHED'}

    _edit(rig, duplicate)  # the copy carries the binding's tag too, and edit mode rebuilds the order:
    after = [bone.name for bone in rig.data.bones]  # the copy sits beside its source, not at the end
    assert after.index("RWrist.001") == after.index("RWrist") + 1 != len(order)
    assert _paths(rig)[0] == {"RWrist": (path, True)}
    _edit(rig, lambda edit_bones: setattr(edit_bones["RWrist"], "name", "hand_R"))
    paths, warnings = _paths(rig, RWrist="hand_R")
    assert paths == {"RWrist": (path, True)} and warnings == []
    assert [b.bone for b in rig.trajevae.bindings] == ["hand_R"]


def test_bindings_follow_two_bones_that_swap_names(scene, rig):
    left, right = _curve(scene, "left"), _curve(scene, "right")
    api.bind_curve(rig, "LWrist", left)
    api.bind_curve(rig, "RWrist", right)
    bones = rig.data.bones
    bones["LWrist"].name, bones["RWrist"].name = "swap", "LWrist"
    bones["swap"].name = "RWrist"
    paths, _ = _paths(rig)
    assert paths == {"LWrist": (right, True), "RWrist": (left, True)}  # each path stays on its bone


def test_bindings_follow_a_rename_after_save_and_reload(scene, rig, tmp_path):
    api.bind_curve(rig, "LFoot", _curve(scene, "left foot path"))
    file, name = str(tmp_path / "bound.blend"), rig.name
    bpy.ops.wm.save_as_mainfile(filepath=file)
    bpy.ops.wm.open_mainfile(filepath=file)
    rig = bpy.data.objects[name]
    _edit(rig, lambda edit_bones: setattr(edit_bones["LFoot"], "name", "foot.L"))
    paths, warnings = _paths(rig, LFoot="foot.L")
    assert paths == {"LFoot": (bpy.data.objects["left foot path"], True)} and warnings == []


def test_binding_a_bound_bone_again_replaces_its_row_also_after_a_rename(scene, rig):
    first, second, third = (_curve(scene, name) for name in ("first", "second", "third"))
    api.bind_curve(rig, "LWrist", first)
    api.bind_curve(rig, "LWrist", second, use_drawing_speed=False)
    assert [(b.bone, b.curve, b.use_drawing_speed) for b in rig.trajevae.bindings] == [("LWrist", second, False)]
    rig.pose.bones["LWrist"].name = "hand_L"
    rig.trajevae.mapping.LWrist = "hand_L"
    bpy.context.view_layer.objects.active = rig  # the panel's + button: active bone, selected curve
    rig.data.bones.active = rig.data.bones["hand_L"]
    third.select_set(True)
    assert bpy.ops.trajevae.bind_curve() == {'FINISHED'}
    assert [(b.bone, b.curve) for b in rig.trajevae.bindings] == [("hand_L", third)]


def test_a_binding_whose_curve_was_deleted_is_warned_about(scene, rig):
    path = _curve(scene, "hand path")
    api.bind_curve(rig, "LWrist", path)
    bpy.data.objects.remove(path)
    paths, warnings = _paths(rig)
    assert paths == {} and len(warnings) == 1 and "'LWrist'" in warnings[0] and "no curve" in warnings[0]
    assert bindings.problem(rig, rig.trajevae.bindings[0], api.map_rig(rig)) == "no curve"  # the panel's row


def test_a_binding_whose_bone_was_deleted_is_a_warning_and_can_be_unbound(scene, rig):
    api.bind_curve(rig, "LWrist", _curve(scene, "left"))
    api.bind_curve(rig, "RWrist", right := _curve(scene, "right"))
    _edit(rig, lambda edit_bones: edit_bones.remove(edit_bones["LWrist"]))
    paths, warnings = _paths(rig, LWrist="LElbow")
    assert paths == {"RWrist": (right, True)}
    assert len(warnings) == 1 and "'LWrist'" in warnings[0] and "deleted" in warnings[0]
    assert bindings.problem(rig, rig.trajevae.bindings[0], api.map_rig(rig)) == "bone deleted"
    api.unbind(rig, "LWrist")  # by the name the list shows
    assert [b.bone for b in rig.trajevae.bindings] == ["RWrist"]


def test_a_bone_no_joint_is_mapped_to_is_refused_with_the_bones_that_can_be_bound(scene, rig):
    path = _curve(scene, "shoulder path")
    with pytest.raises(ValueError, match="bind one of the mapped bones") as refused:
        api.bind_curve(rig, "LClavicle", path)
    assert "LWrist" in str(refused.value) and "carries no joint" not in str(refused.value)
    assert len(rig.trajevae.bindings) == 0
    bpy.context.view_layer.objects.active = rig
    rig.data.bones.active = rig.data.bones["LClavicle"]
    path.select_set(True)
    with pytest.raises(RuntimeError, match="bind one of the mapped bones"):  # the operator reports it
        bpy.ops.trajevae.bind_curve()
    api.bind_curve(rig, "LWrist", path)
    rig.trajevae.mapping.LWrist = "LElbow"  # the bound bone stops carrying a joint
    with pytest.raises(rig_state.RigError, match="bind one of the mapped bones") as refused:
        _paths(rig)
    assert "carries no joint" not in str(refused.value)
    assert bindings.problem(rig, rig.trajevae.bindings[0], api.map_rig(rig)) == "bone not mapped"


def _mesh(scene):
    obj = bpy.data.objects.new("Cube", bpy.data.meshes.new("Cube"))
    scene.collection.objects.link(obj)
    return obj


def _deleted(scene):
    obj = _curve(scene, "deleted path")
    bpy.data.objects.remove(obj)
    return obj


BAD_CALLS = {  # name: (call, expected error, words in the sentence)
    "map_rig(None)": (lambda s, r, c: api.map_rig(None), TypeError, "armature object, not None"),
    "map_rig(name)": (lambda s, r, c: api.map_rig(r.name), TypeError, "armature object"),
    "map_rig(mesh)": (lambda s, r, c: api.map_rig(_mesh(s)), ValueError, "'Cube' is a mesh"),
    "bind_curve(None)": (lambda s, r, c: api.bind_curve(None, "LWrist", c), TypeError, "armature object"),
    "bind_curve(mesh rig)": (lambda s, r, c: api.bind_curve(_mesh(s), "LWrist", c), ValueError, "is a mesh"),
    "bind_curve(curve None)": (lambda s, r, c: api.bind_curve(r, "LWrist", None), TypeError,
                               "curve or grease pencil object, not None"),
    "bind_curve(mesh curve)": (lambda s, r, c: api.bind_curve(r, "LWrist", _mesh(s)), ValueError,
                               "'Cube' is a mesh, not a curve"),
    "bind_curve(deleted curve)": (lambda s, r, c: api.bind_curve(r, "LWrist", _deleted(s)), ValueError,
                                  "has been deleted"),
    "bind_curve(no such bone)": (lambda s, r, c: api.bind_curve(r, "nonexistent", c), ValueError,
                                 "has no bone 'nonexistent'"),
    "bind_curve(bone None)": (lambda s, r, c: api.bind_curve(r, None, c), TypeError, "bone's name"),
    "bind_curve(speed 1)": (lambda s, r, c: api.bind_curve(r, "LWrist", c, 1), TypeError, "True or False"),
    "bind_curve(speed 'no')": (lambda s, r, c: api.bind_curve(r, "LWrist", c, "no"), TypeError, "True or False"),
    "unbind(None)": (lambda s, r, c: api.unbind(None, "LWrist"), TypeError, "armature object"),
    "unbind(bone 3)": (lambda s, r, c: api.unbind(r, 3), TypeError, "bone's name"),
    "unbind(unbound)": (lambda s, r, c: api.unbind(r, "LWrist"), ValueError, "no path is bound to 'LWrist'"),
}


@pytest.mark.parametrize("name", BAD_CALLS)
def test_bad_api_arguments_are_one_sentence_and_write_nothing(scene, rig, name):
    call, error, words = BAD_CALLS[name]
    curve = _curve(scene, "path")
    with pytest.raises(error) as refused:
        call(scene, rig, curve)
    message = str(refused.value)
    assert words in message and "\n" not in message and not isinstance(refused.value, AttributeError)
    assert len(rig.trajevae.bindings) == 0 and not any(bone.trajevae_tag for bone in rig.pose.bones)


def test_linked_and_override_rigs_are_refused_with_the_way_out(scene, rig, tmp_path):
    library = str(tmp_path / "rig library.blend")
    bpy.data.libraries.write(library, {rig})
    with bpy.data.libraries.load(library, link=True) as (source, linked):
        linked.objects = [rig.name]
    linked_rig = linked.objects[0]
    scene.collection.objects.link(linked_rig)
    path = _curve(scene, "path")
    with pytest.raises(ValueError, match=r"is linked from .* make it local first \(Object > Relations > Make Local\)"):
        api.bind_curve(linked_rig, "LWrist", path)
    override = linked_rig.override_create(remap_local_usages=True)
    with pytest.raises(ValueError, match=r"library override.* make it local first"):
        api.bind_curve(override, "LWrist", path)
    assert len(linked_rig.trajevae.bindings) == len(override.trajevae.bindings) == 0
    for obj in bpy.context.view_layer.objects:
        obj.select_set(obj == override)
    bpy.context.view_layer.objects.active = override
    assert bpy.ops.object.make_local(type='SELECT_OBJECT') == {'FINISHED'}  # the way out works
    api.bind_curve(override, "LWrist", path)
    assert [b.bone for b in override.trajevae.bindings] == ["LWrist"]


def test_unregister_removes_the_bone_tag(scene):
    trajevae_addon.unregister()
    assert not hasattr(bpy.types.PoseBone, "trajevae_tag")
    trajevae_addon.register()
    assert hasattr(bpy.types.PoseBone, "trajevae_tag")
