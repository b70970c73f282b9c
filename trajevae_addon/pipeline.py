"""Generate N variants on a rig: read the rig and its curves, run the model, retarget, write Actions.

Synchronous and free of UI, so operators, scripts and tests share it. The
model runs at its native 30 fps in metres; the scene's rate, units and the
rig's size are converted at this boundary.
"""

import time
from dataclasses import dataclass, field

import bpy
import numpy as np

from . import actions, curves, inference, rig_mapping, rig_state, variants
from .runtime import generation, retarget, skeleton

J = skeleton.JOINT_INDEX


@dataclass
class Report:
    """What one generation did: the new actions, seconds per stage (read, inference, retarget,
    write), and what was keyed: frames (F,) and per variant {bone: matrix_basis (F, 4, 4)}."""

    actions: list = field(default_factory=list)
    seconds: dict = field(default_factory=dict)
    frames: np.ndarray = None
    bases: list = field(default_factory=list)


def bound_joints(armature, bones):
    """[(joint, curve object)] of the armature's bindings, checked against its mapping."""
    joint_of = {bone: joint for joint, bone in bones.items() if bone}
    out = []
    for binding in armature.trajevae.bindings:
        if binding.curve is None:
            continue
        joint = joint_of.get(binding.bone)
        if joint is None:
            raise rig_state.RigError(f"bone {binding.bone!r} is bound to {binding.curve.name!r} but carries no "
                                     "joint; bind a mapped bone (hand, foot, ...)")
        out.append((joint, binding.curve))
    return out


def scene_frames(scene):
    start, end = scene.frame_start, scene.frame_end
    if end - start < 1:
        raise rig_state.RigError(f"the frame range {start}-{end} is a single frame; set a longer range")
    return np.arange(start, end + 1)


def generate_variants(armature, count=5, seed=0, diversity=1.0, scene=None, progress=None):
    """New variant Actions on ``armature`` over the scene frame range; returns a Report."""
    scene = scene or bpy.context.scene
    progress = progress or (lambda fraction: None)
    if armature is None or armature.type != 'ARMATURE':
        raise rig_state.RigError("select an armature to generate motion for")
    report, clock = Report(), time.perf_counter()
    bones = rig_state.checked_mapping(armature)
    profile_name, _ = rig_state.detected(armature)
    switches = rig_mapping.switches(profile_name)
    frames = scene_frames(scene)
    fps = scene.render.fps / scene.render.fps_base

    current = scene.frame_current
    if current != frames[0]:
        scene.frame_set(int(frames[0]))
    depsgraph = bpy.context.evaluated_depsgraph_get()
    rig, joints = rig_state.read(armature, bones, depsgraph)
    before = rig_state.current_switches(armature, switches)
    floor = armature.matrix_world.translation.z
    placement = generation.Placement.for_pose(joints, floor, scene.unit_settings.scale_length)
    model_frames = generation.model_frames(len(frames), fps)
    span = (len(frames) - 1) * generation.NATIVE_FPS / fps
    trajectories = np.zeros((model_frames, skeleton.NUM_JOINTS, 3), np.float32)
    mask = np.zeros((model_frames, skeleton.NUM_JOINTS), np.float32)
    bound = bound_joints(armature, bones)
    for joint, curve in bound:
        path = generation.curve_samples(curves.polyline(curve, depsgraph), model_frames, span)
        trajectories[:, J[joint]] = placement.to_model(path[1:])
        mask[:, J[joint]] = 1.0
    if current != frames[0]:
        scene.frame_set(current)
    report.seconds["read"] = time.perf_counter() - clock
    progress(0.1)

    clock = time.perf_counter()
    motion = generation.generate(inference.model(), placement.to_model(joints), trajectories, mask, count,
                                 np.random.default_rng(seed), diversity, inference.sampler())
    motion[:, 1:] = np.where(mask[None, ..., None] > 0, trajectories[None], motion[:, 1:])  # exactly on the curves
    world = generation.to_scene_rate(placement.to_world(motion.astype(np.float64)), len(frames), fps)
    report.seconds["inference"] = time.perf_counter() - clock
    progress(0.5)

    targets = rig_state.to_armature_space(armature, world)
    variants.record_original(armature, before)
    clock = time.perf_counter()  # all variants in one batch of count x F frames
    flat = retarget.bone_bases(rig, retarget.joint_deltas(rig, targets.reshape(-1, *targets.shape[2:])))
    report.bases = [{bone: basis.reshape(count, len(frames), 4, 4)[index] for bone, basis in flat.items()}
                    for index in range(count)]
    retarget_seconds = time.perf_counter() - clock
    clock, numbered = time.perf_counter(), len(armature.trajevae.variants) + 1
    for index, bases in enumerate(report.bases):
        report.actions.append(actions.write(armature, f"{armature.name} variant {numbered + index:02d}", frames,
                                            bases, bones["Hip"], switches))
        progress(0.5 + 0.5 * (index + 1) / count)
    write_seconds = time.perf_counter() - clock
    report.seconds["retarget"], report.seconds["write"] = retarget_seconds, write_seconds
    report.frames = frames
    variants.add(armature, report.actions)
    return report
