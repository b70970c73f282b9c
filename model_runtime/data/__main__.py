"""``python -m model_runtime.data stats PATH... [--json]``: what the loader makes of BVH files."""

import argparse
import json
import sys

import numpy as np

from ..skeleton import indices
from .dataset import load_clips


def clip_stats(clip):
    return {
        "file": clip.file,
        "frames": clip.frames,
        "seconds": round(clip.seconds, 3),
        "fps": clip.fps,
        "height_m": round(clip.height_m, 3),
        "min_foot_height_m": round(float(clip.positions[:, indices(("RFoot", "LFoot")), 2].min()), 3),
        "profile": clip.profile,
    }


def main(argv=None):
    parser = argparse.ArgumentParser(prog="python -m model_runtime.data")
    commands = parser.add_subparsers(dest="command", required=True)
    stats = commands.add_parser("stats", help="per-clip and total figures for BVH files or folders")
    stats.add_argument("paths", nargs="+", help="BVH files or folders (searched recursively)")
    stats.add_argument("--json", action="store_true", help="print JSON instead of a table")
    args = parser.parse_args(argv)

    loaded, errors = load_clips(args.paths)
    for error in errors:
        print(f"error: {error}", file=sys.stderr)
    rows = [clip_stats(clip) for clip in loaded]
    total = round(sum(row["seconds"] for row in rows), 3)
    if args.json:
        print(json.dumps({"clips": rows, "total_seconds": total}, indent=1))
    else:
        print(f"{'frames':>7} {'seconds':>8} {'fps':>4} {'height_m':>8} {'min_foot_m':>10}  {'profile':<18} file")
        for row in rows:
            print(f"{row['frames']:>7} {row['seconds']:>8.2f} {row['fps']:>4} {row['height_m']:>8.3f} "
                  f"{row['min_foot_height_m']:>10.3f}  {row['profile']:<18} {row['file']}")
        heights = [row["height_m"] for row in rows] or [np.nan]
        print(f"{len(rows)} clips, {sum(r['frames'] for r in rows)} frames, {total:.1f} s "
              f"({total / 60:.1f} min), heights {min(heights):.2f}-{max(heights):.2f} m, {len(errors)} errors")
    return 1 if errors and not rows else 0


if __name__ == "__main__":
    sys.exit(main())
