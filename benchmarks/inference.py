"""Benchmark: TrajeVAE inference of 10 samples of one window on the CPU (target < 100 ms on 2 cores).

Run: ``make bench-model``. Prints the median of repeated runs for k = 0 and k = 4 trajectories.
"""

import statistics
import sys
import time

import numpy as np
import torch

from model_runtime import masks, weights
from model_runtime.data import dataset


def main(samples=10, repeats=30):
    torch.set_num_threads(2)
    model, meta = weights.load_model()
    clips, _ = dataset.load_clips([dataset.DEFAULT_DATA_ROOT / "cmu_mb_01-09" / "02" / "02_01.bvh"])
    window = dataset.windows(clips, future=model.config.frames, stride=1000)[:1]
    initial = torch.from_numpy(window[:, 0])
    print(f"TrajeVAE {meta['parameters']:,} parameters, torch threads {torch.get_num_threads()}")
    for k in (0, 4):
        mask = torch.from_numpy(masks.evaluation_mask(k, model.config.frames)[None])
        trajectories = torch.from_numpy(window[:, 1:]) * mask[..., None]
        model.sample(initial, trajectories, mask, samples)  # warm-up
        times = []
        for _ in range(repeats):
            start = time.perf_counter()
            model.sample(initial, trajectories, mask, samples)
            times.append(time.perf_counter() - start)
        print(f"k={k}: {samples} samples of {model.config.frames} frames: median {statistics.median(times) * 1000:.1f} ms, "
              f"min {min(times) * 1000:.1f} ms (target < 100 ms)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
