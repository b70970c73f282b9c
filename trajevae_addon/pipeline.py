"""Generate N variants on a rig: read the rig, its curves and keys, run the model, retarget, write.

Three steps so the UI can stay responsive: ``prepare`` reads the scene (main
thread), ``infer`` runs the networks (any thread, cancellable, touches no
bpy data), ``finish`` retargets and writes the Actions (main thread). Until
``finish`` nothing is written, so a cancelled job leaves the file as it was.
``generate_variants`` runs all three for scripts. The model runs at its
native 30 fps in metres; the scene's rate, units and the rig's size are
converted here.
"""

import threading
import time
from dataclasses import dataclass, field

import bpy
import numpy as np

from . import actions, bindings, curves, inference, rig_mapping, rig_state, variants
from .runtime import generation, retarget, skeleton

J = skeleton.JOINT_INDEX


class Cancelled(Exception):
    pass


@dataclass
class Job:
    """One generation's inputs (read from the scene) and, after ``infer``, its motion."""

    count: int
    seed: int
    diversity: float
    bones: dict
    switches: dict
    switches_before: dict
    frames: np.ndarray  # (F,) scene frames
    fps: float
    metres_per_unit: float
    rig: object  # retarget.RigState
    initial: np.ndarray  # (17, 3) model frame
    placement: object  # generation.Placement
    trajectories: np.ndarray  # (T, 17, 3) model frame, frames after the initial one
    mask: np.ndarray  # (T, 17)
    curve_paths: dict  # joint -> (F, 3) world positions the curve asks for on each scene frame
    world_to_armature: np.ndarray  # (4, 4)
    seconds: dict = field(default_factory=dict)
    motion: np.ndarray = None  # (count, F, 17, 3) world, at the scene's frames
    progress: float = 0.0
    cancel_event: threading.Event = field(default_factory=threading.Event)


@dataclass
class Report:
    """What one generation did: the new actions, seconds per stage (read, inference, retarget,
    write), what was keyed (frames (F,), per variant {bone: matrix_basis (F, 4, 4)}), and per
    variant the mean distance of curve-bound joints to their curves where the rig can reach
    them, the share of frames it cannot, and the distance to the nearest other variant (m)."""

    actions: list = field(default_factory=list)
    seconds: dict = field(default_factory=dict)
    frames: np.ndarray = None
    bases: list = field(default_factory=list)
    curve_error_m: list = field(default_factory=list)
    out_of_reach: list = field(default_factory=list)
    difference_m: list = field(default_factory=list)


def scene_frames(scene):
    start, end = scene.frame_start, scene.frame_end
    if end - start < 1:
        raise rig_state.RigError(f"the frame range {start}-{end} is a single frame; set a longer range")
    return np.arange(start, end + 1)


def _artist_action(armature):
    """The artist's own action: the recorded original while variants are shown."""
    settings = armature.trajevae
    animation = armature.animation_data
    if settings.has_original:
        return settings.original_action
    return animation.action if animation else None


def _key_frames(action, bones, frames):
    """{scene frame: keyed bones} of the action's keys on ``bones`` inside ``frames``, start excluded."""
    out = {}
    if action is None:
        return out
    for layer in action.layers:
        for strip in layer.strips:
            for bag in strip.channelbags:
                for fcurve in bag.fcurves:
                    if not fcurve.data_path.startswith('pose.bones["'):
                        continue
                    bone = fcurve.data_path.split('"')[1]
                    if bone not in bones:
                        continue
                    keys = np.empty(len(fcurve.keyframe_points) * 2)
                    fcurve.keyframe_points.foreach_get("co", keys)
                    for frame in np.round(keys[0::2]).astype(int):
                        if frames[0] < frame <= frames[-1]:
                            out.setdefault(int(frame), set()).add(bone)
    return out


def _joints_of_keyed_bone(rig, bone):
    """A key on a bone fixes its own joint and the joints of the bones it carries directly."""
    joint_of = {b: j for j, b in rig.bones.items()}
    return [joint_of[bone]] + [joint_of[child] for child, driver in rig.drivers.items() if driver == bone]


def _with_artist_action(armature, read):
    """Run ``read()`` with the artist's own action playing (variants may be shown)."""
    animation = armature.animation_data
    settings = armature.trajevae
    if not settings.has_original or animation is None:
        return read()
    shown, shown_slot = animation.action, animation.action_slot
    animation.action = settings.original_action
    if settings.original_action is not None and settings.original_slot:
        animation.action_slot = next((s for s in settings.original_action.slots
                                      if s.identifier == settings.original_slot), animation.action_slot)
    try:
        return read()
    finally:
        animation.action = shown
        if shown is not None:
            animation.action_slot = shown_slot


def prepare(armature, count=5, seed=0, diversity=1.0, scene=None):
    """Read everything a generation needs from the scene (main thread): a Job."""
    clock = time.perf_counter()
    scene = scene or bpy.context.scene
    if armature is None or armature.type != 'ARMATURE':
        raise rig_state.RigError("select an armature to generate motion for")
    bones = rig_state.checked_mapping(armature)
    profile = rig_state.detected(armature)[0]
    shown_by = rig_mapping.shown_by(profile)
    switches = {**rig_mapping.switches(profile), **bindings.muted_path_constraints(armature, bones)}
    switches_before = rig_state.current_switches(armature, switches)
    switches = {path: value for path, value in switches.items() if path in switches_before}
    frames = scene_frames(scene)
    fps = scene.render.fps / scene.render.fps_base
    metres_per_unit = scene.unit_settings.scale_length

    def read_scene():
        current = scene.frame_current
        key_frames = _key_frames(_artist_action(armature), set(bones.values()), frames)
        poses = {}
        for frame in [int(frames[0])] + sorted(key_frames):
            if frame != scene.frame_current:
                scene.frame_set(frame)
            poses[frame] = rig_state.read(armature, bones, bpy.context.evaluated_depsgraph_get(), shown_by)
        if scene.frame_current != current:
            scene.frame_set(current)
        return key_frames, poses

    key_frames, poses = _with_artist_action(armature, read_scene)
    rig, joints = poses[int(frames[0])]
    depsgraph = bpy.context.evaluated_depsgraph_get()
    placement = generation.Placement.for_pose(joints, armature.matrix_world.translation.z, metres_per_unit)
    model_frames = generation.model_frames(len(frames), fps)
    span = (len(frames) - 1) * generation.NATIVE_FPS / fps
    trajectories = np.zeros((model_frames, skeleton.NUM_JOINTS, 3), np.float32)
    mask = np.zeros((model_frames, skeleton.NUM_JOINTS), np.float32)
    for frame, keyed in key_frames.items():  # keys constrain their joints on their frames only
        time_in_model = (frame - frames[0]) * generation.NATIVE_FPS / fps
        steps = {int(np.floor(time_in_model)), int(np.ceil(time_in_model))} - {0}  # both sides of the key
        for joint in {j for bone in keyed for j in _joints_of_keyed_bone(rig, bone)}:
            for step in steps:
                trajectories[step - 1, J[joint]] = placement.to_model(poses[frame][1][J[joint]])
                mask[step - 1, J[joint]] = 1.0
    curve_paths = {}
    paths, warnings = bindings.joint_paths(armature, bones)
    for joint, (obj, use_drawing_speed) in paths.items():
        points, times = curves.path(obj, depsgraph, int(frames[0]))
        times = times if use_drawing_speed else None
        trajectories[:, J[joint]] = placement.to_model(
            generation.curve_samples(points, model_frames, span, times)[1:])
        mask[:, J[joint]] = 1.0
        curve_paths[joint] = generation.curve_samples(points, len(frames) - 1, len(frames) - 1, times)
    return Job(count, seed, diversity, bones, switches, switches_before, frames, fps,
               metres_per_unit, rig,
               placement.to_model(joints), placement, trajectories, mask, curve_paths,
               np.linalg.inv(np.array(armature.matrix_world, dtype=np.float64)),
               seconds={"read": time.perf_counter() - clock})


def infer(job, on_progress=None):
    """Run the networks for a prepared job (any thread; no bpy). Raises Cancelled once
    ``job.cancel_event`` is set; ``job.progress`` (0 to 1) follows the windows."""
    clock = time.perf_counter()

    def step(fraction):
        job.progress = 0.9 * fraction
        if on_progress is not None:
            on_progress(job.progress)
        if job.cancel_event.is_set():
            raise Cancelled()

    # The diverse sampler where nothing is given; with curves or keys the prior's own samples follow
    # them more closely and skip the sampler's larger pool of draws.
    sampler = None if job.mask.any() else inference.sampler()
    motion = generation.generate(inference.model(), job.initial, job.trajectories, job.mask, job.count,
                                 np.random.default_rng(job.seed), job.diversity, sampler, progress=step)
    known = job.mask[None, ..., None] > 0
    motion[:, 1:] = np.where(known, job.trajectories[None], motion[:, 1:])  # exactly on curves and keys
    job.motion = generation.to_scene_rate(job.placement.to_world(motion.astype(np.float64)), len(job.frames),
                                          job.fps)
    job.seconds["inference"] = time.perf_counter() - clock


def finish(job, armature):
    """Retarget the job's motion onto the rig and write one Action per variant (main thread)."""
    report = Report(seconds=dict(job.seconds), frames=job.frames)
    clock = time.perf_counter()  # all variants in one batch of count x F frames
    count, frames = job.count, len(job.frames)
    targets = job.motion @ job.world_to_armature[:3, :3].T + job.world_to_armature[:3, 3]
    known = np.concatenate([np.zeros((1, job.mask.shape[1])), job.mask])[..., None]  # initial frame free
    pinned = generation.to_scene_rate(np.repeat(known, 3, axis=-1), frames, job.fps)[..., 0] > 0.999
    deltas = retarget.joint_deltas(job.rig, targets.reshape(-1, *targets.shape[2:]),
                                   np.tile(pinned, (count, 1)).astype(float))
    flat = retarget.bone_bases(job.rig, deltas)
    report.bases = [{bone: basis.reshape(count, frames, 4, 4)[index] for bone, basis in flat.items()}
                    for index in range(count)]
    report.seconds["retarget"] = time.perf_counter() - clock
    _measure(job, report, retarget.achieved_joints(job.rig, deltas).reshape(count, frames, -1, 3), armature)

    clock = time.perf_counter()
    variants.record_original(armature, job.switches_before)
    numbered = len(armature.trajevae.variants) + 1
    for index, bases in enumerate(report.bases):
        report.actions.append(actions.write(armature, f"{armature.name} variant {numbered + index:02d}",
                                            job.frames, bases, job.bones["Hip"], job.switches))
    report.seconds["write"] = time.perf_counter() - clock
    variants.add(armature, report.actions, report.curve_error_m, report.difference_m)
    return report


def _measure(job, report, achieved, armature):
    """Per variant: mean distance of curve-bound joints to their curves on the frames the rig can
    reach them (and the share it cannot), and mean joint distance to the nearest other variant."""
    world = np.array(armature.matrix_world, dtype=np.float64)
    to_armature = lambda points: points @ job.world_to_armature[:3, :3].T + job.world_to_armature[:3, 3]
    for index in range(job.count):
        errors, out_of_reach = [], []
        for joint, path in job.curve_paths.items():
            reach = retarget.reachable(job.rig, achieved[index], to_armature(path), joint)
            placed = achieved[index, :, J[joint]] @ world[:3, :3].T + world[:3, 3]
            errors.extend(np.linalg.norm(placed - path, axis=-1)[reach])
            out_of_reach.append(1.0 - reach.mean())
        report.curve_error_m.append(float(np.mean(errors)) * job.metres_per_unit if errors else 0.0)
        report.out_of_reach.append(float(np.mean(out_of_reach)) if out_of_reach else 0.0)
        others = [np.linalg.norm(job.motion[index] - job.motion[other], axis=-1).mean()
                  for other in range(job.count) if other != index]
        report.difference_m.append(float(min(others)) * job.metres_per_unit if others else 0.0)


def generate_variants(armature, count=5, seed=0, diversity=1.0, scene=None):
    """New variant Actions on ``armature`` over the scene frame range, synchronously: a Report.
    Headless runs print progress for frame ranges longer than one model window."""
    job = prepare(armature, count, seed, diversity, scene)
    long_job = bpy.app.background and len(job.trajectories) > inference.model().frames
    infer(job, (lambda fraction: print(f"TrajeVAE {armature.name}: {100 * fraction:.0f}%", flush=True))
          if long_job else None)
    return finish(job, armature)
