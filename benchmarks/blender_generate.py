"""Benchmark: 10 variants of 120 frames on a generated Rigify rig, headless.

Prints the split (read rig and curves, inference, retarget, write keys,
measure the curve error as Blender plays the variants), the
end-to-end time, and the time to write the same keys alone (targets: under
1 s end to end on 2 cores, under 3x the key-writing time).
"""

import sys
import time
from pathlib import Path

import bpy
import numpy as np

sys.path[:0] = [str(Path(__file__).resolve().parents[1]), str(Path(__file__).resolve().parents[1] / "tests")]

import blender_rigs  # noqa: E402
import trajevae_addon  # noqa: E402
from trajevae_addon import actions, api, pipeline, rig_mapping, rig_state  # noqa: E402


def main():
    scene = blender_rigs.fresh_scene()
    scene.frame_start, scene.frame_end = 1, 120
    trajevae_addon.register()
    rig = blender_rigs.rigify_rig(scene)
    bones = api.map_rig(rig)
    _, joints = rig_state.read(rig, bones, bpy.context.evaluated_depsgraph_get())
    from model_runtime.skeleton import JOINT_INDEX
    for joint, offset in (("LWrist", (0.1, -0.4, 0.3)), ("RWrist", (-0.1, -0.3, 0.1))):
        start = joints[JOINT_INDEX[joint]]
        api.bind_curve(rig, bones[joint], blender_rigs.curve(scene, joint, start + np.linspace(0, 1, 8)[:, None]
                                                              * offset))
    pipeline.generate_variants(rig, 2)  # load the weights once, as a session would
    api.restore_original(rig)

    rows = []
    for _ in range(3):
        bpy.context.evaluated_depsgraph_get()  # a settled scene, as after the viewport has drawn
        clock = time.perf_counter()
        report = pipeline.generate_variants(rig, 10, seed=len(rows))
        total = time.perf_counter() - clock
        switches = rig_mapping.switches(rig_state.detected(rig)[0])
        clock = time.perf_counter()  # the same keys again, into new actions
        written = [actions.write(rig, "keys only", report.frames, channels, switches)
                   for channels in report.channels]
        keys_only = time.perf_counter() - clock
        for action in written:
            bpy.data.actions.remove(action)
        api.restore_original(rig)
        rows.append((total, keys_only, report.seconds))
    total, keys_only, seconds = min(rows, key=lambda row: row[0])
    split = ", ".join(f"{stage} {value * 1000:.0f} ms" for stage, value in seconds.items())
    print(f"10 variants x 120 frames on a generated Rigify rig ({sum(map(bool, bones.values()))} joints mapped), best of 3:")
    print(f"  {split}")
    print(f"  end to end {total * 1000:.0f} ms; writing the same keys alone {keys_only * 1000:.0f} ms "
          f"({total / keys_only:.1f}x)")


if __name__ == "__main__":
    main()
