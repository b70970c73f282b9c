"""Batch example for the scripting API: open a .blend, bind curves, generate variants, save.

    .venv/bin/python examples/batch_generate.py scene.blend --armature Armature \
        --bind hand.L=HandPath --bind foot.R=StepPath --variants 5 --out scene_variants.blend

Without --bind, the variants are diverse motions from the rig's pose at the
start frame. The frame range is the scene's.
"""

import argparse
import sys
from pathlib import Path

import bpy

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import trajevae_addon  # noqa: E402
from trajevae_addon import api  # noqa: E402


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("blend")
    parser.add_argument("--armature", required=True)
    parser.add_argument("--bind", action="append", default=[], metavar="BONE=CURVE")
    parser.add_argument("--variants", type=int, default=5)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--out", required=True)
    args = parser.parse_args()

    bpy.ops.wm.open_mainfile(filepath=args.blend)
    trajevae_addon.register()
    rig = bpy.data.objects[args.armature]
    print("mapping:", {joint: bone for joint, bone in api.map_rig(rig).items() if bone})
    for pair in args.bind:
        bone, curve = pair.split("=", 1)
        api.bind_curve(rig, bone, bpy.data.objects[curve])
    for action in api.generate_variants(rig, n=args.variants, seed=args.seed):
        print("variant:", action.name)
    bpy.ops.wm.save_as_mainfile(filepath=str(Path(args.out).resolve()))
    print("saved", args.out)


if __name__ == "__main__":
    main()
