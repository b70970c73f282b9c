"""Drawn paths as world-space polylines: Curve objects and Grease Pencil strokes, where they are seen."""

import numpy as np

from .runtime import curve_geometry


class CurveError(ValueError):
    pass


def _read(collection, attribute, width):
    """One float attribute (N, width) of every item of a bpy collection."""
    values = np.empty(len(collection) * width)
    collection.foreach_get(attribute, values)
    return values.reshape(-1, width)


def _world(points, matrix):
    """Points (P, 3) moved by a 4x4 matrix (mathutils or nested sequence)."""
    matrix = np.array(matrix, dtype=np.float64)
    return points @ matrix[:3, :3].T + matrix[:3, 3]


def _finite(values):
    """Whether every value is a number. Blender stores an infinite coordinate typed into a point as
    the largest 32-bit float, so that counts as infinite."""
    return bool((np.abs(values) < np.finfo(np.float32).max).all())  # False for NaN too


def _numbers(points, what):
    """The points (P, k), or a CurveError when a coordinate is NaN or infinite."""
    if not _finite(points):
        raise CurveError(f"{what} has a point that is not a number (NaN or infinite); fix or redraw it")
    return points


def _path(points, what):
    """World points (P, 3), or a CurveError when one is not a number or they do not make a path."""
    _numbers(points, what)
    if len(points) < 2 or np.linalg.norm(np.diff(points, axis=0), axis=1).sum() <= 1e-9:
        raise CurveError(f"{what} has no length (fewer than 2 distinct points); draw a longer path")
    return points


def polyline(curve_object):
    """World positions (P, 3) along a Curve object's one spline (Bezier, poly or NURBS), in order;
    a cyclic spline ends where it starts.

    The spline's control points are evaluated as Blender tessellates them
    (``resolution_u`` samples per segment or knot span), so a hidden curve, one
    not linked to the scene and a bevelled or extruded one (whose mesh is the
    tube's surface) are all followed along the spline itself. Shape keys and
    modifiers of the curve are not applied.
    """
    what = f"curve {curve_object.name!r}"
    splines = curve_object.data.splines
    if len(splines) != 1:
        raise CurveError(f"{what} has {len(splines)} splines; a bound curve needs exactly one")
    spline = splines[0]
    if spline.type == 'BEZIER':
        handles = spline.bezier_points
        controls = [_numbers(_read(handles, name, 3), what) for name in ("co", "handle_left", "handle_right")]
        points = curve_geometry.bezier(*controls, spline.resolution_u, spline.use_cyclic_u)
    else:
        homogeneous = _numbers(_read(spline.points, "co", 4), what)  # x, y, z and the NURBS weight
        if spline.type == 'POLY':
            points = curve_geometry.poly(homogeneous[:, :3], spline.use_cyclic_u)
        else:
            points = curve_geometry.nurbs(homogeneous[:, :3], homogeneous[:, 3], spline.order_u, spline.resolution_u,
                                          spline.use_cyclic_u, spline.use_endpoint_u, spline.use_bezier_u)
    return _path(_world(points, curve_object.matrix_world), what)


def _layer_to_world(gp_object, layer):
    """(4, 4) from a Grease Pencil layer's drawing space to the world, as the viewport draws it:
    the layer's own transform, then its parent object (or parent bone) through the parent inverse
    when it has one, else the object's transform."""
    local = np.array(layer.matrix_local, dtype=np.float64)
    parent = layer.parent
    if parent is None:
        return np.array(gp_object.matrix_world, dtype=np.float64) @ local
    parent_world = np.array(parent.matrix_world, dtype=np.float64)
    if parent.type == 'ARMATURE' and layer.parent_bone in parent.pose.bones:
        parent_world = parent_world @ np.array(parent.pose.bones[layer.parent_bone].matrix, dtype=np.float64)
    return parent_world @ np.array(layer.matrix_parent_inverse, dtype=np.float64) @ local


def stroke(gp_object, frame):
    """World positions (P, 3) of a Grease Pencil object's last drawn stroke, where it is seen, and
    the drawing time of each point in seconds (P,) or None when the stroke carries none.

    The stroke is taken from the active layer's drawing shown at ``frame`` and
    placed by the layer's transform and parent as well as the object's.
    """
    what = f"grease pencil {gp_object.name!r}"
    layer = gp_object.data.layers.active or next(iter(gp_object.data.layers), None)
    shown = [f for f in layer.frames if f.frame_number <= frame] if layer else []
    if not shown:
        raise CurveError(f"{what} has no drawing at frame {frame}")
    drawing = max(shown, key=lambda f: f.frame_number).drawing
    offsets = [offset.value for offset in drawing.curve_offsets]
    if len(offsets) < 2:
        raise CurveError(f"{what} has no stroke at frame {frame}")
    points = _numbers(_read(drawing.attributes["position"].data, "vector", 3)[offsets[-2]:], what)
    points = _path(_world(points, _layer_to_world(gp_object, layer)), what)
    times = None
    if "delta_time" in drawing.attributes:
        values = _read(drawing.attributes["delta_time"].data, "value", 1)[offsets[-2]:, 0]
        if not _finite(values):
            raise CurveError(f"{what} has a drawing time that is not a number (NaN or infinite); "
                             "turn off its drawing speed or redraw it")
        if not np.all(np.diff(values) >= 0):  # per-point increments rather than time since the start
            values = np.cumsum(values)
        times = values if values[-1] > values[0] else None
    return points, times


def path(obj, frame):
    """(world points (P, 3), drawing times (P,) or None) of a Curve object or a Grease Pencil stroke
    (the stroke shown at ``frame``)."""
    if obj.type == 'CURVE':
        return polyline(obj), None
    if obj.type == 'GREASEPENCIL':
        return stroke(obj, frame)
    raise CurveError(f"{obj.name!r} is a {obj.type.lower()}: bind a curve or a grease pencil stroke")
