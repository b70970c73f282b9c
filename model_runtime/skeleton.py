"""The canonical 17-joint skeleton shared by the data, the model and the add-on.

Joint names are the product's public vocabulary: the add-on's scripting API
and rig mappings use them. The layout is the Human3.6M 17-joint skeleton the
papers use, with our own definition of where each joint sits (see
``model_runtime.data.profiles``).

Coordinates everywhere are metres, Z up. Facing convention: a body's forward
direction is ``cross(LHip - RHip, Z)``; e.g. with LHip at -X and RHip at +X the
body faces +Y.
"""

import numpy as np

JOINT_NAMES = (
    "Hip", "RHip", "RKnee", "RFoot", "LHip", "LKnee", "LFoot",
    "Spine", "Thorax", "Neck", "Head",
    "LShoulder", "LElbow", "LWrist", "RShoulder", "RElbow", "RWrist",
)
PARENTS = (-1, 0, 1, 2, 0, 4, 5, 0, 7, 8, 9, 8, 11, 12, 8, 14, 15)
NUM_JOINTS = len(JOINT_NAMES)
JOINT_INDEX = {name: i for i, name in enumerate(JOINT_NAMES)}

LEFT_RIGHT_PAIRS = (
    ("LHip", "RHip"), ("LKnee", "RKnee"), ("LFoot", "RFoot"),
    ("LShoulder", "RShoulder"), ("LElbow", "RElbow"), ("LWrist", "RWrist"),
)

# The two-bone limbs, legs first (right, left), then arms: (root, middle, end) joints.
LIMBS = (("RHip", "RKnee", "RFoot"), ("LHip", "LKnee", "LFoot"),
         ("RShoulder", "RElbow", "RWrist"), ("LShoulder", "LElbow", "LWrist"))


def limb_length(pose, chain):
    """Length of a chain of joints (a limb or its first part) in a pose (17, 3): the sum of its bones."""
    return sum(float(np.linalg.norm(pose[JOINT_INDEX[b]] - pose[JOINT_INDEX[a]])) for a, b in zip(chain, chain[1:]))


def lower_ankle_height(pose):
    """The lower ankle's height in a pose (17, 3): where the pose stands."""
    return min(float(pose[JOINT_INDEX[foot], 2]) for foot in FEET)


def shortest_leg(pose):
    """The shorter leg's hip-knee-ankle length in a pose (17, 3): how far both legs reach."""
    return min(limb_length(pose, leg) for leg in LIMBS[:2])


LOWER_BODY = ("Hip", "RHip", "RKnee", "RFoot", "LHip", "LKnee", "LFoot")
UPPER_BODY = tuple(name for name in JOINT_NAMES if name not in LOWER_BODY)
FEET = ("RFoot", "LFoot")
# Joints whose bone to their parent is rigid in every rig (limbs, hips, head).
# The torso bones are not: spines and clavicles bend between the joints.
RIGID_BONE_JOINTS = ("RHip", "RKnee", "RFoot", "LHip", "LKnee", "LFoot", "Head",
                     "LElbow", "LWrist", "RElbow", "RWrist")
UP_AXIS = np.array([0.0, 0.0, 1.0])
FLOOR_CONTACT_M = 0.05  # an ankle this close to its lowest height in a motion is on the floor


# Share of the body's mass in each segment (from joint, to joint), its centre halfway along it
# (Winter, Biomechanics and Motor Control of Human Movement: head and neck, trunk, upper arm,
# forearm and hand, thigh, shank; each foot's 0.0145 at its ankle, the joints having no toe).
SEGMENT_MASSES = ((("Neck", "Head"), 0.081), (("Hip", "Neck"), 0.497)) + tuple(
    segment for side in "RL" for segment in (
        ((side + "Shoulder", side + "Elbow"), 0.028), ((side + "Elbow", side + "Wrist"), 0.022),
        ((side + "Hip", side + "Knee"), 0.100), ((side + "Knee", side + "Foot"), 0.0465),
        ((side + "Foot", side + "Foot"), 0.0145)))


def _joint_masses():
    """Each segment's share of the mass split between its two end joints: (17,)."""
    masses = np.zeros(NUM_JOINTS)
    for (start, end), share in SEGMENT_MASSES:
        np.add.at(masses, [JOINT_INDEX[start], JOINT_INDEX[end]], 0.5 * share)
    return masses


JOINT_MASSES = _joint_masses()


def centre_of_mass(positions):
    """The body's centre of mass (..., 3) of poses (..., 17, 3), from SEGMENT_MASSES."""
    return np.einsum("j,...jk->...k", JOINT_MASSES, positions)


def indices(names):
    """Indices of joint names, in the given order."""
    return [JOINT_INDEX[name] for name in names]


def mirror_permutation():
    """Index permutation that swaps every left joint with its right twin (J,)."""
    perm = list(range(NUM_JOINTS))
    for left, right in LEFT_RIGHT_PAIRS:
        perm[JOINT_INDEX[left]], perm[JOINT_INDEX[right]] = JOINT_INDEX[right], JOINT_INDEX[left]
    return np.array(perm)


def bone_lengths(positions):
    """Length of every bone (joint to parent) per frame: (..., J, 3) -> (..., J-1)."""
    positions = np.asarray(positions)
    child = np.arange(1, NUM_JOINTS)
    parent = np.array(PARENTS[1:])
    return np.linalg.norm(positions[..., child, :] - positions[..., parent, :], axis=-1)


def rigid_bone_lengths(poses):
    """Lengths (..., 11) of the ``RIGID_BONE_JOINTS`` bones of poses (..., 17, 3), numpy or torch
    (differentiable), so training losses, metrics and the torch-free add-on share one definition."""
    child = indices(RIGID_BONE_JOINTS)
    parent = [PARENTS[c] for c in child]
    if isinstance(poses, np.ndarray):  # np.take and einsum: 4x faster than fancy indexing on pools of motions
        offsets = np.take(poses, child, axis=-2) - np.take(poses, parent, axis=-2)
        return np.sqrt(np.einsum("...i,...i->...", offsets, offsets))
    offsets = poses[..., child, :] - poses[..., parent, :]
    return (offsets ** 2).sum(-1) ** 0.5


def elevation(vectors):
    """Angles (...) of vectors (..., 3) above the ground plane, radians."""
    return np.arctan2(vectors[..., 2], np.linalg.norm(vectors[..., :2], axis=-1))


def hips_roll(positions):
    """Angles (...) of the right-to-left hip line above horizontal, radians: (..., J, 3) -> (...)."""
    positions = np.asarray(positions)
    return elevation(positions[..., JOINT_INDEX["LHip"], :] - positions[..., JOINT_INDEX["RHip"], :])


def facing(positions):
    """Unit forward direction in the ground plane: (..., J, 3) -> (..., 3)."""
    positions = np.asarray(positions)
    across = positions[..., JOINT_INDEX["LHip"], :] - positions[..., JOINT_INDEX["RHip"], :]
    forward = np.cross(across, UP_AXIS)
    forward[..., 2] = 0.0
    return forward / np.maximum(np.linalg.norm(forward, axis=-1, keepdims=True), 1e-9)


def facing_turns(initial):
    """Cosine and sine (B,) of the turn about Z that makes each pose of ``initial`` (B, 17, 3) face
    +Y (``facing``), numpy or torch: the frame the model works in (``ModelConfig.facing_frame``).
    Hips on one point (no facing) take no turn: the nanometre added forward decides only there."""
    across = initial[:, JOINT_INDEX["LHip"]] - initial[:, JOINT_INDEX["RHip"]]
    forward_x, forward_y = across[:, 1], 1e-9 - across[:, 0]
    length = (forward_x * forward_x + forward_y * forward_y) ** 0.5
    return forward_y / length, forward_x / length


def turned_about_root(poses, turns):
    """Poses (B, T, J, 3), numpy or torch, each frame turned about the vertical through its root joint
    by ``turns`` (cos, sin) (B, T)."""
    root = poses[:, :, :1]
    return root + turned(poses - root, turns)


def turned(values, turns, back=False):
    """Points (B, ..., 3), numpy or torch, turned about Z by ``turns`` (cos, sin) (B,) or (B, T) (one
    turn per frame of points (B, T, ..., 3)), or by their inverse (``back``)."""
    cos, sin = turns
    shape = tuple(cos.shape) + (1,) * (values.ndim - 1 - cos.ndim)
    cos, sin = cos.reshape(shape), (-sin if back else sin).reshape(shape)
    out = np.empty_like(values) if isinstance(values, np.ndarray) else values.new_empty(values.shape)
    out[..., 0] = cos * values[..., 0] - sin * values[..., 1]
    out[..., 1] = sin * values[..., 0] + cos * values[..., 1]
    out[..., 2] = values[..., 2]
    return out
