"""Quaternion helpers (w, x, y, z), vectorised over any leading shape."""

import numpy as np

_AXES = {"X": 0, "Y": 1, "Z": 2}


def axis_angle(axis, angles):
    """Quaternions of rotations by ``angles`` (...,) radians about a principal axis 'X', 'Y' or 'Z'."""
    half = 0.5 * np.asarray(angles, dtype=np.float64)
    quat = np.zeros(half.shape + (4,))
    quat[..., 0] = np.cos(half)
    quat[..., 1 + _AXES[axis]] = np.sin(half)
    return quat


def turned(vectors, axis, angle):
    """Vectors (..., N, 3) turned by ``angle`` (...) radians about unit ``axis`` (..., 3) (Rodrigues)."""
    k, cos, sin = axis[..., None, :], np.cos(angle)[..., None, None], np.sin(angle)[..., None, None]
    return vectors * cos + np.cross(k, vectors) * sin + k * (vectors * k).sum(-1, keepdims=True) * (1.0 - cos)


def multiply(a, b):
    """Hamilton product a * b of (..., 4) quaternions (apply b, then a)."""
    aw, ax, ay, az = np.moveaxis(a, -1, 0)
    bw, bx, by, bz = np.moveaxis(b, -1, 0)
    return np.stack([
        aw * bw - ax * bx - ay * by - az * bz,
        aw * bx + ax * bw + ay * bz - az * by,
        aw * by - ax * bz + ay * bw + az * bx,
        aw * bz + ax * by - ay * bx + az * bw,
    ], axis=-1)


def euler(angles_deg, order):
    """Quaternions of intrinsic Euler rotations as BVH channels list them.

    ``angles_deg`` is (..., 3) in the order of ``order`` (e.g. "ZYX"); the
    rotation is R = R_order[0] @ R_order[1] @ R_order[2].
    """
    angles = np.radians(angles_deg)
    quat = axis_angle(order[0], angles[..., 0])
    for k in (1, 2):
        quat = multiply(quat, axis_angle(order[k], angles[..., k]))
    return quat


def to_matrix(quat):
    """Rotation matrices (..., 3, 3) of unit quaternions (..., 4)."""
    w, x, y, z = np.moveaxis(quat, -1, 0)
    return np.stack([
        np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
        np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),
        np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1),
    ], -2)


def slerp(q0, q1, t):
    """Spherical interpolation between (..., 4) quaternions at fractions t (...,)."""
    dot = np.sum(q0 * q1, axis=-1)
    q1 = np.where(dot[..., None] < 0, -q1, q1)
    dot = np.abs(dot)
    t = np.asarray(t)[..., None] * np.ones_like(dot)[..., None]
    theta = np.arccos(np.clip(dot, -1.0, 1.0))[..., None]
    sin_theta = np.sin(theta)
    close = sin_theta < 1e-6
    safe = np.where(close, 1.0, sin_theta)
    w0 = np.where(close, 1.0 - t, np.sin((1.0 - t) * theta) / safe)
    w1 = np.where(close, t, np.sin(t * theta) / safe)
    out = w0 * q0 + w1 * q1
    return out / np.linalg.norm(out, axis=-1, keepdims=True)


def from_matrix(matrix):
    """Unit quaternions (..., 4) of rotation matrices (..., 3, 3), w >= 0."""
    m = matrix
    trace = m[..., 0, 0] + m[..., 1, 1] + m[..., 2, 2]
    candidates = np.stack([  # 4x the quaternion, each well conditioned where its term is largest
        np.stack([1 + trace, m[..., 2, 1] - m[..., 1, 2], m[..., 0, 2] - m[..., 2, 0], m[..., 1, 0] - m[..., 0, 1]], -1),
        np.stack([m[..., 2, 1] - m[..., 1, 2], 1 + m[..., 0, 0] - m[..., 1, 1] - m[..., 2, 2],
                  m[..., 0, 1] + m[..., 1, 0], m[..., 0, 2] + m[..., 2, 0]], -1),
        np.stack([m[..., 0, 2] - m[..., 2, 0], m[..., 0, 1] + m[..., 1, 0],
                  1 - m[..., 0, 0] + m[..., 1, 1] - m[..., 2, 2], m[..., 1, 2] + m[..., 2, 1]], -1),
        np.stack([m[..., 1, 0] - m[..., 0, 1], m[..., 0, 2] + m[..., 2, 0], m[..., 1, 2] + m[..., 2, 1],
                  1 - m[..., 0, 0] - m[..., 1, 1] + m[..., 2, 2]], -1),
    ], -2)
    best = np.argmax(np.stack([trace, m[..., 0, 0], m[..., 1, 1], m[..., 2, 2]], -1), axis=-1)
    quat = np.take_along_axis(candidates, best[..., None, None], axis=-2)[..., 0, :]
    quat = quat / np.linalg.norm(quat, axis=-1, keepdims=True)
    return np.where(quat[..., :1] < 0, -quat, quat)


def continuous(quats):
    """Quaternions (F, ..., 4) with signs chosen so consecutive frames are on the same side."""
    dots = np.sum(quats[1:] * quats[:-1], axis=-1)
    signs = np.concatenate([np.ones_like(dots[:1]), np.cumprod(np.where(dots < 0, -1.0, 1.0), axis=0)])
    return quats * signs[..., None]


def to_euler(matrix, order):
    """Blender Euler angles (F, ..., 3) as (x, y, z) of matrices (F, ..., 3, 3), unwrapped over frames.

    Blender's order "XYZ" applies X first: matrix = Rz @ Ry @ Rx.
    """
    i, j, k = (_AXES[axis] for axis in order)
    parity = 1.0 if (j - i) % 3 == 1 else -1.0
    m = matrix
    first = np.arctan2(parity * m[..., k, j], m[..., k, k])
    middle = np.arcsin(np.clip(-parity * m[..., k, i], -1.0, 1.0))
    last = np.arctan2(parity * m[..., j, i], m[..., i, i])
    angles = np.zeros(m.shape[:-2] + (3,))
    angles[..., i], angles[..., j], angles[..., k] = first, middle, last
    return np.unwrap(angles, axis=0)


def to_axis_angle(quats):
    """Blender axis-angle (angle, x, y, z) (..., 4) of unit quaternions; the Y axis at zero angle."""
    vector = quats[..., 1:]
    length = np.linalg.norm(vector, axis=-1)
    angle = 2.0 * np.arctan2(length, quats[..., 0])
    axis = np.where(length[..., None] > 1e-9, vector / np.maximum(length, 1e-12)[..., None], [0.0, 1.0, 0.0])
    return np.concatenate([angle[..., None], axis], axis=-1)
