"""Drawn paths as world-space polylines."""

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
