"""BVH parsing, forward kinematics and resampling on tiny files built here (no data needed)."""

import numpy as np
import pytest

from model_runtime.data import bvh, clips

TINY = """HIERARCHY
ROOT Root
{
  OFFSET 0 0 0
  CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation
  JOINT Upper
  {
    OFFSET 0 2 0
    CHANNELS 3 Zrotation Xrotation Yrotation
    End Site
    {
      OFFSET 0 1 0
    }
  }
}
MOTION
Frames: 3
Frame Time: 0.5
1 0 0 0 0 0 0 0 0
1 0 0 90 0 0 0 0 0
1 0 0 90 0 0 0 90 0
"""


def test_parse_reads_hierarchy_and_motion():
    motion = bvh.parse(TINY)
    assert motion.hierarchy.names == ["Root", "Upper"]
    assert motion.hierarchy.parents == [-1, 0]
    np.testing.assert_allclose(motion.hierarchy.end_offsets[1], [0, 1, 0])
    assert motion.values.shape == (3, 9)
    assert motion.frame_time == 0.5


def test_forward_kinematics_composes_rotations_in_channel_order():
    motion = bvh.parse(TINY)
    quats, translations = bvh.local_transforms(motion, [0, 1])
    world_rot, world_pos = bvh.forward_kinematics([-1, 0], quats, translations)
    # Frame 0: rest. Frame 1: root turned 90 degrees about Z, so +Y becomes -X.
    np.testing.assert_allclose(world_pos[:, 1], [[1, 2, 0], [-1, 0, 0], [-1, 0, 0]], atol=1e-9)
    # Frame 2: Upper also turned 90 about its own X; its end site (local +Y) goes to +Z.
    tip = world_pos[2, 1] + world_rot[2, 1] @ np.array([0.0, 1.0, 0.0])
    np.testing.assert_allclose(tip, [-1, 0, 1], atol=1e-9)


def test_euler_order_matters():
    # Z then X differs from X then Z: the parser must honour the file's order.
    zx = bvh.parse(TINY.replace("0 0 90 0 0 0 90 0", "0 0 90 90 0 0 0 0"))
    xz = bvh.parse(TINY.replace("Zrotation Xrotation Yrotation\n  JOINT", "Xrotation Zrotation Yrotation\n  JOINT")
                   .replace("0 0 90 0 0 0 90 0", "0 0 90 90 0 0 0 0"))
    a = bvh.forward_kinematics([-1, 0], *bvh.local_transforms(zx, [0, 1]))[1][2, 1]
    b = bvh.forward_kinematics([-1, 0], *bvh.local_transforms(xz, [0, 1]))[1][2, 1]
    assert np.linalg.norm(a - b) > 0.5


def test_malformed_files_raise_bvh_error():
    with pytest.raises(bvh.BVHError, match="no MOTION"):
        bvh.parse("HIERARCHY\nROOT A\n{\nOFFSET 0 0 0\n}\n")
    with pytest.raises(bvh.BVHError, match="no frames"):
        bvh.parse(TINY.split("MOTION")[0] + "MOTION\nFrames: 0\nFrame Time: 0.1\n")


def test_resample_keeps_duration_and_interpolates_rotations():
    motion = bvh.parse(TINY)
    quats, translations = bvh.local_transforms(motion, [0, 1])
    out_q, out_t = clips.resample(quats, translations, source_fps=2.0, target_fps=4.0)
    assert out_q.shape[0] == 5  # 1 s at 4 fps, both ends included
    _, positions = bvh.forward_kinematics([-1, 0], out_q, out_t)
    # Halfway through the root's quarter turn: 45 degrees.
    np.testing.assert_allclose(positions[1, 1], [1 - np.sqrt(2), np.sqrt(2), 0], atol=1e-9)
    lengths = np.linalg.norm(positions[:, 1] - positions[:, 0], axis=-1)
    np.testing.assert_allclose(lengths, 2.0)
