"""Drawn paths as world-space polylines: Curve objects and Grease Pencil strokes."""

import numpy as np


class CurveError(ValueError):
    pass


def polyline(curve_object, depsgraph):
    """World positions (P, 3) along a Curve object's spline (Bezier, poly or NURBS), in order.

    The evaluated curve is tessellated by Blender (``resolution_u`` points per
    segment), so modifiers and shape keys count.
    """
    splines = len(curve_object.data.splines)
    if splines != 1:
        raise CurveError(f"curve {curve_object.name!r} has {splines} splines; a bound curve needs exactly one")
    evaluated = curve_object.evaluated_get(depsgraph)
    mesh = evaluated.to_mesh()
    try:
        count = len(mesh.vertices)
        if count < 2:
            raise CurveError(f"curve {curve_object.name!r} has fewer than 2 points")
        points = np.empty(count * 3)
        mesh.vertices.foreach_get("co", points)
        points = points.reshape(count, 3)
    finally:
        evaluated.to_mesh_clear()
    world = np.array(curve_object.matrix_world, dtype=np.float64)
    return points @ world[:3, :3].T + world[:3, 3]


def stroke(gp_object, frame):
    """World positions (P, 3) of a Grease Pencil object's last drawn stroke, and the drawing time
    of each point in seconds (P,) or None when the stroke carries none.

    The stroke is taken from the active layer's drawing shown at ``frame``.
    """
    layer = gp_object.data.layers.active or next(iter(gp_object.data.layers), None)
    shown = [f for f in layer.frames if f.frame_number <= frame] if layer else []
    if not shown:
        raise CurveError(f"grease pencil {gp_object.name!r} has no drawing at frame {frame}")
    drawing = max(shown, key=lambda f: f.frame_number).drawing
    offsets = [offset.value for offset in drawing.curve_offsets]
    if len(offsets) < 2 or offsets[-1] - offsets[-2] < 2:
        raise CurveError(f"grease pencil {gp_object.name!r}: its last stroke has fewer than 2 points")
    points = np.empty(offsets[-1] * 3, dtype=np.float32)
    drawing.attributes["position"].data.foreach_get("vector", points)
    points = points.reshape(-1, 3)[offsets[-2]:].astype(np.float64)
    times = None
    if "delta_time" in drawing.attributes:
        values = np.empty(offsets[-1], dtype=np.float32)
        drawing.attributes["delta_time"].data.foreach_get("value", values)
        values = values[offsets[-2]:].astype(np.float64)
        if not np.all(np.diff(values) >= 0):  # per-point increments rather than time since the start
            values = np.cumsum(values)
        times = values if values[-1] > values[0] else None
    world = np.array(gp_object.matrix_world, dtype=np.float64)
    return points @ world[:3, :3].T + world[:3, 3], times


def path(obj, depsgraph, frame):
    """(world points (P, 3), drawing times (P,) or None) of a Curve object or a Grease Pencil stroke."""
    if obj.type == 'CURVE':
        return polyline(obj, depsgraph), None
    if obj.type == 'GREASEPENCIL':
        return stroke(obj, frame)
    raise CurveError(f"{obj.name!r} is a {obj.type.lower()}: bind a curve or a grease pencil stroke")
