"""Benchmark: 10 variants of 120 frames on a generated Rigify rig, and 5 of a 300-frame walk
along a path on the floor, headless.

Prints the split (read rig and curves, inference, retarget, write keys,
measure the curve error as Blender plays the variants), the
end-to-end time, and the time to write the same keys alone (targets: under
1 s end to end on 2 cores for each, under 3x the key-writing time for the first).
"""

import sys
import time
from pathlib import Path

import bpy
import numpy as np

sys.path[:0] = [str(Path(__file__).resolve().parents[1]), str(Path(__file__).resolve().parents[1] / "tests")]

import blender_rigs  # noqa: E402
import shots  # noqa: E402
import trajevae_addon  # noqa: E402
from trajevae_addon import actions, api, pipeline, rig_mapping, rig_state  # noqa: E402


def best_of_three(rig, count):
    """(end to end seconds, the same keys written alone, seconds per stage) of the fastest of three
    generations of ``count`` variants."""
    rows = []
    for _ in range(3):
        bpy.context.evaluated_depsgraph_get()  # a settled scene, as after the viewport has drawn
        clock = time.perf_counter()
        report = pipeline.generate_variants(rig, count, seed=len(rows))
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
    return min(rows, key=lambda row: row[0])


def show(title, measured):
    total, keys_only, seconds = measured
    print(title)
    print("  " + ", ".join(f"{stage} {value * 1000:.0f} ms" for stage, value in seconds.items()))
    print(f"  end to end {total * 1000:.0f} ms; writing the same keys alone {keys_only * 1000:.0f} ms "
          f"({total / keys_only:.1f}x)")


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
    show(f"10 variants x 120 frames with two hand curves on a generated Rigify rig "
         f"({sum(map(bool, bones.values()))} joints mapped), best of 3:", best_of_three(rig, 10))

    for bone in [binding.bone for binding in rig.trajevae.bindings]:  # names first: unbinding removes items
        api.unbind(rig, bone)
    scene.frame_end = 300
    curves, _ = shots.long_walk(rig)
    api.walk_along(rig, blender_rigs.curve(scene, "floor path", curves["Hip"]))
    show("5 variants x 300 frames walking a 10 m path on the floor (issue 17), best of 3:", best_of_three(rig, 5))


if __name__ == "__main__":
    main()
