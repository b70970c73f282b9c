"""Generate N variants on a rig: read the rig, its curves and keys, run the model, retarget, write.

Three steps so the UI can stay responsive: ``prepare`` reads and checks the
scene (main thread), ``infer`` runs the networks and the retarget (any
thread, cancellable, touches no bpy data), and a ``Writer`` writes the
Actions and measures them as Blender plays them (main thread, in short steps).
Every input is checked before anything is written, and a Writer that fails
or is cancelled at any step puts the file back as it was.
``generate_variants`` runs all of it for scripts. The model runs at its
native 30 fps in metres; the scene's rate, units, the rig's size and its
(possibly moving) object transform are converted here.
"""

import json
import math
import numbers
import threading
import time
from dataclasses import dataclass, field

import bpy
import numpy as np

from . import actions, bindings, curves, inference, rig_mapping, rig_state, variants
from .runtime import generation, retarget, skeleton

J = skeleton.JOINT_INDEX

MAX_VARIANTS = 50
MAX_DIVERSITY = 2.0
# Drawn input a body cannot follow, refused before generating: a joint's mean speed along its curve
# (captured hands and feet peak near 20 m/s for a moment, a sprinter's body holds about 10 m/s), the
# jump from the joint to its curve's first point, and how far a curve dips below the rig's feet.
MAX_MEAN_SPEED_M_S = 12.0
MAX_START_GAP_M = 1.0
MAX_BELOW_FEET_M = 0.2
# A bound joint further from its curve than this as Blender plays it is reported with its cause.
PLAYED_TOLERANCE_M = 0.01
# Frame evaluations spent measuring the curve error as played, shared by the variants (at least
# MIN_MEASURED_FRAMES each), and frames compared for the distance between variants.
MEASURED_FRAME_BUDGET = 240
MIN_MEASURED_FRAMES = 8
COMPARED_FRAMES = 300
# Where each stage ends on the progress bar: networks and retarget (worker), keys and measuring (main).
PROGRESS_END = {"inference": 0.6, "retarget": 0.8, "write": 0.95, "measure": 1.0}
# Main-thread seconds a Writer step may take before it hands control back to the interface, and
# the keys it writes between looks at the clock (about 0.05 s of writing).
STEP_SECONDS = 0.1
CHUNK_KEYS = 200_000
# Keys of one generation above which its variants are stored as baked samples, a sixth of a key's
# memory: 50 variants of 10,000 frames would otherwise hold 2.4 GB of keys.
MAX_KEYS = 8_000_000


class InputError(ValueError):
    """An argument or a drawn input generation cannot use; the message says what to change."""


class Cancelled(Exception):
    pass


USER_ERRORS = (InputError, rig_state.RigError, curves.CurveError, inference.WeightsError)


@dataclass
class Job:
    """One generation's inputs (read from the scene) and, after ``infer``, its motion and keys."""

    count: int
    seed: int
    diversity: float
    bones: dict
    rotation_modes: dict  # keyed bone -> its rotation mode
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
    curve_names: dict  # joint -> name of the curve object
    world_to_armature: np.ndarray  # (F, 4, 4), or (1, 4, 4) for a rig that stays put
    shown_by: dict  # keyed bone -> the bone showing its visible pose (see rig_state.read)
    warnings: list = field(default_factory=list)
    seconds: dict = field(default_factory=dict)
    motion: np.ndarray = None  # (count, F, 17, 3) world, at the scene's frames
    channels: list = None  # per variant, actions.key_channels output
    shortfall: list = None  # per variant {joint: (F,) distance beyond the limb's reach, world units}
    difference: list = None  # per variant, mean joint distance to the nearest other one (world units)
    progress: float = 0.0
    cancel_event: threading.Event = field(default_factory=threading.Event)


@dataclass
class Report:
    """What one generation did: the new actions, seconds per stage (read, inference, retarget,
    write, measure), what was keyed (frames (F,), per variant actions.key_channels output), and
    per variant the mean distance of curve-bound joints to their curves as Blender plays them
    (on the frames the rig can reach them), the share of frames it cannot, and the distance to
    the nearest other variant (m); ``warnings``: sentences for the artist."""

    actions: list = field(default_factory=list)
    seconds: dict = field(default_factory=dict)
    frames: np.ndarray = None
    channels: list = field(default_factory=list)
    curve_error_m: list = field(default_factory=list)
    out_of_reach: list = field(default_factory=list)
    difference_m: list = field(default_factory=list)
    warnings: list = field(default_factory=list)


def check_arguments(count, seed, diversity):
    """InputError with a sentence for a variant count, seed or diversity generation cannot take."""
    def whole(value):
        return isinstance(value, numbers.Integral) and not isinstance(value, bool)

    if not whole(count) or not 1 <= count <= MAX_VARIANTS:
        raise InputError(f"the number of variants must be a whole number from 1 to {MAX_VARIANTS}, not {count!r}")
    if not whole(seed) or not 0 <= seed < 2 ** 63:
        raise InputError(f"the seed must be a whole number of 0 or more, not {seed!r}")
    if (not isinstance(diversity, numbers.Real) or isinstance(diversity, bool) or not math.isfinite(diversity)
            or not 0.0 <= diversity <= MAX_DIVERSITY):
        raise InputError(f"diversity must be a number from 0 to {MAX_DIVERSITY:g}, not {diversity!r}")


def scene_frames(scene):
    start, end = scene.frame_start, scene.frame_end
    if end - start < 1:
        raise rig_state.RigError(f"the frame range {start}-{end} is a single frame; set a longer range")
    return np.arange(start, end + 1)


def _fcurves(action):
    """Every F-curve of every slot of an action (none for None)."""
    if action is None:
        return
    for layer in action.layers:
        for strip in layer.strips:
            for bag in strip.channelbags:
                yield from bag.fcurves


def _key_frames(action, bones, frames):
    """{scene frame: keyed bones} of the action's keys on ``bones`` inside ``frames``, start excluded."""
    out = {}
    for fcurve in _fcurves(action):
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


def _moves_in_world(armature, action):
    """Whether the armature object's world transform may change over frames (parent, object
    constraints, drivers or object-level keys), so it has to be read on every frame."""
    animation = armature.animation_data
    return (armature.parent is not None or len(armature.constraints) > 0
            or (animation is not None and len(animation.drivers) > 0)
            or any(not fcurve.data_path.startswith("pose.") for fcurve in _fcurves(action)))


def _joints_of_keyed_bone(rig, bone):
    """A key on a bone fixes its own joint and the joints of the bones it carries directly."""
    joint_of = {b: j for j, b in rig.bones.items()}
    return [joint_of[bone]] + [joint_of[child] for child, driver in rig.drivers.items() if driver == bone]


def _with_artist_action(armature, read):
    """Run ``read()`` with the artist's own action and pose in place (variants may be shown)."""
    animation = armature.animation_data
    settings = armature.trajevae
    if not settings.has_original or animation is None:
        return read()
    shown, shown_slot = animation.action, animation.action_slot
    shown_pose = rig_state.pose_snapshot(armature)
    rig_state.restore_pose(armature, json.loads(settings.original_pose))
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
        rig_state.restore_pose(armature, shown_pose)


def _check_reach(job, bones, start_joints):
    """InputError naming each curve a body cannot follow, and by how much (world joints (17, 3) at
    the start frame). Limits hold for the body as the model sees it (rigs outside the trained
    size are scaled to it) and are said in scene metres."""
    to_body = job.placement.scale / job.metres_per_unit  # scene metres -> the model's metres
    feet = min(start_joints[J["LFoot"]][2], start_joints[J["RFoot"]][2])
    seconds = (len(job.frames) - 1) / job.fps
    problems = []
    for joint, path in job.curve_paths.items():
        name = f"curve {job.curve_names[joint]!r} ({bones[joint]})"
        gap = np.linalg.norm(path[0] - start_joints[J[joint]]) * job.metres_per_unit
        if gap * to_body > MAX_START_GAP_M:
            problems.append(f"{name} starts {gap:.2f} m from its joint, which can jump at most "
                            f"{MAX_START_GAP_M / to_body:.2g} m onto it; draw it from the joint")
        length = np.linalg.norm(np.diff(path, axis=0), axis=-1).sum() * job.metres_per_unit
        if length / seconds * to_body > MAX_MEAN_SPEED_M_S:
            problems.append(f"{name} is {length:.1f} m long, {length / seconds:.3g} m/s over the {seconds:.1f} s "
                            f"frame range where this body manages about {MAX_MEAN_SPEED_M_S / to_body:.3g} m/s; "
                            "shorten it or lengthen the range")
        below = (feet - path[:, 2].min()) * job.metres_per_unit
        if below * to_body > MAX_BELOW_FEET_M:
            problems.append(f"{name} goes {below:.2f} m below the feet, through the floor")
    if problems:
        raise InputError("out of reach: " + "; ".join(problems))


def prepare(armature, count=5, seed=0, diversity=1.0, scene=None):
    """Read and check everything a generation needs from the scene (main thread): a Job.
    Raises one of USER_ERRORS, with a sentence, for anything it cannot use."""
    clock = time.perf_counter()
    check_arguments(count, seed, diversity)
    scene = scene or bpy.context.scene
    bones = rig_state.checked_mapping(armature)
    profile = rig_state.detected(armature)[0]
    shown_by = rig_mapping.shown_by(profile)
    switches = {**rig_mapping.switches(profile), **bindings.muted_path_constraints(armature, bones)}
    switches_before = rig_state.current_switches(armature, switches)
    switches = {path: value for path, value in switches.items() if path in switches_before}
    frames = scene_frames(scene)
    fps = scene.render.fps / scene.render.fps_base
    metres_per_unit = scene.unit_settings.scale_length
    if not metres_per_unit > 0.0 or not math.isfinite(metres_per_unit):
        raise InputError(f"the scene's unit scale {metres_per_unit!r} must be a positive number")
    paths, warnings = bindings.joint_paths(armature, bones)

    def read_scene():
        current = scene.frame_current
        action = armature.animation_data.action if armature.animation_data else None
        key_frames = _key_frames(action, set(bones.values()), frames)
        moves = _moves_in_world(armature, action)
        poses, world = {}, []
        try:
            for frame in sorted({int(frames[0]), *key_frames} | (set(frames.tolist()) if moves else set())):
                scene.frame_set(frame)  # even the current one: the scene as played, not as last edited
                if frame == frames[0] or frame in key_frames:
                    poses[frame] = rig_state.read(armature, bones, bpy.context.evaluated_depsgraph_get(), shown_by)
                    rig_state.check_finite(armature, poses[frame][0], frame)
                if moves:
                    world.append(np.array(armature.matrix_world, dtype=np.float64))
        finally:
            scene.frame_set(current)
        world = np.array(world) if moves else np.array(armature.matrix_world, dtype=np.float64)[None]
        return key_frames, poses, world

    key_frames, poses, world = _with_artist_action(armature, read_scene)
    if not np.isfinite(world).all() or abs(np.linalg.det(world[:, :3, :3])).min() < 1e-12:
        raise rig_state.RigError(f"{armature.name!r}: its object transform is not a number or flattens it "
                                 "(zero scale) on some frame; fix it before generating")
    rig, joints = poses[int(frames[0])]
    placement = generation.Placement.for_pose(joints, world[0][2, 3], metres_per_unit)
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
    curve_paths, curve_names = {}, {}
    for joint, (obj, use_drawing_speed) in paths.items():
        points, times = curves.path(obj, int(frames[0]))
        times = times if use_drawing_speed else None
        trajectories[:, J[joint]] = placement.to_model(
            generation.curve_samples(points, model_frames, span, times)[1:])
        mask[:, J[joint]] = 1.0
        curve_paths[joint] = generation.curve_samples(points, len(frames) - 1, len(frames) - 1, times)
        curve_names[joint] = obj.name
    inference.model()  # loaded here, so missing or broken weights are said before any work
    if not mask.any():
        note = inference.missing_sampler_note()
        if note:
            warnings.append(note)
        inference.sampler()
    job = Job(count, seed, diversity, bones, {bone: armature.pose.bones[bone].rotation_mode
                                              for bone in rig.bones.values()},
              switches, switches_before, frames, fps, metres_per_unit, rig, placement.to_model(joints), placement,
              trajectories, mask, curve_paths, curve_names, np.linalg.inv(world), shown_by, warnings)
    _check_reach(job, bones, joints)
    job.seconds["read"] = time.perf_counter() - clock
    return job


def _to_armature(world_to_armature, points):
    """World points (F, ..., 3) in armature space with per-frame (F or 1, 4, 4) inverses."""
    rotation = world_to_armature[:, :3, :3].reshape(-1, *([1] * (points.ndim - 2)), 3, 3)
    offset = world_to_armature[:, :3, 3].reshape(-1, *([1] * (points.ndim - 2)), 3)
    return (rotation @ points[..., None])[..., 0] + offset


def infer(job, on_progress=None):
    """Run the networks and the retarget for a prepared job (any thread; no bpy). Raises Cancelled
    once ``job.cancel_event`` is set; ``job.progress`` (0 to 1) follows the work."""
    clock = time.perf_counter()

    def advance(progress):
        job.progress = progress
        if on_progress is not None:
            on_progress(job.progress)
        if job.cancel_event.is_set():
            raise Cancelled()

    # The diverse sampler where nothing is given; with curves or keys the prior's own samples follow
    # them more closely and skip the sampler's larger pool of draws.
    sampler = None if job.mask.any() else inference.sampler()
    motion = generation.generate(inference.model(), job.initial, job.trajectories, job.mask, job.count,
                                 np.random.default_rng(job.seed), job.diversity, sampler,
                                 progress=lambda fraction: advance(PROGRESS_END["inference"] * fraction))
    known = job.mask[None, ..., None] > 0
    motion[:, 1:] = np.where(known, job.trajectories[None], motion[:, 1:])  # exactly on curves and keys
    job.motion = np.empty((job.count, len(job.frames), skeleton.NUM_JOINTS, 3))
    for index in range(job.count):  # one variant at a time: resampling makes copies
        job.motion[index] = generation.to_scene_rate(job.placement.to_world(motion[index].astype(np.float64)),
                                                     len(job.frames), job.fps)
    del motion
    for joint, path in job.curve_paths.items():  # on each scene frame, exactly where its curve is
        job.motion[:, :, J[joint]] = path
    if not np.isfinite(job.motion).all():
        job.motion = None
        raise InputError("the model returned motion that is not a number for this input; nothing was written")
    job.seconds["inference"] = time.perf_counter() - clock
    _retarget(job, advance)


def _retarget(job, advance):
    """Key channels, reach shortfalls and differences of every variant, one variant at a time so
    memory stays that of one variant's matrices."""
    clock = time.perf_counter()
    frames = len(job.frames)
    known = np.concatenate([np.zeros((1, job.mask.shape[1])), job.mask])[..., None]  # initial frame free
    pinned = (generation.to_scene_rate(np.repeat(known, 3, axis=-1), frames, job.fps)[..., 0] > 0.999).astype(float)
    job.channels, job.shortfall = [], []
    world_scale = np.abs(np.linalg.det(job.world_to_armature[:, :3, :3])) ** (-1.0 / 3.0)  # (F or 1,)
    start = PROGRESS_END["inference"]
    for index in range(job.count):
        targets = _to_armature(job.world_to_armature, job.motion[index])
        deltas = retarget.joint_deltas(job.rig, targets, pinned)
        channels = actions.key_channels(retarget.bone_bases(job.rig, deltas), job.rotation_modes, job.bones["Hip"])
        if not all(np.isfinite(values).all() for _, _, values in channels):
            raise InputError("the retarget returned keys that are not a number for this rig; nothing was written")
        job.channels.append(channels)
        achieved = retarget.achieved_joints(job.rig, deltas)
        job.shortfall.append({joint: world_scale * retarget.reach_shortfall(
            job.rig, achieved, _to_armature(job.world_to_armature, path), joint)
            for joint, path in job.curve_paths.items()})
        advance(start + (PROGRESS_END["retarget"] - start) * (index + 1) / job.count)
    compared = job.motion[:, np.unique(np.linspace(0, frames - 1, min(frames, COMPARED_FRAMES)).astype(int))]
    job.difference = [min((float(np.linalg.norm(compared[index] - compared[other], axis=-1).mean())
                           for other in range(job.count) if other != index), default=0.0)
                      for index in range(job.count)]
    job.seconds["retarget"] = time.perf_counter() - clock


CONSTRAINT_KINDS = bpy.types.Constraint.bl_rna.properties["type"].enum_items


def _blame(armature, bone):
    """A phrase naming what moves ``bone`` away from its keys as played: active constraints on it
    or its parents, or drivers on their channels; None when nothing is found."""
    causes = []
    pose_bone = armature.pose.bones.get(bone)
    while pose_bone is not None:
        causes += [f"constraint {c.name!r} ({CONSTRAINT_KINDS[c.type].name}) on {pose_bone.name!r}"
                   for c in pose_bone.constraints if not c.mute and c.influence > 0.0
                   and c.type not in bindings.PATH_CONSTRAINTS]
        pose_bone = pose_bone.parent
    animation = armature.animation_data
    driven = [d.data_path for d in (animation.drivers if animation else ()) if d.data_path.startswith("pose.bones[")]
    causes += [f"a driver on {path}" for path in driven if path.split('"')[1] in _chain(armature, bone)]
    return ", ".join(causes) or None


def _chain(armature, bone):
    names, data_bone = [], armature.data.bones.get(bone)
    while data_bone is not None:
        names.append(data_bone.name)
        data_bone = data_bone.parent
    return names


class Writer:
    """Writes a job's variants onto the armature in short main-thread steps, then plays each one
    to measure its curve error as Blender evaluates it. ``rollback`` undoes everything it did.

    Usage: ``writer = Writer(job, armature)``, then ``writer.step()`` until ``writer.done``
    (each step takes about STEP_SECONDS), then ``writer.report``."""

    def __init__(self, job, armature):
        self.job, self.armature, self.scene = job, armature, bpy.context.scene
        missing = sorted(bone for bone in job.rotation_modes if bone not in armature.pose.bones)
        if missing:
            raise rig_state.RigError(f"bone {', '.join(map(repr, missing))} of {armature.name!r} was renamed or "
                                     "deleted during generation; nothing was written, generate again")
        reason = rig_state.unusable_reason(armature)
        if reason:
            raise rig_state.RigError(reason)
        changed = sorted(bone for bone, mode in job.rotation_modes.items()
                         if armature.pose.bones[bone].rotation_mode != mode)
        if changed:
            raise rig_state.RigError(f"the rotation mode of {', '.join(map(repr, changed))} changed during "
                                     "generation; nothing was written, generate again")
        animation = armature.animation_data
        self._animation_before = None if animation is None else (animation.action, animation.action_slot)
        self._pose_before = rig_state.pose_snapshot(armature)
        self._frame_before = self.scene.frame_current
        self._listed_before = len(armature.trajevae.variants)
        self._recorded = variants.record_original(armature, job.switches_before)
        self.report = Report(seconds=dict(job.seconds), frames=job.frames, channels=job.channels,
                             out_of_reach=[], warnings=list(job.warnings))
        self._measured = [[] for _ in range(job.count)]  # per variant, (joint, error) on measured frames
        self._written, self._pending = 0, None  # finished variants; (channelbag, channels left) of the next
        channels_per_variant = sum(values.shape[1] for _, _, values in job.channels[0])
        self.sampled = job.count * len(job.frames) * channels_per_variant > MAX_KEYS
        if self.sampled:
            self.report.warnings.append(
                f"{job.count} variants of {len(job.frames)} frames are stored as baked samples to fit in memory; "
                "Keep turns the kept one into keys (or Graph Editor > Channel > Samples to Keys)")
        frames = len(job.frames)
        per_variant = min(frames, max(MIN_MEASURED_FRAMES, MEASURED_FRAME_BUDGET // job.count))
        self._measure_at = np.unique(np.linspace(0, frames - 1, per_variant).round().astype(int))
        self.done = False

    @property
    def progress(self):
        written, measured = self._written, sum(bool(m) for m in self._measured)
        write_start = PROGRESS_END["retarget"]
        return (write_start + (PROGRESS_END["write"] - write_start) * written / self.job.count
                + (PROGRESS_END["measure"] - PROGRESS_END["write"]) * measured / self.job.count)

    def step(self, seconds=STEP_SECONDS):
        """Write or measure variants, one at least, for about ``seconds``; the last step commits
        the list."""
        began = clock = time.perf_counter()
        while True:
            if self._written < self.job.count:
                self._write_next()
                stage = "write"
            else:
                if all(self._measured):
                    self._commit()
                else:
                    self._measure_next()
                stage = "measure"
            now = time.perf_counter()
            self.report.seconds[stage] = self.report.seconds.get(stage, 0.0) + now - clock
            if self.done or now - began >= seconds:
                return
            clock = now

    def _write_next(self):
        """Start the next variant's Action or add about CHUNK_KEYS keys to it."""
        job = self.job
        if self._pending is None:
            numbered = self._listed_before + self._written + 1
            action, channelbag = actions.new(self.armature, f"{self.armature.name} variant {numbered:02d}")
            self.report.actions.append(action)
            actions.add_switches(channelbag, job.frames, job.switches)
            self._pending = (channelbag, list(job.channels[self._written]))
        channelbag, left = self._pending
        count = max(1, CHUNK_KEYS // (4 * len(job.frames)))
        actions.add_channels(self.armature, channelbag, job.frames, left[:count], self.sampled)
        del left[:count]
        if not left:
            self._written, self._pending = self._written + 1, None

    def _measure_next(self):
        """Play the next variant on the measured frames and record each bound joint's distance to
        its curve (world units)."""
        index = next(i for i, m in enumerate(self._measured) if not m)
        variants.assign(self.armature, self.report.actions[index])
        measured = []
        for position in self._measure_at:
            self.scene.frame_set(int(self.job.frames[position]))
            _, world = rig_state.read(self.armature, self.job.bones, bpy.context.evaluated_depsgraph_get(),
                                      self.job.shown_by)
            for joint, path in self.job.curve_paths.items():
                measured.append((joint, position, float(np.linalg.norm(world[J[joint]] - path[position]))))
        self._measured[index] = measured or [(None, 0, 0.0)]

    def _commit(self):
        """Per-variant figures and warnings, the frame as it was, the list with the first shown."""
        job, report, units = self.job, self.report, self.job.metres_per_unit
        if self.scene.frame_current != self._frame_before:
            self.scene.frame_set(self._frame_before)
        worst = {}
        for index, measured in enumerate(self._measured):
            errors, shares = [], []
            for joint in job.curve_paths:
                shortfall = job.shortfall[index][joint]
                reached = [e for j, position, e in measured if j == joint and shortfall[position] <= 0.0]
                errors += reached
                shares.append(float(np.mean(shortfall > 0.0)))
                if reached:
                    worst[joint] = max(worst.get(joint, 0.0), float(np.mean(reached)))
            report.curve_error_m.append(float(np.mean(errors)) * units if errors else 0.0)
            report.out_of_reach.append(float(np.mean(shares)) if shares else 0.0)
            report.difference_m.append(job.difference[index] * units)
        for joint, error in worst.items():
            if error * units > PLAYED_TOLERANCE_M:
                bone = job.bones[joint]
                cause = _blame(self.armature, bone) or "something in the rig or its parents"
                report.warnings.append(f"{bone} misses its curve {job.curve_names[joint]!r} by {100 * error * units:.1f} "
                                       f"cm as played: {cause} moves it away from its keys")
        for joint in job.curve_paths:
            shortfall = np.max([s[joint] for s in job.shortfall], axis=0) * units
            if shortfall.max() > PLAYED_TOLERANCE_M:
                report.warnings.append(f"curve {job.curve_names[joint]!r} is beyond the reach of {job.bones[joint]} on "
                                       f"{100 * np.mean(shortfall > PLAYED_TOLERANCE_M):.0f} % of frames, by up to "
                                       f"{shortfall.max():.2f} m")
        self.armature.trajevae.last_report = "\n".join(report.warnings)
        variants.add(self.armature, report.actions, report.curve_error_m, report.difference_m)
        self.done = True

    def rollback(self):
        """Leave the file as it was before this Writer: no new Actions, the same action, slot,
        pose, switches, variant list and frame."""
        armature = self.armature
        for action in self.report.actions:
            bpy.data.actions.remove(action)
        self.report.actions.clear()
        try:
            settings = armature.trajevae
        except ReferenceError:  # the armature was deleted meanwhile
            return
        while len(settings.variants) > self._listed_before:
            settings.variants.remove(len(settings.variants) - 1)
        if self._recorded:
            variants.forget_original(armature)
        if self._animation_before is None:
            if armature.animation_data is not None:
                armature.animation_data_clear()
        else:
            armature.animation_data.action, slot = self._animation_before
            if slot is not None:
                armature.animation_data.action_slot = slot
        rig_state.apply_switches(armature, self.job.switches_before)
        rig_state.restore_pose(armature, self._pose_before)
        self.scene.frame_set(self._frame_before)


def finish(job, armature):
    """Write and measure a job's variants in one go (main thread): a Report. On any failure the
    file is left as it was and the error raised again."""
    writer = Writer(job, armature)
    try:
        while not writer.done:
            writer.step()
    except BaseException:
        writer.rollback()
        raise
    return writer.report


def generate_variants(armature, count=5, seed=0, diversity=1.0, scene=None):
    """New variant Actions on ``armature`` over the scene frame range, synchronously: a Report.
    Headless runs print progress for frame ranges longer than one model window."""
    job = prepare(armature, count, seed, diversity, scene)
    long_job = bpy.app.background and len(job.trajectories) > inference.model().frames
    infer(job, (lambda fraction: print(f"TrajeVAE {armature.name}: {100 * fraction:.0f}%", flush=True))
          if long_job else None)
    return finish(job, armature)
