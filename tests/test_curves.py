"""Curves and strokes read as drawn and seen, with real bpy; the spline math on its own."""

import bpy
import numpy as np
import pytest

import blender_rigs
from model_runtime import curve_geometry
from trajevae_addon import api, curves

WAVE = np.array([[0.0, 0.0, 1.0], [0.4, -0.3, 1.2], [0.9, -0.2, 0.8], [1.3, 0.3, 1.1], [1.6, 0.1, 1.5],
                 [2.0, -0.4, 1.3], [2.3, 0.2, 0.9]])  # (7, 3) control points of a wavy path in metres


def _linked(scene, name, data):
    obj = bpy.data.objects.new(name, data)
    scene.collection.objects.link(obj)
    return obj


def _bezier(scene, name, points, cyclic=False, resolution=12):
    """A Bezier Curve object through points (N, 3) with automatic handles."""
    data = bpy.data.curves.new(name, 'CURVE')
    data.dimensions = '3D'
    spline = data.splines.new('BEZIER')
    spline.bezier_points.add(len(points) - 1)
    for point, co in zip(spline.bezier_points, points):
        point.co = co
        point.handle_left_type = point.handle_right_type = 'AUTO'
    spline.use_cyclic_u, spline.resolution_u = cyclic, resolution
    return _linked(scene, name, data)


def _spline(scene, name, kind, points, weights=None, cyclic=False, resolution=12, **settings):
    """A poly or NURBS Curve object on control points (N, 3) with weights (N,) and spline settings."""
    data = bpy.data.curves.new(name, 'CURVE')
    data.dimensions = '3D'
    spline = data.splines.new(kind)
    spline.points.add(len(points) - 1)
    weights = np.ones(len(points)) if weights is None else weights
    spline.points.foreach_set("co", np.column_stack([points, weights]).ravel())
    spline.use_cyclic_u, spline.resolution_u = cyclic, resolution
    for key, value in settings.items():
        setattr(spline, key, value)
    return _linked(scene, name, data)


def _tube(obj):
    """Give a curve a thick bevelled and extruded tube, as artists do to see a path in renders."""
    obj.data.bevel_depth, obj.data.extrude = 0.05, 0.1
    return obj


def _blender_tessellation(scene, obj):
    """World points (V, 3) of Blender's own mesh of a visible, unbevelled copy of a curve object,
    closed when its spline is cyclic."""
    copy = obj.copy()
    copy.data = obj.data.copy()
    copy.data.bevel_depth = copy.data.extrude = 0.0
    copy.hide_viewport = False
    scene.collection.objects.link(copy)
    evaluated = copy.evaluated_get(bpy.context.evaluated_depsgraph_get())
    mesh = evaluated.to_mesh()
    points = np.empty(len(mesh.vertices) * 3)
    mesh.vertices.foreach_get("co", points)
    evaluated.to_mesh_clear()
    world = np.array(copy.matrix_world)
    points = points.reshape(-1, 3) @ world[:3, :3].T + world[:3, 3]
    return np.concatenate([points, points[:1]]) if obj.data.splines[0].use_cyclic_u else points


def _length(points):
    return float(np.linalg.norm(np.diff(points, axis=0), axis=1).sum())


def _resampled(points, count=400):
    """Points (count, 3) evenly spaced in arc length along a polyline (P, 3)."""
    travelled = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(points, axis=0), axis=1))])
    wanted = np.linspace(0.0, travelled[-1], count)
    return np.stack([np.interp(wanted, travelled, points[:, axis]) for axis in range(3)], axis=-1)


def _read(obj):
    """The path the add-on follows for a bound object at frame 1, as the pipeline asks for it
    (after the scene is evaluated, which places moved objects)."""
    bpy.context.view_layer.update()
    return curves.path(obj, 1)[0]


def _assert_same_path(ours, blenders, tolerance=0.002):
    assert abs(_length(ours) - _length(blenders)) < tolerance
    assert np.linalg.norm(_resampled(ours) - _resampled(blenders), axis=1).max() < tolerance


def test_hidden_and_unlinked_bound_curves_are_read(scene):
    rig = blender_rigs.mannequin_rig(scene)
    for hide in ("hide_viewport", "hide_set", "unlinked"):
        curve = blender_rigs.curve(scene, f"HandPath {hide}", WAVE)
        curve.location = (0.0, -0.5, 0.0)
        bpy.context.view_layer.update()
        api.bind_curve(rig, "LWrist", curve)
        if hide == "hide_viewport":
            curve.hide_viewport = True
        elif hide == "hide_set":
            curve.hide_set(True)
        else:
            scene.collection.objects.unlink(curve)
        np.testing.assert_allclose(_read(curve), WAVE + [0.0, -0.5, 0.0], atol=1e-6)


def test_bevelled_and_extruded_curve_is_followed_along_its_spline(scene):
    curve = _bezier(scene, "HandPath", WAVE)
    curve.rotation_euler = (0.0, 0.0, 0.6)
    plain = _read(curve)
    bevelled = _read(_tube(curve))
    np.testing.assert_allclose(bevelled, plain, atol=1e-9)
    length, blenders = _length(bevelled), curve.data.splines[0].calc_length()
    print(f"bevelled curve: length {length:.4f} m, spline.calc_length {blenders:.4f} m")
    assert abs(length - blenders) < 0.01 * blenders


@pytest.mark.parametrize("kind, cyclic, resolution", [
    ('BEZIER', False, 12), ('BEZIER', True, 12), ('BEZIER', False, 3), ('POLY', False, 12), ('POLY', True, 12)])
def test_bezier_and_poly_curves_match_blenders_tessellation(scene, kind, cyclic, resolution):
    if kind == 'BEZIER':
        curve = _bezier(scene, "HandPath", WAVE, cyclic, resolution)
    else:
        curve = _spline(scene, "HandPath", kind, WAVE, cyclic=cyclic, resolution=resolution)
    curve.scale = (1.0, 2.0, 1.0)
    bpy.context.view_layer.update()
    curve.hide_viewport = True  # disabled in viewports: not evaluated, its mesh not made
    ours = _read(_tube(curve))
    _assert_same_path(ours, _blender_tessellation(scene, curve))
    if cyclic:  # the loop closes: it ends where it starts
        np.testing.assert_allclose(ours[-1], ours[0])


@pytest.mark.parametrize("order, endpoint, bezier_knots, cyclic", [
    (3, False, False, False), (3, True, False, False), (4, False, False, False), (4, True, False, False),
    (4, True, True, False), (3, False, True, False), (4, False, False, True), (3, True, False, True),
    (4, False, True, True)])
def test_nurbs_curves_match_blenders_tessellation(scene, order, endpoint, bezier_knots, cyclic):
    weights = np.array([1.0, 2.5, 0.5, 1.0, 3.0, 0.8, 1.0])
    points = WAVE[:6] if cyclic and bezier_knots else WAVE  # whole Bezier segments close a cyclic curve
    curve = _spline(scene, "HandPath", 'NURBS', points, weights[:len(points)], cyclic, 10, order_u=order,
                    use_endpoint_u=endpoint, use_bezier_u=bezier_knots)
    curve.location = (0.3, 0.0, -0.2)
    ours = _read(_tube(curve))
    blenders = _blender_tessellation(scene, curve)
    _assert_same_path(ours, blenders)
    if endpoint and not cyclic:  # clamped: starts and ends on its end control points
        np.testing.assert_allclose(ours[[0, -1]], WAVE[[0, -1]] + [0.3, 0.0, -0.2], atol=1e-6)


def _grease_pencil(scene, name, points):
    """A Grease Pencil object with one layer whose drawing at frame 1 is one stroke through
    points (P, 3)."""
    data = bpy.data.grease_pencils.new(name)
    drawing = data.layers.new("Lines").frames.new(1).drawing
    drawing.add_strokes([len(points)])
    drawing.attributes["position"].data.foreach_set("vector", np.asarray(points, np.float32).ravel())
    return _linked(scene, name, data)


def _blender_stroke(scene, gp_object):
    """World points (P, 3) of a Grease Pencil object as Blender places them when it converts a copy
    to a mesh."""
    copy = gp_object.copy()
    copy.data = gp_object.data.copy()
    scene.collection.objects.link(copy)
    for obj in scene.objects:
        obj.select_set(obj == copy)
    bpy.context.view_layer.objects.active = copy
    assert bpy.ops.object.convert(target='MESH') == {'FINISHED'}
    points = np.empty(len(copy.data.vertices) * 3)
    copy.data.vertices.foreach_get("co", points)
    world = np.array(copy.matrix_world)
    return points.reshape(-1, 3) @ world[:3, :3].T + world[:3, 3]


def test_grease_pencil_stroke_is_followed_where_its_layer_shows_it(scene):
    stroke = _grease_pencil(scene, "Stroke", WAVE)
    layer = stroke.data.layers["Lines"]
    before = _read(stroke)
    layer.translation = (0.0, 0.0, 0.5)
    np.testing.assert_allclose(_read(stroke), before + [0.0, 0.0, 0.5], atol=1e-6)

    stroke.location, stroke.rotation_euler = (0.2, 0.0, 0.3), (0.0, 0.0, 0.7)
    layer.rotation, layer.scale = (0.3, 0.0, 0.2), (1.5, 1.0, 1.0)
    np.testing.assert_allclose(_read(stroke), _blender_stroke(scene, stroke), atol=1e-5)
    carrier = _linked(scene, "Carrier", None)
    carrier.location = (1.0, 0.0, 0.0)
    bpy.context.view_layer.update()
    layer.parent = carrier  # parenting keeps the stroke in place; moving the parent then carries it
    carrier.location, carrier.rotation_euler = (1.0, 2.0, 0.5), (0.4, 0.0, 0.0)
    bpy.context.view_layer.update()
    np.testing.assert_allclose(_read(stroke), _blender_stroke(scene, stroke), atol=1e-5)


def test_points_that_are_not_numbers_are_refused_with_a_sentence(scene):
    broken = WAVE.copy()
    broken[3, 1] = np.nan
    poly = blender_rigs.curve(scene, "HandPath", broken)
    bezier = _bezier(scene, "FootPath", WAVE)
    handle = bezier.data.splines[0].bezier_points[2]
    handle.handle_right_type = 'FREE'  # an automatic handle would be recomputed
    handle.handle_right = (np.inf, 0.0, 0.0)  # kept as the largest float32
    nurbs = _spline(scene, "HipPath", 'NURBS', WAVE, np.array([1.0, 1.0, np.nan, 1.0, 1.0, 1.0, 1.0]), order_u=4)
    stroke = _grease_pencil(scene, "Stroke", broken)
    for obj, what in ((poly, "curve 'HandPath'"), (bezier, "curve 'FootPath'"), (nurbs, "curve 'HipPath'"),
                      (stroke, "grease pencil 'Stroke'")):
        with pytest.raises(curves.CurveError, match=f"^{what} has a point that is not a number"):
            _read(obj)
    timed = _grease_pencil(scene, "Timed", WAVE)
    timed.data.layers["Lines"].frames[0].drawing.strokes[0].points[2].delta_time = np.nan
    with pytest.raises(curves.CurveError, match="^grease pencil 'Timed' has a drawing time that is not a number"):
        curves.path(timed, 1)


def test_paths_without_length_are_refused_with_a_sentence(scene):
    still = blender_rigs.curve(scene, "Still", np.repeat(WAVE[:1], 4, axis=0))
    dot = blender_rigs.curve(scene, "Dot", WAVE[:1])
    tap = _grease_pencil(scene, "Tap", WAVE[:1])
    for obj, what in ((still, "curve 'Still'"), (dot, "curve 'Dot'"), (tap, "grease pencil 'Tap'")):
        with pytest.raises(curves.CurveError, match=f"^{what} has no length"):
            _read(obj)
    two = blender_rigs.curve(scene, "Two", WAVE)
    two.data.splines.new('POLY').points.add(1)
    with pytest.raises(curves.CurveError, match="^curve 'Two' has 2 splines; a bound curve needs exactly one"):
        _read(two)


def test_bezier_segments_are_cubics_through_their_handles():
    points = np.array([[0.0, 0.0, 0.0], [3.0, 0.0, 0.0]])
    line = curve_geometry.bezier(points, points - [1.0, 0.0, 0.0], points + [1.0, 0.0, 0.0], 6, False)
    np.testing.assert_allclose(line[:, 0], np.linspace(0.0, 3.0, 7))  # handles at thirds: even steps
    loop = curve_geometry.bezier(points, points + [[0.0, -1.0, 0.0], [0.0, 1.0, 0.0]],
                                 points + [[0.0, 1.0, 0.0], [0.0, -1.0, 0.0]], 4, True)
    assert loop.shape == (9, 3)
    np.testing.assert_allclose(loop[[0, 4, 8]], points[[0, 1, 0]])
    np.testing.assert_allclose(loop[2], [1.5, 0.75, 0.0])  # the cubic's midpoint: (p0 + 3 h0 + 3 h1 + p1) / 8


def test_nurbs_knot_vectors():
    np.testing.assert_array_equal(curve_geometry.nurbs_knots(5, 3, False, False, False), np.arange(8))
    np.testing.assert_array_equal(curve_geometry.nurbs_knots(5, 3, False, True, False),
                                  [0, 0, 0, 1, 2, 3, 3, 3])
    np.testing.assert_array_equal(curve_geometry.nurbs_knots(7, 4, False, True, True),
                                  [0, 0, 0, 0, 1, 1, 1, 2, 2, 2, 2])
    assert len(curve_geometry.nurbs_knots(6, 4, True, False, False)) == 6 + 4 + 3


def test_rational_quadratic_nurbs_draws_a_circular_arc():
    corner = np.array([[1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 1.0, 0.0]])
    arc = curve_geometry.nurbs(corner, [1.0, np.sqrt(0.5), 1.0], 3, 16, False, True, False)
    assert arc.shape == (17, 3)
    np.testing.assert_allclose(np.linalg.norm(arc, axis=1), 1.0, atol=1e-12)
    straight = curve_geometry.nurbs(corner, [1.0, 1.0, 1.0], 3, 16, False, True, False)
    assert np.linalg.norm(straight[8]) > 1.05  # equal weights give a parabola, nearer the corner


def test_clamped_bezier_knots_give_the_bezier_cubic():
    controls = WAVE[:4]
    as_nurbs = curve_geometry.nurbs(controls, np.ones(4), 4, 8, False, True, True)
    as_bezier = curve_geometry.bezier(controls[[0, 3]], controls[[0, 2]], controls[[1, 3]], 8, False)
    np.testing.assert_allclose(as_nurbs, as_bezier, atol=1e-12)


def test_unevaluable_nurbs_shows_its_control_polygon():
    np.testing.assert_array_equal(curve_geometry.nurbs(WAVE[:3], np.ones(3), 4, 12, False, False, False), WAVE[:3])
    np.testing.assert_array_equal(curve_geometry.nurbs(WAVE[:3], np.ones(3), 4, 12, True, False, False),
                                  WAVE[[0, 1, 2, 0]])
