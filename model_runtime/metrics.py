"""Accuracy and diversity metrics of the DLow protocol that all four papers report.

Protocol: float64, root removed, the other 16 joints relative to the root,
flattened to 48 numbers per frame, metres.
"""

import numpy as np


def to_protocol(motion):
    """(..., T, 17, 3) -> (..., T, 48) root-relative, float64."""
    motion = np.asarray(motion, dtype=np.float64)
    relative = motion[..., 1:, :] - motion[..., :1, :]
    return relative.reshape(*relative.shape[:-2], -1)


def pairwise_distances(samples):
    """L2 distances (K, K) between K samples (K, T, 48), each flattened: one matrix product."""
    flat = samples.reshape(len(samples), -1)
    return np.sqrt(np.maximum(_squared_distances(flat), 0.0))


def diversity(samples):
    """(APD, MPD) of K samples (K, T, 48): mean and minimum pairwise distance; near-duplicates give
    MPD 0; both 0 for K = 1."""
    if len(samples) < 2:
        return 0.0, 0.0
    distances = pairwise_distances(samples)
    count = len(samples)
    apd = distances.sum() / (count * (count - 1))
    np.fill_diagonal(distances, np.inf)
    return float(apd), float(distances.min())


def ade_fde(samples, truth):
    """Best-of-K average and final displacement errors of samples (K, T, 48) against (T, 48)."""
    ade, fde = _best_of_k(samples, truth[None])
    return float(ade[0]), float(fde[0])


def multimodal_ade_fde(samples, pseudo_truths):
    """ADE and FDE averaged over pseudo ground truths (P, T, 48)."""
    ade, fde = _best_of_k(samples, pseudo_truths)
    return float(ade.mean()), float(fde.mean())


def _best_of_k(samples, truths):
    """Per truth (P,), the best sample's mean and final frame distance: one batched matmul per frame."""
    frame_first_samples = np.ascontiguousarray(samples.transpose(1, 0, 2))  # (T, K, 48)
    frame_first_truths = np.ascontiguousarray(truths.transpose(1, 2, 0))  # (T, 48, P)
    squared = (np.einsum("tkd,tkd->tk", frame_first_samples, frame_first_samples)[:, :, None]
               + np.einsum("tdp,tdp->tp", frame_first_truths, frame_first_truths)[:, None, :]
               - 2.0 * frame_first_samples @ frame_first_truths)  # (T, K, P)
    distance = np.sqrt(np.maximum(squared, 0.0))
    return distance.mean(axis=0).min(axis=0), distance[-1].min(axis=0)


def pseudo_truth_groups(initial_poses, threshold=0.5):
    """For each window, the windows whose initial pose (N, 48) lies within L2 < threshold (itself included)."""
    distances = np.sqrt(np.maximum(_squared_distances(initial_poses), 0.0))
    return [np.flatnonzero(row < threshold) for row in distances]


def trajectory_error(motion, trajectories, mask):
    """Mean distance (m) of known joints to their given positions: motion (..., T, J, 3), mask (T, J)."""
    if not mask.any():
        return float("nan")
    distance = np.linalg.norm(np.asarray(motion, np.float64) - trajectories, axis=-1)
    return float(distance[..., mask > 0].mean())


def _squared_distances(flat):
    squared_norms = np.einsum("ij,ij->i", flat, flat)
    return squared_norms[:, None] + squared_norms[None, :] - 2.0 * flat @ flat.T
