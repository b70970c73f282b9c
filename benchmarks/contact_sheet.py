"""Contact sheets of played shots: stick figures drawn with numpy, saved as PNG through Blender.

A sheet has a column per take (variant or capture clip) and a row per view
(front, side, top) of the 17 joints (bones to ``skeleton.PARENTS``) and the
toes: an onion skin of a few frames coloured from blue (first) to red (last);
seen from the top, the first and last frames and the hips' path. With them:
the toes' paths over every frame (grey), the frames a toe is planted (within
2 cm of the floor: green, so a sliding foot leaves a green streak) or sunk
(more than 1 cm below it: red), the floor (brown line, the ground under it
shaded, ticks every 0.5 m; a 0.5 m grid seen from the top), the bound curves
(magenta) and the bound joint as played (purple), and the key pose (black)
beside the take's pose on the key frame. Two charts over the shot's time
follow: the toes' heights above the floor (floating, sinking, lifts) and the
worst joint acceleration per frame (pops). A shot with several takes ends
with a column of every take's last frame, a colour each. The takes of a shot
share one scale and centre, so they compare at a glance. Labels are drawn
with Blender's ``blf`` into the saved image.
"""

from dataclasses import dataclass, field

import bpy  # first: Blender's blf and imbuf modules come with it
import blf
import imbuf
import numpy as np

from model_runtime.animation_quality import PLANTED_BAND_M, accelerations
from model_runtime.skeleton import JOINT_INDEX, PARENTS, facing

PANEL = (200, 240)  # width, height in pixels of one view
GAP, HEADER, LABEL, MARGIN = 10, 90, 20, 8  # pixels between panels, for the title, a caption, around a figure
VIEWS = ("front", "side", "top")
CHART = 90  # height in pixels of a chart over time
# Charts over time: name, lowest and highest value shown (clipped), grid lines.
CHARTS = (("toe height (-10 to 30 cm)", -0.1, 0.3, (0.0,)), ("acceleration (0 to 600 m/s^2)", 0.0, 600.0,
                                                             (100.0, 200.0, 300.0, 400.0, 500.0)))
ONION = 6  # frames drawn per take
WALK_TOP, WALK_SIDE = (520, 520), (520, 300)  # pixels of the walk figure's top and side views
STRIDE_S, STRIDE_STEP_S = 1.2, 0.2  # the walk figure's side view: how long, how often
SUNK_M = 0.01  # a toe this far below the floor is marked as sunk
BACKGROUND, CHART_BACKGROUND, CHART_BAND = (1.0, 1.0, 1.0), (0.97, 0.97, 0.97), (0.85, 0.95, 0.85)
GROUND, FLOOR_LINE, GRID = (0.93, 0.89, 0.82), (0.55, 0.4, 0.25), (0.88, 0.88, 0.88)
TOE_PATH, PLANTED, SUNK = (0.6, 0.6, 0.6), (0.1, 0.7, 0.2), (0.9, 0.1, 0.1)
CURVE, BOUND_PATH, KEY = (0.9, 0.2, 0.8), (0.45, 0.1, 0.55), (0.0, 0.0, 0.0)
RIGHT_TOE, LEFT_TOE, ACCELERATION = (0.15, 0.15, 0.15), (0.3, 0.55, 0.95), (0.75, 0.15, 0.1)
EARLY, LATE = np.array([0.2, 0.45, 0.9]), np.array([0.85, 0.2, 0.15])
TAKES = np.array([(0.12, 0.47, 0.71), (1.0, 0.5, 0.05), (0.17, 0.63, 0.17), (0.84, 0.15, 0.16), (0.58, 0.4, 0.74),
                  (0.55, 0.34, 0.29), (0.89, 0.47, 0.76), (0.5, 0.5, 0.5)])
LEGEND = (f"Front and side views: {ONION} frames from the first (blue, thin) to the last (red). Top view: the first,",
          "the last and the hips' path. Grey: toe paths. Green: toe planted (within "
          f"{100 * PLANTED_BAND_M:.0f} cm of the floor). Red: toe over {100 * SUNK_M:.0f} cm under it.",
          "Magenta: curve; purple: its joint as played; black: the key pose. Floor ticks and grid: 0.5 m.",
          "Charts over the shot: toe heights (right black, left blue; green band: planted); worst joint acceleration.")
BONES = np.array([(joint, parent) for joint, parent in enumerate(PARENTS) if parent >= 0])
FEET = [JOINT_INDEX["RFoot"], JOINT_INDEX["LFoot"]]


@dataclass
class Shot:
    """What was played and what was asked for, in world space (metres, Z up)."""

    joints: np.ndarray  # (V, F, 17, 3) per take
    toes: np.ndarray  # (V, F, 2, 3) right, left
    floor: float
    fps: float
    curves: dict = field(default_factory=dict)  # joint name -> polyline (P, 3) it was bound to
    key: tuple = None  # the keyed pose: joints (17, 3), toes (2, 3)
    key_index: int = None  # the frame (index into F) it was keyed on


class Canvas:
    """An RGB image (H, W, 3), row 0 at the top, drawn on with alpha-blended discs."""

    def __init__(self, width, height):
        self.pixels = np.empty((height, width, 3), np.float32)
        self.pixels[:] = BACKGROUND

    def dots(self, points, colour, radius=1.0, alpha=1.0):
        """Discs of ``radius`` pixels at points (N, 2) (x right, y down)."""
        reach = int(np.ceil(radius))
        grid = np.mgrid[-reach:reach + 1, -reach:reach + 1].reshape(2, -1).T
        disc = grid[(grid ** 2).sum(1) <= radius ** 2 + 0.25]
        cells = (np.round(points)[:, None, :].astype(int) + disc[None]).reshape(-1, 2)
        height, width = self.pixels.shape[:2]
        cells = cells[(cells[:, 0] >= 0) & (cells[:, 0] < width) & (cells[:, 1] >= 0) & (cells[:, 1] < height)]
        x, y = cells[:, 0], cells[:, 1]
        self.pixels[y, x] = (1.0 - alpha) * self.pixels[y, x] + alpha * np.asarray(colour, np.float32)

    def lines(self, starts, ends, colour, width=2.0, alpha=1.0):
        """Segments from starts (N, 2) to ends (N, 2), sampled every half pixel."""
        if not len(starts):
            return
        count = int(np.ceil(2.0 * np.linalg.norm(ends - starts, axis=-1).max())) + 2
        share = np.linspace(0.0, 1.0, count)[None, :, None]
        self.dots((starts[:, None] + share * (ends - starts)[:, None]).reshape(-1, 2), colour, width / 2.0, alpha)

    def path(self, points, colour, width=1.0, alpha=1.0):
        """A polyline through points (N, 2)."""
        self.lines(points[:-1], points[1:], colour, width, alpha)

    def fill(self, left, top, right, bottom, colour):
        """A rectangle of pixels, clipped at the image's top left."""
        self.pixels[max(top, 0):max(bottom, 0), max(left, 0):max(right, 0)] = colour


class View:
    """An orthographic view of a panel: world points (..., 3) -> pixels (..., 2)."""

    def __init__(self, axes, centre, scale, corner, size=PANEL):
        self.axes, self.centre, self.scale, self.corner = axes, centre, scale, np.asarray(corner, float)
        self.size = np.asarray(size, float)  # width, height in pixels

    def __call__(self, points):
        return self.flat(points @ self.axes.T)

    def flat(self, points):
        """Pixels (..., 2) of points (..., 2) given in the view's own axes (metres)."""
        return self.corner + self.size / 2.0 + self.scale * (points - self.centre) * [1.0, -1.0]

    def marks(self, axis, step=0.5):
        """Coordinates (N,) along the view's ``axis`` of multiples of ``step`` metres in the panel."""
        half = 0.5 * self.size[axis] / self.scale
        return np.arange(np.ceil((self.centre[axis] - half) / step), (self.centre[axis] + half) / step) * step


def _views(forward):
    """Axes (2, 3) of the VIEWS: front (the body's left to the right), side (forward to the right)
    and top (forward up, the body's right to the right)."""
    left = np.cross([0.0, 0.0, 1.0], forward)
    up = np.array([0.0, 0.0, 1.0])
    return dict(zip(VIEWS, (np.array([left, up]), np.array([forward, up]), np.array([-left, forward]))))


def _layout(shot, axes, size=PANEL):
    """Per view the centre (2,), and one scale (pixels per metre) fitting everything the shot draws
    into panels of ``size`` pixels."""
    points = [shot.joints.reshape(-1, 3), shot.toes.reshape(-1, 3), *shot.curves.values()]
    points = np.concatenate(points)
    points = np.concatenate([points, points * [1.0, 1.0, 0.0] + [0.0, 0.0, shot.floor]])  # the floor under it
    centres, scale = {}, np.inf
    for name, view_axes in axes.items():
        flat = points @ view_axes.T
        low, high = flat.min(0), flat.max(0)
        centres[name] = (low + high) / 2.0
        scale = min(scale, *((np.array(size) - 2 * MARGIN) / np.maximum(high - low, 0.3)))
    return centres, scale


def _floor(canvas, view, name, shot):
    """The ground with ticks every 0.5 m (front and side views) or a 0.5 m grid (top view)."""
    x0, y0 = view.corner.astype(int)
    x1, y1 = (view.corner + view.size).astype(int)
    half = 0.5 * view.size / view.scale
    if name == "top":
        for axis in range(2):
            marks = view.marks(axis)
            ends = np.zeros((len(marks), 2, 2))
            ends[..., axis] = marks[:, None]
            ends[..., 1 - axis] = view.centre[1 - axis] + np.array([-1.0, 1.0]) * half[1 - axis]
            pixels = view.flat(ends)
            canvas.lines(pixels[:, 0], pixels[:, 1], GRID, 1.0)
        return
    level = int(round(view(np.array([0.0, 0.0, shot.floor]))[1]))
    canvas.fill(x0, max(level, y0), x1, y1, GROUND)
    if y0 <= level < y1:
        canvas.lines(np.array([[x0, level]]), np.array([[x1 - 1, level]]), FLOOR_LINE, 2.0)
        ticks = view.flat(np.column_stack([view.marks(0), np.zeros(len(view.marks(0)))]))[:, 0]
        canvas.lines(np.column_stack([ticks, np.full_like(ticks, level)]),
                     np.column_stack([ticks, np.full_like(ticks, level + 5)]), FLOOR_LINE, 1.0)


def _figure(canvas, view, joints, toes, colour, width=2.0, alpha=1.0):
    """One pose: joints (17, 3) and toes (2, 3)."""
    canvas.lines(view(joints[BONES[:, 1]]), view(joints[BONES[:, 0]]), colour, width, alpha)
    canvas.lines(view(joints[FEET]), view(toes), colour, width, alpha)


def _feet(canvas, view, toes, floor):
    """Toe paths (F, 2, 3) over every frame, planted and sunk frames marked."""
    for foot in range(toes.shape[1]):
        canvas.path(view(toes[:, foot]), TOE_PATH, 1.0)
    height = toes[..., 2] - floor
    canvas.dots(view(toes[height < PLANTED_BAND_M]), PLANTED, 1.5)
    canvas.dots(view(toes[height < -SUNK_M]), SUNK, 1.5)


def _take(canvas, views, shot, take):
    """One take's column of views: onion skin, feet, curves and key pose."""
    joints, toes = shot.joints[take], shot.toes[take]
    frames = np.linspace(0, len(joints) - 1, ONION).round().astype(int)
    if shot.key_index is not None:
        frames[1 + np.argmin(np.abs(frames[1:] - shot.key_index))] = shot.key_index
    for name, view in views.items():
        _floor(canvas, view, name, shot)
        _feet(canvas, view, toes, shot.floor)
        for joint, points in shot.curves.items():
            canvas.path(view(points), CURVE, 3.0)
            canvas.path(view(joints[:, JOINT_INDEX[joint]]), BOUND_PATH, 1.0)
        if name == "top":
            canvas.path(view(joints[:, JOINT_INDEX["Hip"]]), EARLY, 1.0)
        shown = frames[[0, -1]] if name == "top" else frames
        for order, frame in enumerate(shown):
            share = order / (len(shown) - 1)
            _figure(canvas, view, joints[frame], toes[frame], (1 - share) * EARLY + share * LATE,
                    2.0 if order else 1.0, 0.85)
        if shot.key is not None:
            _figure(canvas, view, *shot.key, KEY, 1.0)


def _overlay(canvas, views, shot):
    """Every take's last frame and toe paths, a colour per take."""
    for name, view in views.items():
        _floor(canvas, view, name, shot)
        for joint, points in shot.curves.items():
            canvas.path(view(points), CURVE, 3.0)
        for take, (joints, toes) in enumerate(zip(shot.joints, shot.toes)):
            colour = TAKES[take % len(TAKES)]
            for foot in range(toes.shape[1]):
                canvas.path(view(toes[:, foot]), colour, 1.0, 0.6)
            _figure(canvas, view, joints[-1], toes[-1], colour, 2.0, 0.9)


def _chart(canvas, corner, chart, series):
    """Series [(values (N,), colour)] over the shot's time, left to right, in a PANEL[0] x CHART
    panel at ``corner`` showing one of CHARTS."""
    _, low, high, grid = chart
    x0, y0 = corner

    def pixels(values):
        height = (high - np.clip(values, low, high)) / (high - low)
        return np.column_stack([x0 + np.linspace(0.0, PANEL[0] - 1, len(values)), y0 + (CHART - 1) * height])

    canvas.fill(x0, y0, x0 + PANEL[0], y0 + CHART, CHART_BACKGROUND)
    if low < 0.0:  # heights: the planted band on the floor line
        top, floor = (int(round(pixels(np.array([value]))[0, 1])) for value in (PLANTED_BAND_M, 0.0))
        canvas.fill(x0, top, x0 + PANEL[0], floor, CHART_BAND)
    for value in grid:
        line = pixels(np.array([value, value]))
        canvas.lines(line[:1], line[1:], FLOOR_LINE if low < 0.0 else GRID, 1.0)
    for values, colour in series:
        canvas.path(pixels(values), colour, 1.5)


def _charts(canvas, corners, shot, take):
    """A take's toe heights and worst joint accelerations over time, or every take's (lower toe)."""
    heights = shot.toes[..., 2] - shot.floor  # (V, F, 2)
    if take is None:
        series = ([(height.min(axis=1), TAKES[k % len(TAKES)]) for k, height in enumerate(heights)],
                  [(accelerations(joints, shot.fps), TAKES[k % len(TAKES)]) for k, joints in enumerate(shot.joints)])
    else:
        series = ([(heights[take, :, 0], RIGHT_TOE), (heights[take, :, 1], LEFT_TOE)],
                  [(accelerations(shot.joints[take], shot.fps), ACCELERATION)])
    for corner, chart, lines in zip(corners, CHARTS, series):
        _chart(canvas, corner, chart, lines)


def save(path, title, shots):
    """Draw ``shots`` [(label, Shot)] side by side, a column per take (then one of every take's
    last frame where a shot has several), a row per view and per chart, and save it as a PNG at
    ``path``."""
    columns = []  # (caption, shot, take or None for every take's last frame)
    for label, shot in shots:
        takes = len(shot.joints)
        columns += [(f"{label} {take + 1}" if takes > 1 else label, shot, take) for take in range(takes)]
        columns += [("every take, last frame", shot, None)] if takes > 1 else []
    rows = [(name, PANEL[1]) for name in VIEWS] + [(chart[0], CHART) for chart in CHARTS]
    tops = HEADER + LABEL + np.cumsum([0] + [size + GAP for _, size in rows])
    canvas = Canvas(len(columns) * (PANEL[0] + GAP) + GAP, int(tops[-1]))
    labels = [(GAP, 18, title, 14)] + [(GAP, 36 + 15 * line, text, 11) for line, text in enumerate(LEGEND)]
    labels += [(GAP + 3, top + 13, name, 11) for (name, _), top in zip(rows, tops)]
    layouts = {}
    for column, (caption, shot, take) in enumerate(columns):
        if id(shot) not in layouts:
            axes = _views(facing(shot.joints[0, 0]))
            layouts[id(shot)] = (axes, *_layout(shot, axes))
        axes, centres, scale = layouts[id(shot)]
        left = GAP + column * (PANEL[0] + GAP)
        views = {name: View(axes[name], centres[name], scale, (left, top)) for name, top in zip(VIEWS, tops)}
        if take is None:
            _overlay(canvas, views, shot)
        else:
            _take(canvas, views, shot, take)
        _charts(canvas, [(left, top) for top in tops[len(VIEWS):-1]], shot, take)
        labels.append((left, HEADER + LABEL - 6, caption, 12))
    _write(path, canvas.pixels, labels)


def walk(path, title, shot, take=0):
    """One take of a walk at a glance, saved as a PNG at ``path``: seen from the top, the path
    (magenta), the hips' path (blue) and a footprint on every frame a toe is planted (right black,
    left blue); beside it, seen from the side at mid-shot, the body every ``STRIDE_STEP_S`` over
    ``STRIDE_S``, from blue to red."""
    joints, toes = shot.joints[take], shot.toes[take]
    middle = len(joints) // 2
    frames = middle + np.round(np.arange(0.0, STRIDE_S, STRIDE_STEP_S) * shot.fps).astype(int)
    frames = frames[frames < len(joints)]
    one = Shot(joints[None], toes[None], shot.floor, shot.fps, shot.curves)
    top_axes = {"top": np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])}
    side_axes = {"side": _views(facing(joints[middle]))["side"]}
    strobe = Shot(joints[None, frames], toes[None, frames], shot.floor, shot.fps)
    (top_centre, top_scale), (side_centre, side_scale) = ((centres[name], scale) for name, (centres, scale) in
                                                          (("top", _layout(one, top_axes, WALK_TOP)),
                                                           ("side", _layout(strobe, side_axes, WALK_SIDE))))
    top = View(top_axes["top"], top_centre, top_scale, (GAP, HEADER), WALK_TOP)
    side = View(side_axes["side"], side_centre, side_scale, (2 * GAP + WALK_TOP[0], HEADER), WALK_SIDE)
    canvas = Canvas(3 * GAP + WALK_TOP[0] + WALK_SIDE[0], HEADER + WALK_TOP[1] + GAP)
    _floor(canvas, top, "top", one)
    _floor(canvas, side, "side", one)
    for points in shot.curves.values():
        canvas.path(top(points), CURVE, 3.0)
    canvas.path(top(joints[:, JOINT_INDEX["Hip"]]), EARLY, 1.0)
    planted = toes[..., 2] - shot.floor < PLANTED_BAND_M
    for foot, colour in enumerate((RIGHT_TOE, LEFT_TOE)):
        canvas.dots(top(toes[planted[:, foot], foot]), colour, 3.0, 0.8)
    for order, frame in enumerate(frames):
        share = order / max(1, len(frames) - 1)
        _figure(canvas, side, joints[frame], toes[frame], (1 - share) * EARLY + share * LATE, 2.0, 0.85)
    legend = (f"Top: the path (magenta), the hips (blue), toes planted (within {100 * PLANTED_BAND_M:.0f} cm "
              "of the floor; right black, left blue); grid 0.5 m.",
              f"Side, at mid-shot: the body every {STRIDE_STEP_S:.1f} s over {STRIDE_S:.1f} s, blue to red.")
    labels = [(GAP, 18, title, 14)] + [(GAP, 38 + 15 * line, text, 11) for line, text in enumerate(legend)]
    _write(path, canvas.pixels, labels)


def _write(path, pixels, labels):
    """Save pixels (H, W, 3) as a PNG through a Blender image, then draw the labels
    [(x, y from the top, text, size)] into it."""
    path.parent.mkdir(parents=True, exist_ok=True)
    height, width = pixels.shape[:2]
    image = bpy.data.images.new(path.stem, width, height, alpha=True)
    rgba = np.ones((height, width, 4), np.float32)
    rgba[..., :3] = pixels[::-1]  # Blender's rows start at the bottom
    image.pixels.foreach_set(rgba.ravel())
    image.filepath_raw, image.file_format = str(path), 'PNG'
    image.save()
    bpy.data.images.remove(image)
    buffer = imbuf.load(str(path))
    with blf.bind_imbuf(0, buffer):
        blf.color(0, 0.0, 0.0, 0.0, 1.0)
        for x, y, text, size in labels:
            blf.size(0, size)
            blf.position(0, x, height - y, 0)
            blf.draw_buffer(0, text)
    imbuf.write(buffer, filepath=str(path))
    buffer.free()
