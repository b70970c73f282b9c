"""Benchmark: TrajeVAE inference of 10 samples of one window on the CPU (target < 100 ms on 2 cores).

Run: ``make bench-model``. Prints the median of repeated runs for k = 0 and k = 4 trajectories, in
torch and in the numpy path the add-on runs (with curves, the most plausible of a doubled pool),
and the diverse sampler's 10 variants (selected from a pool of ``selection.POOL_FACTOR`` x 10 sampler draws
and ``selection.PRIOR_POOL_FACTOR`` x 10 prior draws).
"""

import statistics
import sys
import time

import numpy as np
import torch

from model_runtime import masks, weights
from model_runtime.data import dataset
from model_runtime.numpy_model import NumpySampler, NumpyTrajeVAE
from model_runtime.sampler import prior_motions


def median_ms(run, repeats):
    """Median and minimum wall time of ``run()`` in milliseconds, after one warm-up call."""
    run()
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        run()
        times.append(time.perf_counter() - start)
    return statistics.median(times) * 1000, min(times) * 1000


def main(samples=10, repeats=30):
    torch.set_num_threads(2)
    model, meta = weights.load_model()
    clips, _ = dataset.load_clips([dataset.DATA_ROOTS[0] / "cmu_mb_01-09" / "02" / "02_01.bvh"])
    window = dataset.windows(clips, future=model.config.frames, stride=1000)[:1]
    initial = torch.from_numpy(window[:, 0])
    print(f"TrajeVAE {meta['parameters']:,} parameters, torch threads {torch.get_num_threads()}")
    for k in (0, 4):
        mask = torch.from_numpy(masks.evaluation_mask(k, model.config.frames)[None])
        trajectories = torch.from_numpy(window[:, 1:]) * mask[..., None]
        median, least = median_ms(lambda: prior_motions(model, initial, trajectories, mask, samples), repeats)
        print(f"torch k={k}: {samples} samples of {model.config.frames} frames: median {median:.1f} ms, "
              f"min {least:.1f} ms (target < 100 ms)")
    numpy_model, sampler = NumpyTrajeVAE(weights.MODEL_WEIGHTS), NumpySampler(weights.SAMPLER_WEIGHTS)
    rng = np.random.default_rng(0)
    for k, name, chosen in ((0, "prior samples", None), (4, "prior samples", None), (0, "diverse sampler", sampler)):
        mask = masks.evaluation_mask(k, model.config.frames)[None]
        trajectories = (window[:, 1:] * mask[..., None]).astype(np.float32)
        median, least = median_ms(lambda: numpy_model.sample(window[:, 0], trajectories, mask, samples, rng,
                                                             sampler=chosen), repeats)
        print(f"numpy k={k} {name}: {samples} samples: median {median:.1f} ms, min {least:.1f} ms")
    return 0


if __name__ == "__main__":
    sys.exit(main())
