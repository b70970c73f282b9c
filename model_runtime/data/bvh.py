"""BVH reading and forward kinematics, vectorised over frames.

The parser keeps the file's own units and axes; ``clips`` converts them.
"""

from dataclasses import dataclass, field

import numpy as np

from .. import rotations


class BVHError(ValueError):
    """A file that is not a readable BVH motion."""


@dataclass
class Hierarchy:
    """Joints in file order (parents come before children)."""

    names: list = field(default_factory=list)
    parents: list = field(default_factory=list)
    offsets: list = field(default_factory=list)
    channels: list = field(default_factory=list)
    end_offsets: dict = field(default_factory=dict)  # joint index -> offset of its End Site

    def index(self, name):
        return self.names.index(name)

    def channel_columns(self):
        """First motion column of every joint (J,)."""
        starts, column = [], 0
        for joint_channels in self.channels:
            starts.append(column)
            column += len(joint_channels)
        return starts, column


@dataclass
class Motion:
    """A parsed BVH file: hierarchy, raw channel values (F, C) and frame time in seconds."""

    hierarchy: Hierarchy
    values: np.ndarray
    frame_time: float


def parse(text, source="<string>"):
    """Parse BVH text into a Motion."""
    head, sep, motion_text = text.partition("MOTION")
    if not sep:
        raise BVHError(f"{source}: no MOTION section")
    hierarchy = _parse_hierarchy(head.split(), source)
    lines = motion_text.strip().split("\n", 2)
    if len(lines) < 2 or not lines[0].strip().startswith("Frames") or "Time" not in lines[1]:
        raise BVHError(f"{source}: missing 'Frames:' or 'Frame Time:' line")
    try:
        frame_count = int(lines[0].split(":")[1])
        frame_time = float(lines[1].split(":")[1])
        numbers = np.array(lines[2].split() if len(lines) > 2 else [], dtype=np.float64)
    except ValueError as error:
        raise BVHError(f"{source}: unreadable motion data ({error})") from None
    _, channel_count = hierarchy.channel_columns()
    whole_frames = min(frame_count, numbers.size // channel_count)
    if whole_frames < 1 or frame_time <= 0:
        raise BVHError(f"{source}: no frames of motion")
    values = numbers[: whole_frames * channel_count].reshape(whole_frames, channel_count)
    return Motion(hierarchy, values, frame_time)


def read(path):
    with open(path, "r", encoding="utf-8", errors="replace") as handle:
        return parse(handle.read(), str(path))


def _parse_hierarchy(tokens, source):
    hierarchy = Hierarchy()
    stack = []  # joint index per open brace; None for an End Site
    pending = None  # ("joint", name) or ("end",) waiting for its "{"
    position = 0
    try:
        while position < len(tokens):
            token = tokens[position]
            if token in ("ROOT", "JOINT"):
                pending = ("joint", tokens[position + 1])
                position += 2
            elif token == "End":
                pending = ("end",)
                position += 2
            elif token == "{":
                if pending is None:
                    raise BVHError(f"{source}: unexpected '{{'")
                if pending[0] == "joint":
                    parent = next((j for j in reversed(stack) if j is not None), -1)
                    hierarchy.names.append(pending[1])
                    hierarchy.parents.append(parent)
                    hierarchy.offsets.append(np.zeros(3))
                    hierarchy.channels.append([])
                    stack.append(len(hierarchy.names) - 1)
                else:
                    stack.append(None)
                pending = None
                position += 1
            elif token == "}":
                stack.pop()
                position += 1
            elif token == "OFFSET":
                offset = np.array([float(v) for v in tokens[position + 1: position + 4]])
                if stack[-1] is None:
                    owner = next(j for j in reversed(stack) if j is not None)
                    hierarchy.end_offsets[owner] = offset
                else:
                    hierarchy.offsets[stack[-1]] = offset
                position += 4
            elif token == "CHANNELS":
                count = int(tokens[position + 1])
                hierarchy.channels[stack[-1]] = tokens[position + 2: position + 2 + count]
                position += 2 + count
            else:
                position += 1
    except (IndexError, ValueError, StopIteration) as error:
        raise BVHError(f"{source}: malformed HIERARCHY ({error})") from None
    if not hierarchy.names:
        raise BVHError(f"{source}: no joints in HIERARCHY")
    return hierarchy


def local_transforms(motion, joints):
    """Local rotations (F, len(joints), 4) and translations (F, len(joints), 3) of chosen joints.

    A joint with position channels takes them as its translation (the usual
    reading for the root); the others take their rest OFFSET.
    """
    hierarchy = motion.hierarchy
    starts, _ = hierarchy.channel_columns()
    frames = motion.values.shape[0]
    quats = np.zeros((frames, len(joints), 4))
    quats[..., 0] = 1.0
    translations = np.zeros((frames, len(joints), 3))
    for slot, joint in enumerate(joints):
        names = hierarchy.channels[joint]
        columns = starts[joint] + np.arange(len(names))
        translations[:, slot] = hierarchy.offsets[joint]
        positions = [(c, n[0].upper()) for c, n in zip(columns, names) if n.lower().endswith("position")]
        for column, axis in positions:
            translations[:, slot, "XYZ".index(axis)] = motion.values[:, column]
        angles = [(c, n[0].upper()) for c, n in zip(columns, names) if n.lower().endswith("rotation")]
        if angles:
            order = "".join(axis for _, axis in angles)
            quats[:, slot] = rotations.euler(motion.values[:, [c for c, _ in angles]], order)
    return quats, translations


def forward_kinematics(parents, quats, translations):
    """World rotations (F, J, 3, 3) and positions (F, J, 3) of a joint chain.

    ``parents`` index into the same joint list (-1 for a root) and come before
    their children. One pass over joints; every frame at once.
    """
    local = rotations.to_matrix(quats)
    world_rot = np.empty_like(local)
    world_pos = np.empty_like(translations)
    for joint, parent in enumerate(parents):
        if parent < 0:
            world_rot[:, joint] = local[:, joint]
            world_pos[:, joint] = translations[:, joint]
        else:
            world_rot[:, joint] = world_rot[:, parent] @ local[:, joint]
            world_pos[:, joint] = world_pos[:, parent] + np.einsum(
                "fij,fj->fi", world_rot[:, parent], translations[:, joint])
    return world_rot, world_pos


def ancestors_closure(hierarchy, joints):
    """The given joints and all their ancestors, in file order."""
    needed = set()
    for joint in joints:
        while joint >= 0 and joint not in needed:
            needed.add(joint)
            joint = hierarchy.parents[joint]
    return sorted(needed)
