"""Splines tessellated as Blender 5.0 draws them: cubic Bezier, poly and NURBS (no bpy).

The add-on reads a Curve object's control points and evaluates them here
rather than through Blender's mesh conversion, which needs the object in the
depsgraph and follows the surface of a bevelled or extruded tube.
"""

import numpy as np


def poly(points, cyclic):
    """A poly spline's points (N, 3) as a polyline (N, 3), or (N + 1, 3) closed when cyclic."""
    points = np.asarray(points, dtype=np.float64)
    return np.concatenate([points, points[:1]]) if cyclic else points


def bezier(points, handles_left, handles_right, resolution, cyclic):
    """Positions (S, 3) along a cubic Bezier spline.

    ``points``, ``handles_left`` and ``handles_right`` are (N, 3); each segment
    from point i to point i + 1 (and from the last to the first when cyclic)
    is sampled ``resolution`` times at even parameter steps, as Blender does.
    The last point ends the polyline; when cyclic, that is the first point
    again, so S = segments * resolution + 1.
    """
    points = np.asarray(points, dtype=np.float64)
    handles_left = np.asarray(handles_left, dtype=np.float64)
    handles_right = np.asarray(handles_right, dtype=np.float64)
    starts = np.arange(len(points) if cyclic else len(points) - 1)
    ends = (starts + 1) % len(points)
    controls = np.stack([points[starts], handles_right[starts], handles_left[ends], points[ends]], axis=1)
    t = np.arange(resolution) / resolution
    u = 1.0 - t
    bernstein = np.stack([u ** 3, 3.0 * u * u * t, 3.0 * u * t * t, t ** 3], axis=1)  # (resolution, 4)
    samples = np.einsum("rk,skd->srd", bernstein, controls).reshape(-1, 3)
    return np.concatenate([samples, points[:1] if cyclic else points[-1:]])


def nurbs_knots(count, order, cyclic, endpoint, bezier_knots):
    """Blender's generated knot vector (count + order + (order - 1 when cyclic),) for a NURBS
    spline of ``count`` points.

    Knots step by 1. ``endpoint`` clamps the curve to its end points (the
    first knot repeated ``order`` times); ``bezier_knots`` repeats inner knots
    ``order - 1`` times so every ``order - 1`` points make a Bezier segment.
    The last knots (``2 order - 1`` when cyclic, ``order`` when clamped)
    repeat the spacing of the first ones, so the curve closes or is clamped
    at both ends alike.
    """
    size = count + order + (order - 1 if cyclic else 0)
    inner = order - 1 if bezier_knots else 1
    if endpoint:
        first = order - 1 if cyclic else order
    else:
        first = min(2, inner) if bezier_knots else 1
    tail = 2 * order - 1 if cyclic else (order if endpoint else 0)
    lead = 1 if endpoint and cyclic else 0  # one knot before the clamped start of a cyclic curve
    knots = np.zeros(size)
    value, left_in_group = float(lead), first
    for index in range(lead, size - tail):
        knots[index] = value
        left_in_group -= 1
        if left_in_group == 0:
            value, left_in_group = value + 1.0, inner
    for index in range(tail):  # in order: a short curve's tail repeats knots written just before
        knots[size - tail + index] = value + knots[index] - knots[0]
    return knots


def _basis(knots, degree, spans, parameters):
    """Values (S, degree + 1) of the degree + 1 B-spline basis functions that are non-zero at each
    parameter (S,), lying in knot span ``spans`` (S,) (knots[span] < knots[span + 1]).

    Column j belongs to control point spans - degree + j (the Cox-de Boor
    triangle, built up one degree at a time).
    """
    values = np.zeros((len(parameters), degree + 1))
    values[:, 0] = 1.0
    for level in range(1, degree + 1):
        # distance from the parameter back to the knots on its left and on to those on its right
        left = parameters[:, None] - knots[spans[:, None] + 1 - np.arange(1, level + 1)]  # (S, level)
        right = knots[spans[:, None] + np.arange(1, level + 1)] - parameters[:, None]  # (S, level)
        carried = np.zeros(len(parameters))
        for r in range(level):
            share = values[:, r] / (right[:, r] + left[:, level - r - 1])
            values[:, r] = carried + right[:, r] * share
            carried = left[:, level - r - 1] * share
        values[:, level] = carried
    return values


def nurbs(points, weights, order, resolution, cyclic, endpoint, bezier_knots):
    """Positions (S, 3) along a NURBS spline of control points (N, 3) with weights (N,).

    As Blender 5.0 evaluates it: the generated knot vector (``nurbs_knots``),
    ``resolution`` evenly spaced parameters in every knot span of non-zero
    length, the rational basis (weighted control points divided by the sum of
    the weighted basis). A cyclic curve wraps its first ``order - 1`` points
    around and ends on its first sample; an open one ends on its last
    parameter. Where Blender cannot evaluate the spline (fewer points than the
    order; Bezier knots whose points do not fit whole segments) it shows the
    control points joined by straight lines, and so does this.
    """
    points = np.asarray(points, dtype=np.float64)
    weights = np.asarray(weights, dtype=np.float64)
    count, degree = len(points), order - 1
    fits_bezier = (endpoint or count > order) and (not cyclic or count % degree == 0)
    if count < order or resolution < 1 or (bezier_knots and not fits_bezier):
        return poly(points, cyclic)
    knots = nurbs_knots(count, order, cyclic, endpoint, bezier_knots)
    last = count + degree if cyclic else count  # control points after wrapping
    spans = np.arange(degree, last)
    spans = spans[knots[spans + 1] > knots[spans]]
    steps = np.arange(resolution) / resolution
    parameters = (knots[spans, None] + steps * (knots[spans + 1] - knots[spans])[:, None]).ravel()
    span_of = np.repeat(spans, resolution)
    if not cyclic:
        parameters = np.append(parameters, knots[last])
        span_of = np.append(span_of, spans[-1])
    basis = _basis(knots, degree, span_of, parameters)
    indices = (span_of[:, None] - degree + np.arange(order)) % count  # (S, order) control points
    weighted = basis * weights[indices]
    positions = np.einsum("so,sod->sd", weighted, points[indices]) / weighted.sum(axis=1, keepdims=True)
    return np.concatenate([positions, positions[:1]]) if cyclic else positions
