"""Benchmark: is the generated motion usable, as an animator sees it? (issue 15)

On the mannequin and a generated Rigify rig (scene at 30 fps, 5 variants per
shot) it generates nine shots: idle from the rest pose, a hand reach, a foot's
step (the right foot drawn 0.6 of its leg forward over 60 frames), blocking
keys (rest pose at frame 1, a crouch with both arms up at 45), 300 frames
of a slow hand wave, and walks along paths on the floor bound to the hips
(4 m gently curved over 120 frames, a quarter circle of radius 2.5 m over
120, 10 m over 300, and a run: 10 m over 120; issue 17). Each is measured as Blender plays it (``frame_set`` on
every frame) with the figures of ../shared/notes/quality-measures.md, beside
real capture of ../shared/mocap imported with Blender's own BVH importer and
measured the same way. Prints one table per rig and writes contact sheets
(see contact_sheet.py): out/quality_<rig>_<shot>.png and out/quality_capture.png, and the
README's picture of a walk, docs/walk.png (footprints from the top, a stride from the side).
With ``--seeds N`` it prints instead, for each shot but the walks over seeds 0..N-1, the worst
lean, acceleration and balance, the spread and a curve's worst frame: one seed's figures say
little of one set of weights against another. ``--weights DIR`` generates with the weights
folder DIR (as ``python -m model_runtime.train --out DIR`` writes it) instead of the bundled ones,
and leaves docs/walk.png as it is.
"""

import csv
import math
import sys
import time
from pathlib import Path

import bpy
import numpy as np
from mathutils import Matrix

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT), str(ROOT / "tests"), str(ROOT / "benchmarks")]

import blender_rigs  # noqa: E402
import contact_sheet  # noqa: E402
from shots import SHOTS, WALKS  # noqa: E402
import trajevae_addon  # noqa: E402
from model_runtime import animation_quality as quality  # noqa: E402
from model_runtime import generation, realism  # noqa: E402
from model_runtime.data import clips  # noqa: E402
from model_runtime.model import ModelConfig  # noqa: E402
from model_runtime.skeleton import JOINT_INDEX  # noqa: E402
from trajevae_addon import api  # noqa: E402

J = JOINT_INDEX
FPS = 30
VARIANTS = 5
SEED = 0
MOCAP = ROOT.parent / "shared" / "mocap"
OUT = ROOT / "out"
WALK_FIGURE = ("rigify", "quarter turn")  # the README's picture of a walk: docs/walk.png
CAPTURE = ("Female1_B03_Walk1", "02_01", "Female1_A07_Crouch", "Female1_A05_PickUpBox")  # MANIFEST file stems
NOTES = """
planted: mean horizontal speed of toes within 2 cm of the floor (the lower toe at the start frame). float, sink: the
lower toe's highest height above and deepest depth below it. air: frames with both toes over 3 cm up. acc: worst
joint acceleration; spike: worst frame over median frame. steps: per foot, right/left. lean: hips to neck base from
vertical. roll: the hip line's tilt from horizontal. swing: the wrists' swing front to back (5th-95th percentile
from the shoulder). knee-in: knee pointing inward of forward. balance: the centre of mass outside the soles where
both feet bear weight (toes within 5 cm of the floor). held-up: frames with a toe over 5 cm up for 0.6 s or more
(a foot left hovering; a walk's swing lasts 0.3-0.5 s). off-limit: frames outside the joint-angle limits
fitted on the training data. spread: mean pairwise joint distance of the variants. curve: the bound joint to where
its curve puts it, mean / worst frame. path: the hips' farthest from a ground path; facing: worst angle of the
body's facing from the path's tangent; hip h: the hips' lowest height over their standing height; seam: the worst
acceleration within 2 frames of where model windows meet over the worst elsewhere / the same of the means. key:
worst keyed joint at the key frame / the head top, which the keyed rotation of the head bone places. Over variants:
float, sink, acc, spike, lean, roll, knee-in, balance, held-up and key are the worst, the rest means.
Capture, levelled: the clip with its capture floor levelled as the training data loader levels it; the tilt is
how far that moved points up or down over the clip."""




def _reset(rig):
    """The rig as built: no variants, no action, no bindings, the rest pose."""
    api.restore_original(rig)
    for binding in list(rig.trajevae.bindings):
        api.unbind(rig, binding.bone)
    if rig.animation_data and rig.animation_data.action:
        bpy.data.actions.remove(rig.animation_data.action)
    for pose_bone in rig.pose.bones:
        pose_bone.matrix_basis = Matrix.Identity(4)
    for obj in [obj for obj in bpy.data.objects if obj.type == 'CURVE']:
        bpy.data.objects.remove(obj)


def run_shot(rig, scene, frames, setup, seed=None):
    """Set a shot up, generate the variants (``seed``, SEED unless given) and play them: a
    contact_sheet.Shot and the keys' error per joint on the key frame ((17,) m, the worst
    variant's; None without keys)."""
    _reset(rig)
    scene.frame_start, scene.frame_end = 1, frames
    curves, key_frame = setup(rig)
    bones = api.map_rig(rig)
    for joint, points in curves.items():
        api.bind_curve(rig, bones[joint], blender_rigs.curve(scene, joint, points))
    asked, asked_toes = blender_rigs.played(rig, [1] + ([key_frame] if key_frame else []))  # the start and the key
    played = []
    for action in api.generate_variants(rig, VARIANTS, SEED if seed is None else seed):
        api.set_active_variant(rig, action)
        played.append(blender_rigs.played(rig, range(1, frames + 1)))
    joints, toes = (np.array(part) for part in zip(*played))
    floor = quality.floor_height(asked_toes)
    if not key_frame:
        return contact_sheet.Shot(joints, toes, floor, FPS, curves), None
    error = np.linalg.norm(joints[:, key_frame - 1] - asked[1], axis=-1).max(axis=0)
    return contact_sheet.Shot(joints, toes, floor, FPS, curves, (asked[1], asked_toes[1]), key_frame - 1), error


def capture(stem):
    """A clip of ../shared/mocap as Blender's BVH importer plays it at 30 fps, in the unit and
    without the converter's added frames the training data loader finds: (contact_sheet.Shot of
    one take, the same on the floor levelled as the loader levels it, how far levelling moved
    points up or down (m): the capture floor's tilt over the clip)."""
    with open(MOCAP / "MANIFEST.csv") as manifest:
        row = next(row for row in csv.DictReader(manifest) if Path(row["file"]).stem == stem)
    path = MOCAP / row["file"]
    clip = clips.load_clip(path)
    scene = blender_rigs.fresh_scene()
    scene.render.fps, scene.render.fps_base = FPS, 1.0
    bpy.ops.import_anim.bvh(filepath=str(path), global_scale=clips.LENGTH_UNITS[clip.unit], use_fps_scale=True)
    rig = bpy.context.object
    first = 1 + math.ceil((int(row["frames"]) - clip.source_frames) * FPS / float(row["fps"]))
    last = math.floor(rig.animation_data.action.frame_range[1] + 0.01)
    joints, toes = blender_rigs.played(rig, range(first, last + 1))
    points = np.concatenate([joints, toes], axis=1)  # (F, 19, 3)
    level, _ = clips._put_on_floor(points, toes[..., 2])
    as_imported = contact_sheet.Shot(joints[None], toes[None], quality.floor_height(toes), FPS)
    levelled = contact_sheet.Shot(level[None, :, :17], level[None, :, 17:], quality.floor_height(level[:, 17:]),
                                  FPS)
    return as_imported, levelled, float(np.ptp(level[..., 2] - points[..., 2]))


def motion_figures(shot):
    """The numbers behind the table's acc, spike, lean, balance (cm), held-up and spread columns, worst over
    the takes (spread: nan for one take); ``--seeds`` averages them unrounded."""
    pops = [quality.pops(joints, FPS) for joints in shot.joints]
    off = [np.nanmax(quality.off_balance(joints, toes, shot.floor), initial=0.0)
           for joints, toes in zip(shot.joints, shot.toes)]
    return {"acc m/s2": max(worst for worst, _ in pops), "spike x": max(spike for _, spike in pops),
            "lean deg": float(quality.lean_degrees(shot.joints.reshape(-1, 17, 3)).max()),
            "balance cm": 100 * max(off),
            "held-up %": 100 * max(quality.held_up(toes, shot.floor, FPS) for toes in shot.toes),
            "spread m": quality.spread(shot.joints) if len(shot.joints) > 1 else float("nan")}


def figures(shot, limits, error=None):
    """The table's figures for a shot's takes, worst or mean over them as each column says."""
    takes = list(zip(shot.joints, shot.toes))
    per_take = [(quality.planted_toe_speed(toes, FPS, shot.floor), *quality.floating(toes, shot.floor),
                 quality.steps(toes, shot.floor)) for joints, toes in takes]
    planted, high, airborne, sink, steps = zip(*per_take)
    motion = motion_figures(shot)
    return {"planted m/s": f"{np.mean(planted):.2f}", "float cm": f"{100 * max(high):.1f}",
            "air %": f"{100 * np.mean(airborne):.0f}", "sink cm": f"{100 * max(sink):.1f}",
            "acc m/s2": f"{motion['acc m/s2']:.0f}", "spike x": f"{motion['spike x']:.0f}",
            "steps R/L": "/".join(f"{n:.1f}".rstrip("0").rstrip(".") for n in np.mean(steps, axis=0)),
            "lean deg": f"{motion['lean deg']:.0f}",
            "roll deg": f"{quality.roll_degrees(shot.joints.reshape(-1, 17, 3)).max():.0f}",
            "swing m": f"{np.mean([quality.arm_swing(joints) for joints in shot.joints]):.2f}",
            "knee-in deg": f"{quality.knee_inward_degrees(shot.joints.reshape(-1, 17, 3)).max():.0f}",
            "balance cm": f"{motion['balance cm']:.0f}",
            "held-up %": f"{motion['held-up %']:.0f}",
            "off-limit %": f"{100 * realism.share_outside_limits(shot.joints, limits):.0f}",
            "spread m": "-" if np.isnan(motion["spread m"]) else f"{motion['spread m']:.2f}",
            "curve cm": "{:.1f} / {:.1f}".format(*(100 * curve_error(shot))) if set(shot.curves) - {"Hip"} else "-",
            "key cm": "-" if error is None else
            f"{100 * np.delete(error, J['Head']).max():.1f} / {100 * error[J['Head']]:.1f}",
            **walk_figures(shot)}


def walk_figures(shot):
    """For a walk along a ground path (a Hip curve): the hips' farthest from the path, the worst
    facing off the path's tangent and the hips' lowest height over standing, worst over takes."""
    if "Hip" not in shot.curves:
        return {"path cm": "-", "facing deg": "-", "hip h %": "-", "seam x": "-"}
    followed = [quality.path_following(joints, shot.curves["Hip"]) for joints in shot.joints]
    joins = generation.window_joins(shot.joints.shape[1], FPS, ModelConfig().frames)
    seams = np.array([quality.seam(joints, FPS, joins) for joints in shot.joints]) if joins else None
    return {"path cm": f"{100 * max(away for away, _ in followed):.0f}",
            "facing deg": f"{max(angles.max() for _, angles in followed):.0f}",
            "hip h %": f"{100 * min(quality.hip_height_share(joints, shot.floor) for joints in shot.joints):.0f}",
            "seam x": "-" if seams is None else f"{seams[:, 0].max():.1f} / {seams[:, 1].max():.1f}"}


def curve_error(shot):
    """(mean, worst) distance (m) of the bound joints, as played, to where their curves put them on
    each frame (uniform in arc length over the shot), over frames, joints and variants: a mean of
    0.0 cm hid a wave's hand 2 cm off its arc for a few frames (4-5 cm with other seeds). A ground
    path (the hips' curve on the floor) is a walk, measured by ``walk_figures`` instead."""
    frames = shot.joints.shape[1]
    errors = np.array([np.linalg.norm(shot.joints[:, :, J[joint]] - generation.curve_samples(points, frames - 1,
                                                                                             frames - 1), axis=-1)
                       for joint, points in shot.curves.items() if joint != "Hip"])
    return np.array([errors.mean(), errors.max()]) if errors.size else np.full(2, np.nan)


def table(title, rows):
    """Print rows [(label, {column: text})] under a title, columns aligned."""
    columns = list(rows[0][1])
    width = max(len(label) for label, _ in rows)
    sizes = [max(len(column), *(len(row[column]) for _, row in rows)) for column in columns]
    print(f"\n{title}")
    print("  ".join([" " * width] + [column.rjust(size) for column, size in zip(columns, sizes)]))
    for label, row in rows:
        print("  ".join([label.ljust(width)] + [row[column].rjust(size) for column, size in zip(columns, sizes)]))


SEED_COLUMNS = ("lean deg", "acc m/s2", "balance cm", "held-up %", "spread m")


def over_seeds(count):
    """``--seeds N``: over seeds 0..N-1 on each rig, each shot but the walks: the mean and the worst
    seed's lean, acceleration, balance and held-up share (each seed's worst variant), the spread (the least seed's)
    and, where a hand or foot is bound, its worst frame off the curve."""
    for name, build in (("mannequin", blender_rigs.mannequin_rig), ("rigify", blender_rigs.rigify_rig)):
        scene = blender_rigs.fresh_scene()
        scene.render.fps, scene.render.fps_base = FPS, 1.0
        rig = build(scene)
        for label, frames, setup in SHOTS:
            taken = [run_shot(rig, scene, frames, setup, seed)[0] for seed in range(count)]
            lean, acc, balance, held, spread = np.array([[motion_figures(shot)[column] for column in SEED_COLUMNS]
                                                   for shot in taken]).T
            worst = np.array([curve_error(shot)[1] for shot in taken])
            curve = ("" if np.isnan(worst).all() else
                     f"; curve's worst frame {100 * worst.mean():.1f} cm (most {100 * worst.max():.1f})")
            print(f"{name} {label} over seeds 0-{count - 1}: lean {lean.mean():.0f} deg (most {lean.max():.0f}), "
                  f"acc {acc.mean():.0f} m/s2 (most {acc.max():.0f}), balance {balance.mean():.1f} cm "
                  f"(most {balance.max():.1f}), held up {held.mean():.0f} % (most {held.max():.0f}), "
                  f"spread {spread.mean():.3f} m (least {spread.min():.3f}){curve}",
                  flush=True)


def main():
    trajevae_addon.register()
    bundled = "--weights" not in sys.argv
    if not bundled:
        print(f"weights: {api.use_weights(sys.argv[sys.argv.index('--weights') + 1])}")
    if "--seeds" in sys.argv:
        over_seeds(int(sys.argv[sys.argv.index("--seeds") + 1]))
        return
    clock = time.perf_counter()
    limits = realism.load_angle_limits()
    captured, capture_rows = [], []
    for stem in CAPTURE:
        as_imported, levelled, tilt = capture(stem)
        name = stem.replace("Female1_", "ACCAD ").replace("02_01", "CMU 02_01")
        capture_rows.append((f"capture {name}", figures(as_imported, limits)))
        if tilt > 0.005:  # the capture floor was tilted: the same clip on the floor levelled
            capture_rows.append((f"  levelled ({100 * tilt:.0f} cm tilt)", figures(levelled, limits)))
            name += ", levelled"
        captured.append((name, levelled))
    contact_sheet.save(OUT / "quality_capture.png", f"Capture, as Blender's BVH importer plays it at {FPS} fps "
                       "(walk floors levelled)", captured)
    seconds = {"capture": time.perf_counter() - clock}
    tables = []
    for name, build in (("mannequin", blender_rigs.mannequin_rig), ("rigify", blender_rigs.rigify_rig)):
        started = time.perf_counter()
        scene = blender_rigs.fresh_scene()
        scene.render.fps, scene.render.fps_base = FPS, 1.0
        rig = build(scene)
        rows = []
        for label, frames, setup in SHOTS + WALKS:
            shot, error = run_shot(rig, scene, frames, setup)
            rows.append((f"{label} ({frames} f)", figures(shot, limits, error)))
            contact_sheet.save(OUT / f"quality_{name}_{label}.png", f"{name}, {label}: {frames} frames at {FPS} fps, "
                               f"{VARIANTS} variants (seed {SEED}) as played", [("variant", shot)])
            if (name, label) == WALK_FIGURE and bundled:  # the picture is of the bundled weights
                contact_sheet.walk(ROOT / "docs" / "walk.png", f"A path drawn on the floor and bound to the {name} "
                                   f"rig's root: {label}, {frames} frames at {FPS} fps, variant 1", shot)
            print(f"{name} {label}: done at {time.perf_counter() - clock:.0f} s", flush=True)
        tables.append((f"{name}: {VARIANTS} variants per shot as played, beside capture", rows + capture_rows))
        seconds[name] = time.perf_counter() - started
    for title, rows in tables:
        table(title, rows)
    print(NOTES)
    print("seconds: " + ", ".join(f"{part} {value:.0f}" for part, value in seconds.items())
          + f"; total {time.perf_counter() - clock:.0f}")


if __name__ == "__main__":
    main()
