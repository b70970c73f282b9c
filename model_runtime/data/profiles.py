"""Rig profiles: declared tables from the canonical joints to a convention's bone names.

A profile names, for 14 of the 17 canonical joints, the bone whose head sits on
that joint (a tuple lists accepted alternatives in order of preference). The
other three are virtual, computed the same way for every convention:

- Hip: midpoint of LHip and RHip (the pelvis centre; rigs disagree on where
  their root bone sits).
- Spine: midpoint of Hip and Thorax.
- Head: the head top, ``HEAD_LENGTH_PER_LEG`` x leg length from Neck along the
  head bone's own rest direction, carried by the head bone's rotation. Several
  conventions have no usable head end site (zero-length or absent), so none
  is read.

Thorax is the base of the neck (the head of the first neck bone); Neck is the
skull base (the head of the head bone).

A profile is chosen from a file's bone names: every mapped bone and every
signature bone must exist. The same tables map artists' rigs in Blender.
A library with its own naming adds a mapping file (``read_mapping``): JSON
from each of the 14 mapped joints to its bone name (or a list of accepted
names), tried before the built-in tables.
"""

import json
from dataclasses import dataclass
from pathlib import Path

from ..skeleton import JOINT_NAMES

HEAD_LENGTH_PER_LEG = 0.14
VIRTUAL_JOINTS = ("Hip", "Spine", "Head")
MAPPED_JOINTS = tuple(name for name in JOINT_NAMES if name not in VIRTUAL_JOINTS)


class MappingError(ValueError):
    """No profile maps every canonical joint of a skeleton."""

    def __init__(self, source, profile, missing):
        self.missing = missing
        detail = ", ".join(f"{joint} ({'/'.join(bones)})" for joint, bones in missing)
        super().__init__(f"{source}: cannot map joints {detail} (closest profile: {profile})")


@dataclass(frozen=True)
class RigProfile:
    name: str
    bones: dict  # canonical joint -> tuple of accepted bone names
    signature: tuple = ()  # bones that tell this convention from similar ones

    def missing(self, bone_names):
        """Canonical joints (with the bones wanted) that a skeleton lacks."""
        present = set(bone_names)
        gaps = [(joint, bones) for joint, bones in self.bones.items()
                if not any(bone in present for bone in bones)]
        gaps += [("(signature)", (bone,)) for bone in self.signature if bone not in present]
        return gaps

    def resolve(self, bone_names):
        """Canonical joint -> the bone used, for a skeleton that has them all."""
        present = set(bone_names)
        return {joint: next(bone for bone in bones if bone in present)
                for joint, bones in self.bones.items()}


def _table(rhip, rknee, rfoot, lhip, lknee, lfoot, thorax, neck,
           lshoulder, lelbow, lwrist, rshoulder, relbow, rwrist):
    names = dict(RHip=rhip, RKnee=rknee, RFoot=rfoot, LHip=lhip, LKnee=lknee, LFoot=lfoot,
                 Thorax=thorax, Neck=neck, LShoulder=lshoulder, LElbow=lelbow, LWrist=lwrist,
                 RShoulder=rshoulder, RElbow=relbow, RWrist=rwrist)
    return {joint: (bone if isinstance(bone, tuple) else (bone,)) for joint, bone in names.items()}


_MOTIONBUILDER = _table("RightUpLeg", "RightLeg", "RightFoot", "LeftUpLeg", "LeftLeg", "LeftFoot",
                        "Neck", "Head", "LeftArm", "LeftForeArm", "LeftHand",
                        "RightArm", "RightForeArm", "RightHand")

PROFILES = (
    RigProfile("cmu-motionbuilder", _MOTIONBUILDER, signature=("LHipJoint", "LowerBack")),
    RigProfile("accad-22", _MOTIONBUILDER, signature=("ToSpine",)),
    RigProfile("accad-24", _MOTIONBUILDER, signature=("Spine4",)),
    RigProfile("cmu-3dsmax", _table("RightHip", "RightKnee", "RightAnkle", "LeftHip", "LeftKnee",
                                    "LeftAnkle", "lowerneck", "Head", "LeftShoulder", "LeftElbow",
                                    "LeftWrist", "RightShoulder", "RightElbow", "RightWrist"),
               signature=("LeftCollar",)),
    RigProfile("daz", _table("rThigh", "rShin", "rFoot", "lThigh", "lShin", "lFoot", "neck", "head",
                             "lShldr", "lForeArm", "lHand", "rShldr", "rForeArm", "rHand")),
    RigProfile("asf-style", _table("rfemur", "rtibia", "rfoot", "lfemur", "ltibia", "lfoot",
                                   ("lowerneck", "neck"), "head", "lhumerus", "lradius",
                                   ("lwrist", "lhand"), "rhumerus", "rradius", ("rwrist", "rhand"))),
    RigProfile("motionbuilder", _MOTIONBUILDER),  # any other file with these common names
)


def read_mapping(path):
    """The profile of a mapping file: {"RHip": "thigh_R", ..., "LWrist": ["hand_L", "wrist_L"]} for
    every joint of ``MAPPED_JOINTS``; ValueError says what is wrong with it."""
    path = Path(path)
    try:
        table = json.loads(path.read_text())
    except (OSError, ValueError) as error:
        raise ValueError(f"the mapping file {path} cannot be read as JSON ({error})") from None
    if not isinstance(table, dict):
        raise ValueError(f"the mapping file {path} must be one JSON object from joint names to bone names")
    unknown = sorted(set(table) - set(MAPPED_JOINTS))
    missing = [joint for joint in MAPPED_JOINTS if joint not in table]
    if unknown or missing:
        raise ValueError(f"the mapping file {path} " + "; ".join(
            part for part in (f"names unknown joints {', '.join(unknown)}" if unknown else "",
                              f"lacks {', '.join(missing)}" if missing else "") if part)
            + f" (it maps exactly these joints: {', '.join(MAPPED_JOINTS)})")
    bones = {}
    for joint in MAPPED_JOINTS:
        names = table[joint] if isinstance(table[joint], list) else [table[joint]]
        if not names or not all(isinstance(name, str) and name for name in names):
            raise ValueError(f"the mapping file {path} gives {joint} no bone name")
        bones[joint] = tuple(names)
    return RigProfile(f"mapping {path.name}", bones)


def detect(bone_names, source="skeleton", custom=()):
    """The profile that maps every canonical joint of these bones, else MappingError. ``custom``
    profiles (from mapping files) are tried first."""
    ranked = sorted(tuple(custom) + PROFILES, key=lambda profile: len(profile.missing(bone_names)))
    best = ranked[0]
    gaps = best.missing(bone_names)
    if gaps:
        raise MappingError(source, best.name, gaps)
    return best
