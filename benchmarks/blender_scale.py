"""Benchmark: 50 variants of a 10,000-frame shot with one hand curve on the mannequin, headless.

Runs the stages as the Generate button does (read on the main thread, the
networks and retarget in a worker thread, keys written and measured on the
main thread in short steps) and prints the peak memory of the process, the
main thread's seconds, the longest main-thread step, and the progress
reached (targets: under 2 GB, every stage cancellable, progress to 100 %).
"""

import sys
import threading
import time
from pathlib import Path

import bpy
import numpy as np

sys.path[:0] = [str(Path(__file__).resolve().parents[1]), str(Path(__file__).resolve().parents[1] / "tests")]

import blender_rigs  # noqa: E402
import trajevae_addon  # noqa: E402
from model_runtime.skeleton import JOINT_INDEX  # noqa: E402
from trajevae_addon import api, pipeline, rig_state  # noqa: E402

FRAMES, VARIANTS = 10_000, 50


def peak_memory_gb():
    """The process's peak resident memory (VmHWM), GB."""
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith("VmHWM:"):
            return int(line.split()[1]) / 1024 ** 2
    return float("nan")


def main():
    scene = blender_rigs.fresh_scene()
    scene.render.fps = 30
    scene.frame_start, scene.frame_end = 1, FRAMES
    trajevae_addon.register()
    rig = blender_rigs.mannequin_rig(scene)
    bones = api.map_rig(rig)
    start = rig_state.read(rig, bones, bpy.context.evaluated_depsgraph_get())[1][JOINT_INDEX["RWrist"]]
    t = np.linspace(0.0, 1.0, 400)[:, None]
    wave = np.column_stack([0.25 * np.sin(40 * np.pi * t[:, 0]), -0.2 * np.sin(20 * np.pi * t[:, 0]),
                            0.2 * np.sin(30 * np.pi * t[:, 0])])  # about 2 m/s of hand motion
    api.bind_curve(rig, bones["RWrist"], blender_rigs.curve(scene, "hand path", start + wave))
    print(f"before generating: {peak_memory_gb():.2f} GB peak")

    main_thread = 0.0
    clock = time.perf_counter()
    job = pipeline.prepare(rig, VARIANTS, 0)
    main_thread += time.perf_counter() - clock
    failures = []

    def work():
        try:
            pipeline.infer(job)
        except Exception as error:  # said below, as the operator would
            failures.append(error)

    worker = threading.Thread(target=work)
    clock = time.perf_counter()
    worker.start()
    reported = []
    while worker.is_alive():
        time.sleep(0.5)
        reported.append(job.progress)
    worker_seconds = time.perf_counter() - clock
    if failures:
        raise failures[0]
    writer = pipeline.Writer(job, rig)
    longest = 0.0
    while not writer.done:
        clock = time.perf_counter()
        writer.step()
        longest = max(longest, time.perf_counter() - clock)
        main_thread += time.perf_counter() - clock
        reported.append(writer.progress)
    report = writer.report
    stages = ", ".join(f"{stage} {seconds:.1f} s" for stage, seconds in report.seconds.items())
    print(f"{VARIANTS} variants x {FRAMES} frames, one hand curve: {stages}")
    print(f"  worker (networks and retarget) {worker_seconds:.1f} s; main thread {main_thread:.1f} s in all, "
          f"longest step {1000 * longest:.0f} ms; progress reported {len(reported)} times, up to "
          f"{100 * max(reported):.0f} %")
    print(f"  peak memory {peak_memory_gb():.2f} GB; curve error as played {100 * np.mean(report.curve_error_m):.2f} cm")


if __name__ == "__main__":
    main()
