"""The demo: a mannequin, a drawn hand curve, five motion variants; a .blend and a side-by-side image.

Run headless from the repository root (``make demo``)::

    .venv/bin/python scripts/demo.py [--out DIR] [--variants 5] [--seed 0]

It builds a fresh 3 s scene at 30 fps, adds the mannequin and a reaching arc
for its right hand starting at the wrist, binds the curve to the hand bone,
generates the variants and saves OUT/demo.blend (open it and cycle the
variants in the TrajeVAE sidebar). Then, in the same session but without
saving again, it lays the variants out side by side (each as a strobe of
three poses, each beside its own copy of the curve) and renders OUT/demo.png
with Cycles on the CPU.
"""

import argparse
import sys
import time
from pathlib import Path

import bpy
import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import trajevae_addon  # noqa: E402
from trajevae_addon import api, pipeline, rig_state  # noqa: E402
from trajevae_addon.runtime import skeleton  # noqa: E402

FPS, FIRST, LAST = 30, 1, 90
SPACING = 1.2  # metres between the figures in the image
VIEW = np.array([-0.5, -1.0, 0.22])  # toward the camera: in front of the figures, on their right, a little above
STROBE = ((1, 0.18), (45, 0.4), (90, 1.0))  # (frame, opacity) of each pose shown per figure
COLOURS = ((0.80, 0.25, 0.20), (0.90, 0.60, 0.15), (0.30, 0.65, 0.30), (0.20, 0.45, 0.85), (0.60, 0.30, 0.75))


def arguments():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=ROOT / "out", help="output folder (default: out/)")
    parser.add_argument("--variants", type=int, default=5, help="how many variants (default: 5)")
    parser.add_argument("--seed", type=int, default=0, help="random seed (default: 0)")
    return parser.parse_args()


def material(name, colour, alpha=1.0, emission=0.0):
    mat = bpy.data.materials.new(name)
    bsdf = mat.node_tree.nodes["Principled BSDF"]
    bsdf.inputs["Base Color"].default_value = (*colour, 1.0)
    bsdf.inputs["Roughness"].default_value = 0.6
    bsdf.inputs["Alpha"].default_value = alpha
    if emission:
        bsdf.inputs["Emission Color"].default_value = (*colour, 1.0)
        bsdf.inputs["Emission Strength"].default_value = emission
    mat.diffuse_color = (*colour, alpha)  # the viewport colour
    return mat


def hand_arc(start, samples=40):
    """A reach forward (-Y) and up from the wrist, with a small outward swing and a wave: about 55 cm long."""
    t = np.linspace(0.0, 1.0, samples)[:, None]
    ease = 0.5 - 0.5 * np.cos(np.pi * t)  # starts and ends gently
    offset = np.hstack([-0.08 * np.sin(np.pi * t),  # out to the right (-X) and back
                        -0.30 * ease,  # forward
                        0.35 * np.sin(0.5 * np.pi * ease) + 0.03 * np.sin(3 * np.pi * t)])  # up, with a wave
    return start + offset


def add_curve(scene, name, points, mat):
    """A visible poly Curve object through world points (P, 3)."""
    data = bpy.data.curves.new(name, 'CURVE')
    data.dimensions = '3D'
    data.bevel_depth, data.bevel_resolution = 0.012, 2
    spline = data.splines.new('POLY')
    spline.points.add(len(points) - 1)
    spline.points.foreach_set("co", np.column_stack([points, np.ones(len(points))]).ravel())
    data.materials.append(mat)
    obj = bpy.data.objects.new(name, data)
    scene.collection.objects.link(obj)
    return obj


def build_scene(scene):
    scene.render.fps, scene.render.fps_base = FPS, 1.0
    scene.frame_start, scene.frame_end = FIRST, LAST
    scene.frame_set(FIRST)
    rig = trajevae_addon.mannequin.build_mannequin(scene)
    bones = api.map_rig(rig)
    _, joints = rig_state.read(rig, bones, bpy.context.evaluated_depsgraph_get())
    wrist = joints[skeleton.JOINT_INDEX["RWrist"]]
    curve = add_curve(scene, "Right Hand Path", hand_arc(wrist), material("Path", (1.0, 0.45, 0.0), emission=3.0))
    api.bind_curve(rig, bones["RWrist"], curve)
    return rig, curve, wrist


def posed_copy(scene, body, frame, name, location, mat):
    """A static mesh of the evaluated body at ``frame``, moved by ``location``."""
    scene.frame_set(frame)
    evaluated = body.evaluated_get(bpy.context.evaluated_depsgraph_get())
    mesh = bpy.data.meshes.new_from_object(evaluated)
    mesh.transform(body.matrix_world)
    for polygon in mesh.polygons:
        polygon.use_smooth = True
    mesh.materials.clear()
    mesh.materials.append(mat)
    obj = bpy.data.objects.new(name, mesh)
    obj.location = location
    scene.collection.objects.link(obj)
    return obj


def render_side_by_side(scene, rig, curve, variant_actions, path):
    """Replace the scene's contents in memory by a line-up of the variants and render it (not saved)."""
    body = next(child for child in rig.children if child.type == 'MESH')
    row = np.array([-VIEW[1], VIEW[0], 0.0]) / np.hypot(VIEW[0], VIEW[1])  # across the view, on the floor
    for index, action in enumerate(variant_actions):
        api.set_active_variant(rig, action)
        offset = index * SPACING * row
        for frame, alpha in STROBE:
            posed_copy(scene, body, frame, f"Variant {index + 1} f{frame}", offset,
                       material(f"Figure {index + 1} {frame}", COLOURS[index % len(COLOURS)], alpha))
        copy = curve.copy()
        copy.location = offset
        scene.collection.objects.link(copy)
    rig.hide_render = body.hide_render = curve.hide_render = True
    scene.frame_set(LAST)

    width = (len(variant_actions) - 1) * SPACING
    ground = bpy.data.objects.new("Ground", bpy.data.meshes.new("Ground"))
    ground.data.from_pydata([(-20, -20, 0), (20, -20, 0), (20, 20, 0), (-20, 20, 0)], [], [(0, 1, 2, 3)])
    ground.data.materials.append(material("Ground", (0.55, 0.55, 0.55)))
    scene.collection.objects.link(ground)
    sun = bpy.data.objects.new("Sun", bpy.data.lights.new("Sun", 'SUN'))
    sun.data.energy, sun.data.angle = 3.0, np.radians(10.0)
    sun.rotation_euler = (np.radians(40.0), 0.0, np.radians(-30.0))
    scene.collection.objects.link(sun)
    world = bpy.data.worlds.new("World")
    world.node_tree.nodes["Background"].inputs["Color"].default_value = (0.6, 0.65, 0.75, 1.0)
    world.node_tree.nodes["Background"].inputs["Strength"].default_value = 0.6
    scene.world = world

    camera = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    camera.data.type, camera.data.ortho_scale = 'ORTHO', width + 2.0
    target = width / 2.0 * row + np.array([0.0, -0.15, 0.85])
    camera.location = target + 12.0 * VIEW / np.linalg.norm(VIEW)
    camera.rotation_euler = _look_at(camera.location, target)
    scene.collection.objects.link(camera)
    scene.camera = camera

    scene.render.engine = 'CYCLES'
    scene.cycles.device = 'CPU'
    scene.cycles.samples = 16
    scene.cycles.use_denoising = True
    scene.render.threads_mode, scene.render.threads = 'FIXED', 2
    scene.render.resolution_x, scene.render.resolution_y, scene.render.resolution_percentage = 1280, 440, 100
    scene.render.image_settings.file_format = 'PNG'
    scene.render.image_settings.color_mode = 'RGB'
    scene.render.image_settings.compression = 100
    scene.render.dither_intensity = 0.0  # no dither noise: flat areas compress (README image < 400 KB)
    scene.render.filepath = str(path)
    try:
        bpy.ops.render.render(write_still=True)
    except RuntimeError:  # no denoiser in this build
        scene.cycles.use_denoising = False
        bpy.ops.render.render(write_still=True)


def _look_at(location, target):
    from mathutils import Vector
    return (Vector(target) - Vector(location)).to_track_quat('-Z', 'Y').to_euler()


def main():
    args = arguments()
    out = args.out.resolve()
    out.mkdir(parents=True, exist_ok=True)
    clock = time.perf_counter()
    bpy.ops.wm.read_factory_settings(use_empty=True)
    trajevae_addon.register()
    scene = bpy.context.scene
    rig, curve, wrist = build_scene(scene)
    print(f"scene: mannequin, hand curve from the right wrist {np.round(wrist, 3).tolist()} "
          f"({curve.data.splines[0].calc_length():.2f} m), frames {FIRST}-{LAST} at {FPS} fps")

    report = pipeline.generate_variants(rig, args.variants, seed=args.seed)
    stages = ", ".join(f"{stage} {seconds * 1000:.0f} ms" for stage, seconds in report.seconds.items())
    print(f"generated {len(report.actions)} variants (seed {args.seed}): {stages}")
    api.set_active_variant(rig, report.actions[0])
    scene.frame_set(FIRST)

    blend = out / "demo.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(blend))
    image = out / "demo.png"
    render_clock = time.perf_counter()
    render_side_by_side(scene, rig, curve, report.actions, image)
    print(f"rendered with Cycles (CPU) in {time.perf_counter() - render_clock:.1f} s")

    print(f"saved {blend}")
    print(f"image {image}")
    for index, action in enumerate(report.actions, 1):
        print(f"  variant {index}: {action.name}")
    print(f"done in {time.perf_counter() - clock:.1f} s")


if __name__ == "__main__":
    main()
