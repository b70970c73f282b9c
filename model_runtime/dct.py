"""Orthonormal DCT-II over time, as a matrix so it runs as one matmul in numpy or torch."""

import numpy as np


def dct_matrix(length):
    """(length, length) orthonormal DCT-II: coefficients = D @ signal; signal = D.T @ coefficients."""
    n = np.arange(length)
    basis = np.cos(np.pi * (n[None, :] + 0.5) * n[:, None] / length)
    basis[0] *= np.sqrt(1.0 / length)
    basis[1:] *= np.sqrt(2.0 / length)
    return basis
