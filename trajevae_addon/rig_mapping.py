"""Which bone of an artist's rig carries each canonical joint.

A mapping names, per canonical joint, the bone that is keyed for it:

- the 14 joints of ``profiles.MAPPED_JOINTS``: the bone whose head sits on the
  joint (thigh for RHip, shin for RKnee, neck bone for Thorax, head bone for
  Neck...), exactly as the motion-capture profiles define them;
- Hip: the root of the body (translation and pelvis rotation);
- Spine: the bone that turns the chest (the lowest spine bone above Hip);
- Head: optional (the head top is computed from the head bone).

Rig profiles are declared name tables, chosen from a rig's bone names; the
motion-capture profiles map armatures made by Blender's BVH importer. Hip and
Spine, when a profile does not name them, are found from the hierarchy. A
profile may also name switches (custom properties) that make keyed FK
controls drive the visible skeleton, as on a generated Rigify rig.
"""

from dataclasses import dataclass, field

from .runtime import profiles, retarget, skeleton

JOINT_NAMES = skeleton.JOINT_NAMES
REQUIRED = retarget.REQUIRED_JOINTS


@dataclass(frozen=True)
class BlenderRigProfile:
    name: str
    bones: dict  # joint -> bone name
    signature: tuple
    switches: dict = field(default_factory=dict)  # data path -> value while generated motion plays
    shown_by: dict = field(default_factory=dict)  # keyed bone -> bone showing the pose the artist sees
    clavicles: dict = field(default_factory=dict)  # "RClavicle" / "LClavicle" -> bone (else from the hierarchy)


def _sided(table):
    """Expand a table with "{s}"/"{S}" placeholders into both sides (s: L/R, S: Left/Right)."""
    out = {}
    for joint, bone in table.items():
        if "{" not in joint:
            out[joint] = bone
            continue
        for side, word in (("L", "Left"), ("R", "Right")):
            out[joint.format(s=side)] = bone.format(s=side, S=word)
    return out


# Generated Rigify rig: FK controls. Its chest controls blend into the spine at
# fixed weights, so nothing there turns the upper body rigidly: the torso
# control carries the whole trunk (Spine stays unmapped). FK shows
# (IK_FK = 1), FK limbs and the head follow the body rigidly
# (FK_limb_follow = 0, neck_follow = head_follow = 1).
_RIGIFY = BlenderRigProfile(
    "rigify",
    _sided({"Hip": "torso", "Thorax": "neck", "Neck": "head",
            "{s}Hip": "thigh_fk.{s}", "{s}Knee": "shin_fk.{s}", "{s}Foot": "foot_fk.{s}",
            "{s}Shoulder": "upper_arm_fk.{s}", "{s}Elbow": "forearm_fk.{s}", "{s}Wrist": "hand_fk.{s}"}),
    signature=("torso", "ORG-spine", "thigh_parent.L"),
    switches={**{f'pose.bones["{limb}_parent.{side}"]["{prop}"]': value for limb in ("thigh", "upper_arm")
                 for side in "LR" for prop, value in (("IK_FK", 1.0), ("FK_limb_follow", 0.0))},
              'pose.bones["torso"]["neck_follow"]': 1.0, 'pose.bones["torso"]["head_follow"]': 1.0},
    # an artist posing in IK sees the ORG chain: generation starts from it, as an FK snap would
    shown_by={f"{part}_fk.{side}": f"ORG-{part}.{side}" for side in "LR"
              for part in ("thigh", "shin", "foot", "upper_arm", "forearm", "hand")},
    clavicles=_sided({"{s}Clavicle": "shoulder.{s}"}))
_METARIG = BlenderRigProfile(
    "rigify-metarig",
    _sided({"Hip": "spine", "Spine": "spine.001", "Thorax": "spine.004", "Neck": "spine.006",
            "{s}Hip": "thigh.{s}", "{s}Knee": "shin.{s}", "{s}Foot": "foot.{s}",
            "{s}Shoulder": "upper_arm.{s}", "{s}Elbow": "forearm.{s}", "{s}Wrist": "hand.{s}"}),
    signature=("spine.006", "pelvis.L"))
_MIXAMO = BlenderRigProfile(
    "mixamo",
    _sided({"Hip": "mixamorig:Hips", "Spine": "mixamorig:Spine", "Thorax": "mixamorig:Neck",
            "Neck": "mixamorig:Head", "{s}Hip": "mixamorig:{S}UpLeg", "{s}Knee": "mixamorig:{S}Leg",
            "{s}Foot": "mixamorig:{S}Foot", "{s}Shoulder": "mixamorig:{S}Arm",
            "{s}Elbow": "mixamorig:{S}ForeArm", "{s}Wrist": "mixamorig:{S}Hand"}),
    signature=("mixamorig:Hips",))
_MANNEQUIN = BlenderRigProfile(
    "mannequin", {joint: joint for joint in JOINT_NAMES if joint != "Head"}, signature=("Hip", "Thorax", "LWrist"))

PROFILES = (_RIGIFY, _METARIG, _MIXAMO, _MANNEQUIN)


def _mixamo_prefix(names):
    """Mixamo rigs come as "mixamorig:", "mixamorig1:", ...: the prefix used, or None."""
    for name in names:
        if name.endswith(":Hips"):
            return name[: -len("Hips")]
    return None


def _lowest_common_ancestor(parents, bones):
    chains = []
    for bone in bones:
        chain = []
        while bone is not None:
            chain.append(bone)
            bone = parents.get(bone)
        chains.append(chain)
    shared = set(chains[0]).intersection(*chains[1:])
    return next((bone for bone in chains[0] if bone in shared), None)


def _torso_from_hierarchy(parents, mapping):
    """Hip = common ancestor of the thighs and the neck bone; Spine = its child toward the neck."""
    needed = [mapping.get(joint) for joint in ("RHip", "LHip", "Thorax")]
    if None in needed:
        return {}
    hip = _lowest_common_ancestor(parents, needed)
    if hip is None:
        return {}
    spine, bone = None, mapping["Thorax"]
    while bone is not None and bone != hip:
        spine, bone = bone, parents.get(bone)
    return {"Hip": hip, "Spine": spine if spine != mapping["Thorax"] else None}


def detect(parents):
    """(profile name, {joint: bone or None}) for a rig given as {bone: parent or None}.

    The first profile whose signature and bones all exist wins; otherwise the
    one that maps the most joints, with the gaps left None.
    """
    names = set(parents)
    prefix = _mixamo_prefix(names)
    candidates = []
    for profile in PROFILES:
        bones = profile.bones
        signature = profile.signature
        if profile is _MIXAMO and prefix:
            bones = {j: b.replace("mixamorig:", prefix) for j, b in bones.items()}
            signature = tuple(b.replace("mixamorig:", prefix) for b in signature)
        mapping = {joint: (bone if bone in names else None) for joint, bone in bones.items()}
        candidates.append((profile.name, mapping, all(s in names for s in signature)))
    for profile in profiles.PROFILES:
        mapping = {joint: next((b for b in bones if b in names), None) for joint, bones in profile.bones.items()}
        mapping.update(_torso_from_hierarchy(parents, mapping))
        candidates.append((profile.name, mapping, all(s in names for s in profile.signature)))
    complete = [c for c in candidates if c[2] and all(c[1].get(j) for j in REQUIRED)]
    name, mapping, _ = complete[0] if complete else max(
        candidates, key=lambda c: sum(bool(c[1].get(j)) for j in JOINT_NAMES))
    return name, {joint: mapping.get(joint) for joint in JOINT_NAMES}


def _profile(name):
    return next((p for p in PROFILES if p.name == name), None)


def switches(profile_name):
    """Data path -> value the profile needs while generated motion plays."""
    profile = _profile(profile_name)
    return profile.switches if profile else {}


def shown_by(profile_name):
    """Keyed bone -> the bone that shows the pose the artist sees (when they differ)."""
    profile = _profile(profile_name)
    return profile.shown_by if profile else {}


def clavicles(profile_name, parents, mapping):
    """{"RClavicle" / "LClavicle": bone} of a rig given as {bone: parent or None} and its mapping:
    as its profile names them, or else each upper arm's parent where no joint is mapped to it and
    the other upper arm does not hang from it (it is not the chest)."""
    profile = _profile(profile_name)
    if profile is not None and profile.clavicles:
        return {key: bone for key, bone in profile.clavicles.items() if bone in parents}
    mapped = {bone for bone in mapping.values() if bone}
    out = {}
    for side, other in (("R", "L"), ("L", "R")):
        upper, other_upper = mapping.get(f"{side}Shoulder"), mapping.get(f"{other}Shoulder")
        parent = parents.get(upper) if upper else None
        if parent is None or parent in mapped:
            continue
        ancestors, bone = set(), other_upper
        while bone is not None:
            ancestors.add(bone)
            bone = parents.get(bone)
        if parent not in ancestors:
            out[f"{side}Clavicle"] = parent
    return out


def missing(mapping):
    """Required joints without a bone."""
    return [joint for joint in REQUIRED if not mapping.get(joint)]
