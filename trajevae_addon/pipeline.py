"""Generate N variants on a rig: read the scene into a shot request, run it, write the Actions.

The motion itself is ``model_runtime.shot`` (no bpy); this module is its
Blender side, in three steps so the interface stays responsive: ``prepare``
reads and checks the scene into a ``shot.Request`` (main thread), ``infer``
runs the shot (any thread, cancellable, touches no bpy data), and a
``Writer`` writes the Actions and measures them as Blender plays them (main
thread, in short steps). Every input is checked before anything is written,
and a Writer that fails or is cancelled at any step puts the file back as it
was. ``generate_variants`` runs all of it for scripts.
"""

import json
import threading
import time
from dataclasses import dataclass, field

import bpy
import numpy as np

from . import actions, bindings, curves, inference, rig_mapping, rig_state, variants
from .runtime import shot, skeleton

J = skeleton.JOINT_INDEX

# A bound joint further from its curve than this as Blender plays it is reported with its cause.
PLAYED_TOLERANCE_M = 0.01
# Frame evaluations spent measuring the curve error as played, shared by the variants (at least
# MIN_MEASURED_FRAMES each; each variant's frames fall between the previous one's, so together they
# cover the shot). A Rigify rig takes 5-8 ms a frame: 240 evaluations took 1.9 s of a 2.3 s walk.
MEASURED_FRAME_BUDGET = 30
MIN_MEASURED_FRAMES = 3
# Where each stage ends on the progress bar: the shot (worker), keys and measuring (main thread).
PROGRESS_END = {"shot": 0.8, "write": 0.95, "measure": 1.0}
# Main-thread seconds a Writer step may take before it hands control back to the interface, and
# the keys it writes between looks at the clock (about 0.05 s of writing).
STEP_SECONDS = 0.1
CHUNK_KEYS = 200_000
# Keys of one generation above which its variants are stored as baked samples, a sixth of a key's
# memory: 50 variants of 10,000 frames would otherwise hold 2.4 GB of keys.
MAX_KEYS = 8_000_000

InputError = shot.InputError


class Cancelled(Exception):
    pass


USER_ERRORS = (InputError, rig_state.RigError, curves.CurveError, inference.WeightsError)


@dataclass
class Job:
    """One generation: the shot's request (and as the model sees it), what Blender needs besides (the mapping, switches to
    key and the values to restore, bones showing the visible pose, sentences for the artist) and,
    after ``infer``, the shot's result."""

    request: shot.Request
    given: shot.ModelInput  # the request as the model sees it, its reach checked
    networks: tuple  # (model, sampler or None) of the weights in use when it was prepared
    bones: dict
    switches: dict
    switches_before: dict
    shown_by: dict
    warnings: list = field(default_factory=list)
    seconds: dict = field(default_factory=dict)
    result: shot.Result = None
    progress: float = 0.0
    cancel_event: threading.Event = field(default_factory=threading.Event)

    @property
    def count(self):
        return self.request.count


@dataclass
class Report:
    """What one generation did: the new actions, seconds per stage (read, shot, write, measure),
    what was keyed (frames (F,), per variant ``retarget.key_channels`` output), and per variant
    the mean distance of curve-bound joints to their curves as Blender plays them (on the frames
    the rig can reach them), the share of frames it cannot, and the distance to the nearest other
    variant (m); ``warnings``: sentences for the artist."""

    actions: list = field(default_factory=list)
    seconds: dict = field(default_factory=dict)
    frames: np.ndarray = None
    channels: list = field(default_factory=list)
    curve_error_m: list = field(default_factory=list)
    out_of_reach: list = field(default_factory=list)
    difference_m: list = field(default_factory=list)
    warnings: list = field(default_factory=list)


def scene_frames(scene):
    start, end = scene.frame_start, scene.frame_end
    if end - start < 1:
        raise rig_state.RigError(f"the frame range {start}-{end} is a single frame; set a longer range")
    return np.arange(start, end + 1)


def _key_frames(action, bones, frames):
    """{scene frame: keyed bones} of the action's keys on ``bones`` inside ``frames``, start excluded."""
    out = {}
    for fcurve in actions.fcurves(action):
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
            or any(not fcurve.data_path.startswith("pose.") for fcurve in actions.fcurves(action)))


def _joints_of_keyed_bone(rig, bone):
    """A key on a bone fixes its own joint and the joints of the bones it carries directly, or
    through a clavicle (which the artist's keys do not move)."""
    joint_of = {b: j for j, b in rig.bones.items()}
    carriers = {bone} | {b for b in rig.clavicles.values() if rig.drivers[b] == bone}
    return [joint_of[bone]] + [joint_of[child] for child, driver in rig.drivers.items()
                               if driver in carriers and child in joint_of]


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


def prepare(armature, count=5, seed=0, diversity=1.0, scene=None):
    """Read and check everything a generation needs from the scene (main thread): a Job.
    Raises one of USER_ERRORS, with a sentence, for anything it cannot use."""
    clock = time.perf_counter()
    shot.check_arguments(count, seed, diversity)
    scene = scene or bpy.context.scene
    bones = rig_state.checked_mapping(armature)
    profile = rig_state.detected(armature)[0]
    shown_by = rig_mapping.shown_by(profile)
    switches = {**rig_mapping.switches(profile), **bindings.muted_path_constraints(armature, bones)}
    switches_before = rig_state.current_switches(armature, switches)
    switches = {path: value for path, value in switches.items() if path in switches_before}
    frames = scene_frames(scene)
    metres_per_unit = scene.unit_settings.scale_length
    if not metres_per_unit > 0.0 or not np.isfinite(metres_per_unit):
        raise InputError(f"the scene's unit scale {metres_per_unit!r} must be a positive number")
    paths, warnings = bindings.joint_paths(armature, bones)
    # The rig's root above the hips (Rigify's root): its keys are waypoints of the hips.
    roots = {bone for bone in bindings.bone_joints(armature, bones) if bone not in bones.values()}

    def read_scene():
        current = scene.frame_current
        action = armature.animation_data.action if armature.animation_data else None
        key_frames = _key_frames(action, set(bones.values()) | roots, frames)
        moves = _moves_in_world(armature, action)
        poses, world, toes = {}, [], []
        try:
            for frame in sorted({int(frames[0]), *key_frames} | (set(frames.tolist()) if moves else set())):
                scene.frame_set(frame)  # even the current one: the scene as played, not as last edited
                if frame == frames[0] or frame in key_frames:
                    depsgraph = bpy.context.evaluated_depsgraph_get()
                    poses[frame] = rig_state.read(armature, bones, depsgraph, shown_by)
                    rig_state.check_finite(armature, poses[frame][0], frame)
                if frame == frames[0]:
                    toes.append(rig_state.toes(armature, bones, depsgraph, shown_by))
                if moves:
                    world.append(np.array(armature.matrix_world, dtype=np.float64))
        finally:
            scene.frame_set(current)
        world = np.array(world) if moves else np.array(armature.matrix_world, dtype=np.float64)[None]
        return key_frames, poses, world, toes[0]

    key_frames, poses, world, toes = _with_artist_action(armature, read_scene)
    if not np.isfinite(world).all() or abs(np.linalg.det(world[:, :3, :3])).min() < 1e-12:
        raise rig_state.RigError(f"{armature.name!r}: its object transform is not a number or flattens it "
                                 "(zero scale) on some frame; fix it before generating")
    rig, joints = poses[int(frames[0])]
    keys = {frame: {joint: poses[frame][1][J[joint]]
                    for bone in keyed for joint in (["Hip"] if bone in roots else _joints_of_keyed_bone(rig, bone))}
            for frame, keyed in key_frames.items()}
    request = shot.Request(
        count, seed, diversity, rig, {bone: armature.pose.bones[bone].rotation_mode for bone in rig.keyed.values()},
        bones["Hip"], frames, scene.render.fps / scene.render.fps_base, world, joints, float(toes[:, 2].min()),
        metres_per_unit, keys=keys, start_toes=toes)
    for joint, (obj, use_drawing_speed) in paths.items():
        points, times = curves.path(obj, int(frames[0]))
        request.curves[joint] = (points, times if use_drawing_speed else None)
        request.curve_names[joint] = obj.name
    networks = inference.networks()  # loaded here, so missing or broken weights are said before any work
    note = inference.missing_sampler_note()
    if note:
        warnings.append(note)
    return Job(request, shot.checked_input(request), networks, bones, switches, switches_before, shown_by, warnings,
               seconds={"read": time.perf_counter() - clock})


def infer(job, on_progress=None):
    """Run the shot of a prepared job (any thread; no bpy). Raises Cancelled once
    ``job.cancel_event`` is set; ``job.progress`` (0 to 1) follows the work."""
    clock = time.perf_counter()

    def advance(fraction):
        job.progress = PROGRESS_END["shot"] * fraction
        if on_progress is not None:
            on_progress(job.progress)
        if job.cancel_event.is_set():
            raise Cancelled()

    job.result = shot.run(job.request, *job.networks, advance, job.given)
    job.seconds["shot"] = time.perf_counter() - clock


CONSTRAINT_KINDS = bpy.types.Constraint.bl_rna.properties["type"].enum_items


def _blame(armature, bone):
    """A phrase naming what moves ``bone`` away from its keys as played: active constraints on it
    or its parents, or drivers on their channels; None when nothing is found."""
    causes, chain = [], set()
    pose_bone = armature.pose.bones.get(bone)
    while pose_bone is not None:
        chain.add(pose_bone.name)
        causes += [f"constraint {c.name!r} ({CONSTRAINT_KINDS[c.type].name}) on {pose_bone.name!r}"
                   for c in pose_bone.constraints if not c.mute and c.influence > 0.0
                   and c.type not in bindings.PATH_CONSTRAINTS]
        pose_bone = pose_bone.parent
    animation = armature.animation_data
    driven = [d.data_path for d in (animation.drivers if animation else ()) if d.data_path.startswith("pose.bones[")]
    causes += [f"a driver on {path}" for path in driven if path.split('"')[1] in chain]
    return ", ".join(causes) or None


class Writer:
    """Writes a job's variants onto the armature in short main-thread steps, then plays each one
    to measure its curve error as Blender evaluates it. ``rollback`` undoes everything it did.

    Usage: ``writer = Writer(job, armature)``, then ``writer.step()`` until ``writer.done``
    (each step takes about STEP_SECONDS), then ``writer.report``."""

    def __init__(self, job, armature):
        self.job, self.armature, self.scene = job, armature, bpy.context.scene
        missing = sorted(bone for bone in job.request.rotation_modes if bone not in armature.pose.bones)
        if missing:
            raise rig_state.RigError(f"bone {', '.join(map(repr, missing))} of {armature.name!r} was renamed or "
                                     "deleted during generation; nothing was written, generate again")
        reason = rig_state.unusable_reason(armature)
        if reason:
            raise rig_state.RigError(reason)
        changed = sorted(bone for bone, mode in job.request.rotation_modes.items()
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
        self.report = Report(seconds=dict(job.seconds), frames=job.request.frames, channels=job.result.channels,
                             out_of_reach=[], warnings=list(job.warnings))
        self._measured = [[] for _ in range(job.count)]  # per variant, (joint, error) on measured frames
        self._written, self._pending = 0, None  # finished variants; (channelbag, channels left) of the next
        channels_per_variant = sum(values.shape[1] for _, _, values in job.result.channels[0])
        self.sampled = job.count * len(job.request.frames) * channels_per_variant > MAX_KEYS
        if self.sampled:
            self.report.warnings.append(
                f"{job.count} variants of {len(job.request.frames)} frames are stored as baked samples to fit in memory; "
                "Keep turns the kept one into keys (or Graph Editor > Channel > Samples to Keys)")
        self.done = False

    @property
    def progress(self):
        written, measured = self._written, sum(bool(m) for m in self._measured)
        write_start = PROGRESS_END["shot"]
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
            actions.add_switches(channelbag, job.request.frames, job.switches)
            self._pending = (channelbag, list(job.result.channels[self._written]))
        channelbag, left = self._pending
        count = max(1, CHUNK_KEYS // (4 * len(job.request.frames)))
        actions.add_channels(self.armature, channelbag, job.request.frames, left[:count], self.sampled)
        del left[:count]
        if not left:
            self._written, self._pending = self._written + 1, None

    def _measure_next(self):
        """Play the next variant on the measured frames and record each bound joint's distance to
        its curve (world units)."""
        index = next(i for i, m in enumerate(self._measured) if not m)
        variants.assign(self.armature, self.report.actions[index])
        measured = []
        for position in self._measured_frames(index):
            self.scene.frame_set(int(self.job.request.frames[position]))
            world = rig_state.world_joints(self.armature, self.job.bones, bpy.context.evaluated_depsgraph_get(),
                                           self.job.shown_by)
            for joint, path in self.job.result.targets.items():
                axes, asked = self.job.result.axes[joint], shot.variant_target(path, index)[position]
                measured.append((joint, position, float(np.linalg.norm((world[J[joint]] - asked)[axes]))))
        self._measured[index] = measured or [(None, 0, 0.0)]

    def _measured_frames(self, index):
        """Indices into the shot's frames that variant ``index`` is played on: evenly spaced, each
        variant's shifted by a share of the spacing."""
        frames, count = len(self.job.request.frames), self.job.count
        per_variant = min(frames, max(MIN_MEASURED_FRAMES, MEASURED_FRAME_BUDGET // count))
        spacing = frames / per_variant
        return np.unique(((np.arange(per_variant) + (index + 0.5) / count) * spacing).astype(int).clip(0, frames - 1))

    def _commit(self):
        """Per-variant figures and warnings, the frame as it was, the list with the first shown."""
        job, report, units = self.job, self.report, self.job.request.metres_per_unit
        if self.scene.frame_current != self._frame_before:
            self.scene.frame_set(self._frame_before)
        worst = {}
        for index, measured in enumerate(self._measured):
            errors, shares = [], []
            for joint in job.result.targets:
                shortfall = job.result.shortfall[index][joint]
                reached = [e for j, position, e in measured if j == joint and shortfall[position] <= 0.0]
                errors += reached
                shares.append(float(np.mean(shortfall > 0.0)))
                if reached:
                    worst[joint] = max(worst.get(joint, 0.0), float(np.mean(reached)))
            report.curve_error_m.append(float(np.mean(errors)) * units if errors else 0.0)
            report.out_of_reach.append(float(np.mean(shares)) if shares else 0.0)
            report.difference_m.append(job.result.difference[index] * units)
        for joint, error in worst.items():
            if error * units > PLAYED_TOLERANCE_M:
                bone = job.bones[joint]
                cause = _blame(self.armature, bone) or "something in the rig or its parents"
                report.warnings.append(f"{bone} misses its curve {shot.curve_name(job.request, joint)!r} by {100 * error * units:.1f} "
                                       f"cm as played: {cause} moves it away from its keys")
        for joint in job.result.targets:
            shortfall = np.max([s[joint] for s in job.result.shortfall], axis=0) * units
            if shortfall.max() > PLAYED_TOLERANCE_M:
                report.warnings.append(f"curve {shot.curve_name(job.request, joint)!r} is beyond the reach of {job.bones[joint]} on "
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
    seconds = (len(job.request.frames) - 1) / job.request.fps
    long_job = bpy.app.background and seconds * shot.generation.NATIVE_FPS > job.networks[0].frames
    infer(job, (lambda fraction: print(f"TrajeVAE {armature.name}: {100 * fraction:.0f}%", flush=True))
          if long_job else None)
    return finish(job, armature)
