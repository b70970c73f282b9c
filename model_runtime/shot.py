"""A shot without Blender: what the artist asked for in (a ``Request``), N variants out.

``run`` takes these steps, each a named function:

1. ``model_input``: the curves and keys as the model's known joints, at its
   native 30 fps in its own frame (metres, floor at z = 0, see
   ``generation.Placement``), and each curve's target on every scene frame;
   under a ground path of the hips, each variant's planned walk
   (``planned_walks``): its hips and steps as known joints;
2. ``generation.generate``: the model's variants over the whole shot;
3. ``cleanup.tidy``: at the scene's frame rate, the variants put on the
   floor, eased onto the keys, planted feet held still, curves and keys met;
4. ``retarget``: joint positions to the rig's keys, one variant at a time.

Coordinates are converted once each way: world (scene units, Z up) to the
model's frame on the way in, back to world on the way out, then into the
armature's space with each frame's inverse world matrix (a rig carried by a
moving parent follows its curves in world space).
"""

import functools
import math
import numbers
from dataclasses import dataclass, field

import numpy as np

from . import cleanup, footsteps, generation, retarget, selection
from .animation_quality import mean_joint_distances
from .filters import smoothstep
from .skeleton import FEET, JOINT_INDEX, LIMBS, NUM_JOINTS, indices, limb_length, lower_ankle_height

J = JOINT_INDEX

MAX_VARIANTS = 50
MAX_DIVERSITY = 2.0
# Drawn input a body cannot follow, refused before generating: a joint's mean speed along its curve
# (captured hands and feet peak near 20 m/s for a moment, a sprinter's body holds about 10 m/s), the
# jump from the joint to its curve's first point, and how far a curve dips below the rig's feet.
MAX_MEAN_SPEED_M_S = 12.0
MAX_START_GAP_M = 1.0
MAX_BELOW_FEET_M = 0.2
# Frames compared for the distance between variants.
COMPARED_FRAMES = 300
# A curve bound to the hips whose mean height over the floor is under this share of the hips'
# standing height is a ground path: it gives the hips' horizontal position only (the feet step as
# planned under it, the model chooses the hips' height and the body), and without drawing times the
# walk along it speeds up from rest and slows to rest (``footsteps.WALK_EASE_S``).
GROUND_PATH_HEIGHT = 0.5
# A foot curve drawn without times whose mean height over the floor is under this, at least
# ``footsteps.Stepping.SHORTEST_PATH_M`` long, is a path of footsteps: the foot plants and swings
# along it (``foot_stepping``).
FOOT_PATH_HEIGHT_M = 0.15
# Keys on the hips (a root bone keyed with location) without a curve of theirs are a walk's
# waypoints when they keep the hips within WAYPOINT_HEIGHT_M of their start height and carry them
# WAYPOINT_TRAVEL_M or more: the hips walk a smooth path through them (``waypoint_path``).
WAYPOINT_HEIGHT_M = 0.1
WAYPOINT_TRAVEL_M = 0.5
WAYPOINTS_NAME = "keys on the hips"
# Share of ``run``'s progress spent in the networks; the retarget takes the rest.
INFERENCE_SHARE = 0.75


class InputError(ValueError):
    """An argument or a drawn input a shot cannot use; the message says what to change."""


@dataclass
class Request:
    """One generation, read from the scene.

    rig: the rig at the start frame in armature space (``retarget.RigState``);
    rotation_modes: keyed bone -> its rotation mode; root_bone: the bone keyed with location;
    frames (F,) scene frames at ``fps``; armature_to_world (F, 4, 4), or (1, 4, 4) for a rig
    that stays put; start_joints (17, 3) and floor (the world height the feet stand on) in world
    units, ``metres_per_unit`` of them to the metre; curves: joint -> (points (P, 3) world, drawing
    times (P,) in seconds or None for uniform speed); curve_names: joint -> the curve's name;
    keys: scene frame -> {joint: (3,) world position}; start_toes (2, 3): the toes (the foot bones'
    tails, right then left) in world units at the start frame, or None.
    """

    count: int
    seed: int
    diversity: float
    rig: retarget.RigState
    rotation_modes: dict
    root_bone: str
    frames: np.ndarray
    fps: float
    armature_to_world: np.ndarray
    start_joints: np.ndarray
    floor: float
    metres_per_unit: float
    curves: dict = field(default_factory=dict)
    curve_names: dict = field(default_factory=dict)
    keys: dict = field(default_factory=dict)
    start_toes: np.ndarray = None

    @property
    def seconds(self):
        """The shot's length: from the first frame to the last."""
        return (len(self.frames) - 1) / self.fps


@dataclass
class ModelInput:
    """A request as the model sees it: ``placement`` (world <-> model frame), initial (17, 3),
    trajectories (T, 17, 3) and mask (T, 17, 3) of the known joint coordinates on the model frames
    after the initial one; targets: joint -> (F, 3) world position its curve asks for on each scene
    frame (``variant_target``), of which axes: joint -> (3,) bool says the coordinates followed (a
    ground path: x and y); keyed: scene frame index -> {joint: (3,) model-frame position}; walks:
    each variant's walk planned under a ground path (``planned_walks``: a ``footsteps.Walks``
    on 1 + T frames in the model frame), or None; with walks, trajectories are each variant's
    (V, T, 17, 3), and so are the hips' targets (V, F, 3)."""

    placement: generation.Placement
    initial: np.ndarray
    trajectories: np.ndarray
    mask: np.ndarray
    targets: dict
    axes: dict
    keyed: dict
    walks: footsteps.Walks = None


@dataclass
class Result:
    """A shot's variants: motion (count, F, 17, 3) world at the scene's frames; contacts
    (count, F, 2) planted right and left feet; targets: joint -> (F, 3) world position its curve
    asks for on each scene frame (``variant_target``), on the coordinates axes: joint -> (3,) bool;
    channels, per variant ``retarget.key_channels``;
    shortfall, per variant {joint: (F,) world distance its curve lies beyond the limb's reach};
    difference, per variant the mean joint distance to the nearest other variant (world)."""

    motion: np.ndarray
    contacts: np.ndarray
    targets: dict
    axes: dict
    channels: list
    shortfall: list
    difference: list


def variant_target(path, index):
    """Variant ``index``'s target (F, 3) of a curve's targets: (F, 3), or each variant's own
    (V, F, 3) (the hips of a walk, each in its own time)."""
    return path if path.ndim == 2 else path[index]


def check_arguments(count, seed, diversity):
    """InputError with a sentence for a variant count, seed or diversity a shot cannot take."""
    def whole(value):
        return isinstance(value, numbers.Integral) and not isinstance(value, bool)

    if not whole(count) or not 1 <= count <= MAX_VARIANTS:
        raise InputError(f"the number of variants must be a whole number from 1 to {MAX_VARIANTS}, not {count!r}")
    if not whole(seed) or not 0 <= seed < 2 ** 63:
        raise InputError(f"the seed must be a whole number of 0 or more, not {seed!r}")
    if (not isinstance(diversity, numbers.Real) or isinstance(diversity, bool) or not math.isfinite(diversity)
            or not 0.0 <= diversity <= MAX_DIVERSITY):
        raise InputError(f"diversity must be a number from 0 to {MAX_DIVERSITY:g}, not {diversity!r}")


def model_input(request):
    """The request's curves and keys as the model's input (a ModelInput)."""
    frames, fps = request.frames, request.fps
    placement = generation.Placement.for_pose(request.start_joints, request.floor, request.metres_per_unit)
    steps = generation.model_frames(len(frames), fps)
    span = (len(frames) - 1) * generation.NATIVE_FPS / fps  # model frames to the shot's last frame
    trajectories = np.zeros((steps, NUM_JOINTS, 3), np.float32)
    mask = np.zeros((steps, NUM_JOINTS, 3), np.float32)
    keyed = {}
    waypoints = walk_waypoints(request)
    keys = request.keys if waypoints is None else {  # the hips' keys become their ground path
        frame: {joint: position for joint, position in joints.items() if joint != "Hip"}
        for frame, joints in request.keys.items()}
    for frame, joints in keys.items():  # keys constrain their joints on their frames only
        index = int(frame - frames[0])
        keyed[index] = {joint: placement.to_model(position) for joint, position in joints.items()}
        model_time = index * generation.NATIVE_FPS / fps
        for step in {int(np.floor(model_time)), int(np.ceil(model_time))} - {0}:  # both sides of the key
            for joint, position in keyed[index].items():
                trajectories[step - 1, J[joint]], mask[step - 1, J[joint]] = position, 1.0
    targets, axes = {}, {}
    for joint, (points, times) in request.curves.items():
        ground = joint == "Hip" and on_the_ground(request, points)
        axes[joint] = np.array([True, True, not ground])
        trajectories[:, J[joint]] = placement.to_model(path_samples(request, joint, steps, span)[1:])
        mask[:, J[joint]] = axes[joint]
        targets[joint] = path_samples(request, joint, len(frames) - 1, len(frames) - 1)
    if waypoints is not None:
        axes["Hip"] = np.array([True, True, False])
        trajectories[:, J["Hip"]] = placement.to_model(waypoint_path(request, waypoints, steps, span)[1:])
        mask[:, J["Hip"]] = axes["Hip"]
        targets["Hip"] = waypoint_path(request, waypoints, len(frames) - 1, len(frames) - 1)
    initial = placement.to_model(request.start_joints)
    planned, walks = planned_walks(request, placement, initial, axes, keyed, waypoints, steps, span), None
    if planned is not None:  # the model completes each variant's walking body around its planned steps
        hips, walks = planned
        trajectories = np.repeat(trajectories[None], request.count, axis=0)
        trajectories[:, :, J["Hip"], :2] = placement.to_model(hips[:, 1:])[..., :2]
        trajectories[:, :, indices(FEET)], mask[:, indices(FEET)] = walks.ankles[:, 1:], 1.0
        targets["Hip"] = generation.to_scene_rate(hips[:, :, None], len(frames), fps)[:, :, 0]
    return ModelInput(placement, initial, trajectories, mask, targets, axes, keyed, walks)


def planned_walks(request, placement, initial, axes, keyed, waypoints, steps, span):
    """Each variant's walk under a ground path of the hips, in its own gait
    (``footsteps.variant_gaits``), where the artist gave the feet neither curves nor keys: (its hips
    (V, 1 + T, 3) world, ``footsteps.Walks`` in the model frame) at the model's rate, on ``steps``
    frames ``span`` of them to the shot's end; else None.
    A path drawn without times each variant walks in its own time (``Gait.ease_in``, ``ease_out``),
    its hips swaying over its feet (``footsteps.swayed``); waypoints are passed on their frames."""
    ground = "Hip" in axes and not axes["Hip"][2]
    if not ground or any(foot in axes or any(foot in joints for joints in keyed.values()) for foot in FEET):
        return None
    foot = _foot_length(request, placement)
    gaits = footsteps.variant_gaits(request.count, np.random.default_rng(request.seed), request.diversity)
    walks = []
    for gait in gaits:
        if waypoints is None:
            path = path_samples(request, "Hip", steps, span, (gait.ease_in, gait.ease_out))
        else:
            path = waypoint_path(request, waypoints, steps, span)
        path[0, :2] = request.start_joints[J["Hip"], :2]
        hips = placement.to_model(path).astype(np.float64)
        plan = footsteps.planned_feet(hips[:, :2], initial, generation.NATIVE_FPS, gait, foot)
        if plan is None:
            return None
        swayed = hips if waypoints is not None else footsteps.swayed(hips, plan[0], generation.NATIVE_FPS)
        walks.append((path + (swayed - hips) / placement.scale, *plan, hips))
    world, ankles, pitches, routes = (np.stack(part) for part in zip(*walks))
    return world, footsteps.Walks(ankles, pitches, routes, gaits)


def path_samples(request, joint, count, span, eases=(footsteps.WALK_EASE_S, footsteps.WALK_EASE_S)):
    """Where a joint's curve puts it on 1 + ``count`` frames, ``span`` of them to the shot's end
    (world units, (1 + count, 3)). Drawn without times, a ground path speeds up from rest and slows
    to rest over ``eases`` (seconds in, out), and a foot path on the floor steps
    (``foot_stepping``); otherwise the curve is followed at its drawing speed, or uniformly."""
    points, times = request.curves[joint]
    stepping = foot_stepping(request, joint) if times is None else None
    timing = stepping
    if times is None and joint == "Hip" and on_the_ground(request, points):
        seconds = max(request.seconds, 1e-9)
        timing = functools.partial(generation.eased, ease=eases[0] / seconds, ease_out=eases[1] / seconds)
    samples = generation.curve_samples(points, count, span, times, timing)
    if stepping is not None:  # the ankle at its standing height over the path, lifted in each swing
        lift = stepping.lift(generation.time_shares(count, span))
        samples[:, 2] = request.start_joints[J[joint], 2] + lift / request.metres_per_unit
    return samples


def walk_waypoints(request):
    """(times (K,) s from the start, hips (K, 3) world) of the start and the keys on the hips where
    they are a walk's waypoints (see WAYPOINT_HEIGHT_M), else None."""
    if "Hip" in request.curves:
        return None
    keyed = sorted((frame, joints["Hip"]) for frame, joints in request.keys.items() if "Hip" in joints)
    if not keyed:
        return None
    start = request.start_joints[J["Hip"]]
    times = np.array([0.0] + [(frame - request.frames[0]) / request.fps for frame, _ in keyed])
    hips = np.array([start] + [position for _, position in keyed], dtype=np.float64)
    level = np.abs(hips[:, 2] - start[2]).max() * request.metres_per_unit <= WAYPOINT_HEIGHT_M
    travel = np.linalg.norm(np.diff(hips[:, :2], axis=0), axis=-1).sum() * request.metres_per_unit
    return (times, hips) if level and travel >= WAYPOINT_TRAVEL_M else None


def waypoint_path(request, waypoints, count, span):
    """The hips' position (1 + ``count``, 3) world on frames ``span`` of them to the shot's end,
    through the waypoints ((times (K,), hips (K, 3)), ``walk_waypoints``) on a curve that passes
    each at its time (Catmull-Rom tangents), from rest at the first and to rest at the last, and
    stays at the last."""
    times, hips = waypoints
    now = generation.time_shares(count, span) * request.seconds
    tangents = np.zeros_like(hips)
    tangents[1:-1] = (hips[2:] - hips[:-2]) / np.maximum(times[2:] - times[:-2], 1e-9)[:, None]
    segment = np.clip(np.searchsorted(times, now, side="right") - 1, 0, len(times) - 2)
    begin, end = times[segment], times[segment + 1]
    length = np.maximum(end - begin, 1e-9)[:, None]
    u = np.clip((now - begin) / length[:, 0], 0.0, 1.0)[:, None]
    h00, h10, h01, h11 = 2 * u ** 3 - 3 * u ** 2 + 1, u ** 3 - 2 * u ** 2 + u, -2 * u ** 3 + 3 * u ** 2, u ** 3 - u ** 2
    return (h00 * hips[segment] + h10 * length * tangents[segment] + h01 * hips[segment + 1]
            + h11 * length * tangents[segment + 1])


def curve_name(request, joint):
    """What the artist drew or keyed for a joint's target, to name it in messages."""
    return request.curve_names.get(joint, WAYPOINTS_NAME)


def foot_stepping(request, joint):
    """The ``footsteps.Stepping`` of a foot path drawn on the floor (mean height within
    FOOT_PATH_HEIGHT_M of it) long enough to walk, else None: a foot would glide along it at
    constant speed. The left foot swings half a stride after the right."""
    if joint not in FEET:
        return None
    points = request.curves[joint][0] * request.metres_per_unit
    length = float(np.linalg.norm(np.diff(points, axis=0), axis=1).sum())
    height = float(np.mean(points[:, 2])) - request.floor * request.metres_per_unit
    if length < footsteps.Stepping.SHORTEST_PATH_M or height > FOOT_PATH_HEIGHT_M:
        return None
    return footsteps.Stepping(length, request.seconds, phase=0.5 if joint == "LFoot" else 0.0)


def on_the_ground(request, points):
    """Whether a hip curve's points (P, 3) lie on or near the floor (a ground path)."""
    standing = request.start_joints[J["Hip"], 2] - request.floor
    return float(np.mean(points[:, 2]) - request.floor) < GROUND_PATH_HEIGHT * standing


def checked_input(request):
    """The request's ModelInput, once its curves are known to be within reach (else InputError)."""
    given = model_input(request)
    check_reach(request, given)
    return given


def check_reach(request, given):
    """InputError naming each curve a body cannot follow, and by how much. Limits hold for the
    body as the model sees it (rigs outside the trained size are scaled to it) and are said in
    scene metres."""
    to_body = given.placement.scale / request.metres_per_unit  # scene metres -> the model's metres
    feet = lower_ankle_height(request.start_joints)
    seconds = request.seconds
    problems = []
    for joint, paths in given.targets.items():
        path = variant_target(paths, 0)  # a walk's variants take one path, each in its own time
        name = f"curve {curve_name(request, joint)!r} ({request.rig.bones[joint]})"
        axes = given.axes[joint]
        gap = np.linalg.norm((path[0] - request.start_joints[J[joint]])[axes]) * request.metres_per_unit
        if gap * to_body > MAX_START_GAP_M:
            problems.append(f"{name} starts {gap:.2f} m from its joint, which can jump at most "
                            f"{MAX_START_GAP_M / to_body:.2g} m onto it; draw it from the joint")
        length = np.linalg.norm(np.diff(path, axis=0), axis=-1).sum() * request.metres_per_unit
        if length / seconds * to_body > MAX_MEAN_SPEED_M_S:
            problems.append(f"{name} is {length:.1f} m long, {length / seconds:.3g} m/s over the {seconds:.1f} s "
                            f"frame range where this body manages about {MAX_MEAN_SPEED_M_S / to_body:.3g} m/s; "
                            "shorten it or lengthen the range")
        below = (feet - path[:, 2].min()) * request.metres_per_unit if axes[2] else 0.0
        if below * to_body > MAX_BELOW_FEET_M:
            problems.append(f"{name} goes {below:.2f} m below the feet, through the floor")
    if problems:
        raise InputError("out of reach: " + "; ".join(problems))


def to_armature(world_to_armature, points):
    """World points (F, ..., 3) in armature space, each frame by its matrix (world_to_armature
    (F or 1, 4, 4), the inverse of the armature's world matrix)."""
    rotation = world_to_armature[:, :3, :3].reshape(-1, *([1] * (points.ndim - 2)), 3, 3)
    offset = world_to_armature[:, :3, 3].reshape(-1, *([1] * (points.ndim - 2)), 3)
    return (rotation @ points[..., None])[..., 0] + offset


def run(request, model, sampler=None, progress=None, given=None):
    """The request's variants (a Result). ``sampler``: the diverse sampler, whose pool of draws is
    screened for plausibility and for following the curves and keys, then spread (``selection``);
    the candidates kept are carried through the shot and its cleanup and the variants picked
    among them as played (``selection.distinct_as_played``);
    ``progress(fraction)`` is called as the work goes on and may raise to stop it; ``given``: the
    request's ``checked_input`` where the caller has it already."""
    report = progress or (lambda fraction: None)
    given = given or checked_input(request)
    # candidates to pick the variants from as they play; a walk's variants each take their own planned path
    pool = request.count if given.trajectories.ndim == 4 else selection.played_pool(request.count,
                                                                                      len(request.frames))
    motion, planted = generation.generate(model, given.initial, given.trajectories, given.mask, pool,
                                          np.random.default_rng(request.seed), request.diversity, sampler,
                                          progress=lambda fraction: report(INFERENCE_SHARE * fraction))
    frames = len(request.frames)
    scene_rate = np.empty((pool, frames, NUM_JOINTS, 3))
    for index in range(pool):  # one candidate at a time: resampling makes copies
        scene_rate[index] = generation.to_scene_rate(motion[index].astype(np.float64), frames, request.fps)
    del motion
    planted = generation.to_scene_rate(planted[..., None], frames, request.fps)[..., 0]
    targets = {joint: given.placement.to_model(path).astype(np.float64) for joint, path in given.targets.items()}
    walks = pitches = None
    if given.walks is not None:
        walks = given.walks.resampled(lambda values: generation.to_scene_rate(values, frames, request.fps))
    scene_rate, contacts, turns = cleanup.tidy(scene_rate, request.fps, given.initial, targets, given.axes,
                                               given.keyed, planted, walks)
    if walks is not None:
        ankles = scene_rate[:, :, indices(FEET), 2] - lower_ankle_height(given.initial)
        pitches = footsteps.toes_down(walks.pitches, ankles, _foot_length(request, given.placement))
    report(INFERENCE_SHARE)  # a chance to stop before the retarget
    world = given.placement.to_world(scene_rate)
    if not np.isfinite(world).all():
        raise InputError("the model returned motion that is not a number for this input; nothing was written")
    followed = {joint: path for joint, path in given.targets.items() if given.axes[joint].all()}
    pinned = cleanup.pinned_joints(frames, followed, given.keyed, request.fps)  # a ground path's hips find their height
    # the rig's own pose first: the hips held as at the start, the legs bent to LEG_REACH after it
    start = 1.0 - smoothstep(np.arange(frames) / max(cleanup.START_EASE_S * request.fps, 1.0))
    pinned[:, J["Hip"]] = np.maximum(pinned[:, J["Hip"]], start)
    world_to_armature = np.linalg.inv(request.armature_to_world)
    hips_on_path = "Hip" in given.axes and not given.axes["Hip"][2]
    armature = [to_armature(world_to_armature, motion) for motion in world]  # (P, F, 17, 3)
    if pool > request.count:
        missed = _hands_missed(request.rig, armature, pinned, hips_on_path)
        chosen = selection.distinct_as_played(scene_rate, given.initial, request.count, missed, model.angle_limits)
        world, contacts, turns = world[chosen], contacts[chosen], turns[chosen]
        armature = [armature[index] for index in chosen]
    del scene_rate
    turns = turns - _yaw(request.armature_to_world)[None, :, None]  # the feet's turns in armature space
    world_scale = np.abs(np.linalg.det(request.armature_to_world[:, :3, :3])) ** (1.0 / 3.0)  # (F or 1,)
    channels, shortfall = [], []
    for index in range(request.count):
        deltas = retarget.joint_deltas(request.rig, armature[index], pinned,
                                       turns[index], hips_on_path=hips_on_path,
                                       foot_pitches=None if pitches is None else pitches[index])
        keys = retarget.key_channels(retarget.bone_bases(request.rig, deltas), request.rotation_modes,
                                     request.root_bone)
        if not all(np.isfinite(values).all() for _, _, values in keys):
            raise InputError("the retarget returned keys that are not a number for this rig; nothing was written")
        channels.append(keys)
        achieved = retarget.achieved_joints(request.rig, deltas)
        shortfall.append({joint: world_scale * retarget.reach_shortfall(
            request.rig, achieved, to_armature(world_to_armature, variant_target(path, index)), joint)
            for joint, path in given.targets.items()})
        report(INFERENCE_SHARE + (1.0 - INFERENCE_SHARE) * (index + 1) / request.count)
    return Result(world, contacts, given.targets, given.axes, channels, shortfall, _nearest_other(world))


def _hands_missed(rig, candidates, pinned, hips_on_path):
    """Per candidate (P,): how far its curves and keys miss a hand on the rig on the worst frame, in
    arm lengths (``retarget.hands_missed``; closer to the shoulder than an elbow folded to
    ``selection.SCREENED_FOLD_COS`` counts as missing); candidates (P, F, 17, 3) in armature space."""
    arms = np.array([limb_length(rig.joints, arm) for arm in LIMBS[2:]])
    held = pinned[:, [J[arm[-1]] for arm in LIMBS[2:]]]  # (F, 2): free hands keep their pose against the shoulder
    return np.array([(held * retarget.hands_missed(rig, joints, pinned, hips_on_path, selection.SCREENED_FOLD_COS)
                      / arms).max() for joints in candidates])


def _foot_length(request, placement):
    """The rig's ankle-to-toe length over the ground in the model's frame (the mean of both feet),
    or ``footsteps.FOOT_M`` without its toes."""
    if request.start_toes is None:
        return footsteps.FOOT_M
    ankles = request.start_joints[indices(FEET)]
    return float(np.linalg.norm((request.start_toes - ankles)[:, :2], axis=-1).mean() * placement.scale)


def _yaw(armature_to_world):
    """The armature's turn about Z since the first frame (F or 1,), radians."""
    angle = np.unwrap(np.arctan2(armature_to_world[:, 1, 0], armature_to_world[:, 0, 0]))
    return angle - angle[0]


def _nearest_other(motion):
    """Per variant of motion (V, F, J, 3), the mean joint distance to the nearest other variant,
    on at most COMPARED_FRAMES frames; 0 for a single variant."""
    if len(motion) < 2:
        return [0.0] * len(motion)
    frames = motion.shape[1]
    compared = motion[:, np.unique(np.linspace(0, frames - 1, min(frames, COMPARED_FRAMES)).astype(int))]
    distances = mean_joint_distances(compared)
    np.fill_diagonal(distances, np.inf)
    return [float(nearest) for nearest in distances.min(axis=1)]
