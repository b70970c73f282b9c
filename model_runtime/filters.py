"""Filters over the frames of a motion (the last axis of their input): eases, running minima and
maxima, smoothing."""

import numpy as np


def smoothstep(x):
    """3x^2 - 2x^3 of x clipped to [0, 1]: an ease with no velocity at either end."""
    x = np.clip(x, 0.0, 1.0)
    return x * x * (3.0 - 2.0 * x)


def runs(flags):
    """(start, end) frame pairs, end inclusive, of the True runs in flags (F,)."""
    edges = np.diff(np.concatenate([[0], flags.astype(np.int8), [0]]))
    return list(zip(np.flatnonzero(edges == 1), np.flatnonzero(edges == -1) - 1))


def _windows(values, half):
    """Views (..., F, 2 half + 1) of frames t - half .. t + half of values (..., F). Beyond the ends
    the values go on as they were going (point-reflected about the end frames), so a steady trend
    is filtered without bending at the edges; a motion shorter than the window is held instead."""
    if values.shape[-1] > half:
        before = 2 * values[..., :1] - values[..., half:0:-1]
        after = 2 * values[..., -1:] - values[..., -2:-half - 2:-1]
    else:
        before, after = np.repeat(values[..., :1], half, -1), np.repeat(values[..., -1:], half, -1)
    return np.lib.stride_tricks.sliding_window_view(np.concatenate([before, values, after], -1), 2 * half + 1,
                                                    axis=-1)


def window_min(values, half):
    """Minimum over frames t - half .. t + half of values (..., F)."""
    return _windows(values, half).min(-1)


def window_max(values, half):
    """Maximum over frames t - half .. t + half of values (..., F)."""
    return _windows(values, half).max(-1)


def smooth(values, sigma):
    """Gaussian smoothing (``sigma`` frames) of values (..., F) over frames."""
    if sigma < 0.5:
        return values
    half = int(np.ceil(3 * sigma))
    kernel = np.exp(-0.5 * (np.arange(-half, half + 1) / sigma) ** 2)
    return _windows(values, half) @ (kernel / kernel.sum())


def rate_limited_from_above(values, rate):
    """The least values (F,) at or above ``values`` (F,) that change by at most ``rate`` a frame:
    each frame's value, or a neighbour's less ``rate`` per frame between them, whichever is more."""
    steps = rate * np.arange(len(values))
    rising = np.maximum.accumulate(values + steps) - steps
    falling = (np.maximum.accumulate((values - steps)[::-1]) + steps[::-1])[::-1]
    return np.maximum(rising, falling)
