"""Benchmark: load and cache the whole shared motion set, cold then warm.

Prints seconds and peak memory. Targets on the 2-core machine: under 60 s
cold, under 2 s warm. Run: ``make bench-data``.
"""

import os
import resource
import sys
import tempfile
import time

import numpy as np


def peak_mib():
    """Peak resident memory of this process and of its largest finished child, MiB."""
    own = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    child = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss
    return own / 1024, child / 1024


def main():
    with tempfile.TemporaryDirectory() as cache:
        os.environ["TRAJEVAE_CACHE"] = cache
        from model_runtime.data import dataset

        start = time.perf_counter()
        cold, errors = dataset.load_clips(dataset.DATA_ROOTS)
        cold_s = time.perf_counter() - start
        start = time.perf_counter()
        warm, _ = dataset.load_clips(dataset.DATA_ROOTS)
        warm_s = time.perf_counter() - start
    frames = sum(clip.frames for clip in warm)
    own, child = peak_mib()
    print(f"clips {len(warm)}  errors {len(errors)}  frames {frames}  "
          f"({frames / 30 / 60:.1f} min at 30 fps)  cores {os.cpu_count()}")
    print(f"cold load+cache  {cold_s:6.2f} s   (target < 60 s)")
    print(f"warm load        {warm_s:6.2f} s   (target < 2 s)")
    print(f"peak memory      {own:6.0f} MiB main process, {child:.0f} MiB largest worker")
    assert all(np.array_equal(a.positions, b.positions) for a, b in zip(cold, warm))
    return 0


if __name__ == "__main__":
    sys.exit(main())
