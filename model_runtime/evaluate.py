"""``python -m model_runtime.evaluate``: TrajeVAE against baselines, as trajectories are added.

For k = 0..4 trajectories in the paper's order (RFoot, LFoot, RWrist, LWrist)
prints per method APD, ADE, FDE, MMADE, MMFDE (DLow protocol, metres),
traj_err (mean distance of the conditioned joints to their trajectories), MPD
(minimum pairwise distance among the K samples) and realism: bone_dev (mean
rigid bone-length deviation from the initial pose, m), angle_out (share of
frames outside the joint-angle limits), skating (horizontal foot speed in
contact, m/s), turn (mean absolute turn about Z from the initial pose to the
last frame, degrees); the ground truth's own realism figures are printed beside.
``--json`` writes {"methods": {method: {"k": {"0": {metric: value}, ...}}},
"ground_truth": {...}, "windows": n, "samples": K, "seconds": s}.
By default the windows come from the validation subjects; ``--data`` takes
any BVH files or folders. The nearest-neighbour baseline searches the
training subjects' windows. "trajevae" draws plain prior samples (with
curves, the most plausible of a doubled pool), the paper's way;
"trajevae_posterior" decodes the posterior mean, which sees the future (an
oracle: what the latents can carry, the bound prior samples approach); "sampler" is
what the add-on ships for every generation: the diverse sampler's and the
prior's draws (5K each), screened and spread by ``selection`` (it runs when
the sampler's weights exist). Its pool of 10K draws costs five plain
samplings, so by default it runs at k = 0 only (``--sampler-k 0 1 2 3 4``
measures it at every k, in about three times as long). ``--weights DIR``
evaluates a weights folder (as ``train --out DIR`` writes it) and, on the same
windows, the bundled weights ("bundled:" rows) unless ``--no-compare``;
``--limits`` names the joint-angle limits (default: the folder's), so models
trained on different data are measured alike.
"""

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np
import torch

from . import baselines, masks, metrics, numpy_model, realism, weights
from .data import clips, dataset
from .model import reconstruct
from .sampler import prior_motions, sample_motions

METHODS = ("trajevae", "trajevae_mean", "trajevae_posterior", "sampler", "pinned_pose", "nearest_neighbour")
METRICS = ("APD", "ADE", "FDE", "MMADE", "MMFDE", "traj_err", "MPD", "bone_dev", "angle_out", "skating", "turn")
REALISM = ("bone_dev", "angle_out", "skating", "turn")


def generate(method, model, neighbours, windows, mask, samples, generator, diverse_sampler=None, screen_limits=None):
    """Motions (N, K, T, 17, 3) of one method for windows (N, 1 + T, 17, 3) under one mask (T, 17);
    ``screen_limits``: the joint-angle limits the model's variants are screened with, as the add-on
    screens them (``selection``; numpy (low, high), those of the model's weights folder)."""
    initial, future = windows[:, 0], windows[:, 1:]
    trajectories = future * masks.per_coordinate(mask)
    if method in ("trajevae", "trajevae_mean", "trajevae_posterior", "sampler"):
        out = []
        known = torch.from_numpy(np.broadcast_to(mask, (len(windows),) + mask.shape).copy())
        for start in range(0, len(windows), 16):
            part = slice(start, start + 16)
            condition = (torch.from_numpy(initial[part]), torch.from_numpy(trajectories[part]), known[part])
            with torch.no_grad():
                if method == "sampler":
                    motion = sample_motions(model, diverse_sampler, *condition, samples, generator, screen_limits)
                elif method == "trajevae":
                    motion = prior_motions(model, *condition, samples, generator, screen_limits)
                elif method == "trajevae_posterior":
                    motion = reconstruct(model, condition[0], torch.from_numpy(future[part]), known[part])
                else:
                    motion = model.sample(*condition, 1, generator=generator, use_mean=True)
            out.append(motion.numpy())
        return np.concatenate(out)
    if method == "pinned_pose":
        return np.stack([baselines.pinned_pose(i, t, mask)[None] for i, t in zip(initial, trajectories)])
    return np.concatenate([neighbours.query(initial[start:start + 64], trajectories[start:start + 64], mask, samples)
                           for start in range(0, len(windows), 64)])


def score(motions, windows, mask, groups, limits):
    """Metric means over windows for motions (N, K, T, 17, 3)."""
    truth = metrics.to_protocol(windows[:, 1:])
    rows = []
    for n in range(len(windows)):
        samples = metrics.to_protocol(motions[n])
        ade, fde = metrics.ade_fde(samples, truth[n])
        mmade, mmfde = metrics.multimodal_ade_fde(samples, truth[groups[n]])
        apd, mpd = metrics.diversity(samples)
        rows.append((apd, ade, fde, mmade, mmfde, metrics.trajectory_error(motions[n], windows[n, 1:][None], mask),
                     mpd))
    rows = np.array(rows, dtype=np.float64)
    means = list(np.nanmean(rows, axis=0)) if mask.any() else list(rows.mean(axis=0))
    means += realism_figures(motions, windows, limits)
    return {name: (None if np.isnan(v) else round(float(v), 4)) for name, v in zip(METRICS, means)}


def realism_figures(motions, windows, limits):
    """bone_dev, angle_out, skating, turn of motions (N, K, T, 17, 3) from windows' initial poses."""
    initial = np.broadcast_to(windows[:, None, 0], motions.shape[:2] + windows.shape[2:])
    return [realism.bone_length_deviation(motions, initial), realism.share_outside_limits(motions, limits),
            realism.foot_skating(motions, clips.NATIVE_FPS), realism.turn(motions, initial)]


def evaluate(windows, model, neighbours, samples=50, seed=0, methods=METHODS, diverse_sampler=None,
             progress=print, limits_path=realism.ANGLE_LIMITS, sampler_k=(0,), screen_limits=None):
    """{method: {k: {metric: value}}} for windows (N, 1 + T, 17, 3), and the ground truth's realism;
    ``limits_path`` measures, ``screen_limits`` screens (``generate``)."""
    generator = torch.Generator().manual_seed(seed)
    limits = realism.load_angle_limits(limits_path)
    groups = metrics.pseudo_truth_groups(metrics.to_protocol(windows[:, 0]))
    frames = windows.shape[1] - 1
    methods = [m for m in methods if m != "sampler" or diverse_sampler is not None]
    results = {method: {} for method in methods}
    for k in range(len(masks.EVALUATION_ORDER) + 1):
        mask = masks.evaluation_mask(k, frames)
        for method in methods:
            if method == "sampler" and k not in sampler_k:
                continue
            motions = generate(method, model, neighbours, windows, mask, samples, generator, diverse_sampler,
                               screen_limits)
            results[method][str(k)] = score(motions, windows, mask, groups, limits)
        progress(f"k={k} done")
    truth = dict(zip(REALISM, realism_figures(windows[:, None, 1:], windows, limits)))
    return results, {name: round(float(value), 4) for name, value in truth.items()}


def format_table(results, truth):
    lines = [f"{'method':<18} {'k':>2} " + " ".join(f"{m:>8}" for m in METRICS)]
    for method, by_k in results.items():
        for k, row in by_k.items():
            cells = " ".join(f"{'-' if row[m] is None else format(row[m], '.4f'):>8}" for m in METRICS)
            lines.append(f"{method:<18} {k:>2} {cells}")
    lines.append(f"{'ground_truth':<18} {'':>2} " + " ".join(
        f"{format(truth[m], '.4f') if m in truth else '':>8}" for m in METRICS))
    return "\n".join(lines)


COMPARED = ("trajevae", "sampler")  # the bundled weights' rows beside another folder's


def main(argv=None):
    parser = argparse.ArgumentParser(prog="python -m model_runtime.evaluate", description=__doc__)
    parser.add_argument("--data", nargs="+", help="BVH files or folders (default: the validation subjects)")
    parser.add_argument("--mapping", nargs="+", default=[], help="mapping files for --data (as for training)")
    parser.add_argument("--samples", type=int, default=50, help="K samples per condition")
    parser.add_argument("--stride", type=int, default=20, help="frames between window starts")
    parser.add_argument("--weights", default=str(weights.ASSETS), help="weights folder (default: the bundled)")
    parser.add_argument("--no-compare", action="store_true", help="leave out the bundled weights' rows")
    parser.add_argument("--limits", help="joint-angle limits (JSON; default: the weights folder's)")
    parser.add_argument("--sampler-k", type=int, nargs="+", default=[0], help="k at which the sampler runs")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--json", help="write the results here as JSON")
    args = parser.parse_args(argv)
    started = time.time()
    torch.manual_seed(args.seed)

    folder = Path(args.weights)
    limits = Path(args.limits) if args.limits else folder / weights.LIMITS_FILE
    compared = not args.no_compare and folder.resolve() != weights.ASSETS.resolve()
    model, _ = weights.load_model(weights.model_file(folder))
    train_clips, validation_clips = dataset.split_by_subject(dataset.load_clips(dataset.DATA_ROOTS)[0],
                                                             dataset.read_manifest())
    if args.data:
        eval_clips, errors = dataset.load_clips(args.data, custom=dataset.mapping_profiles(parser, args.mapping))
        for error in errors:
            print(f"skipped: {error}", file=sys.stderr)
    else:
        eval_clips = validation_clips
    windows = dataset.windows(eval_clips, future=model.config.frames, stride=args.stride)
    if not len(windows):
        print("no clip is long enough for a window", file=sys.stderr)
        return 1
    neighbours = baselines.NearestNeighbour(dataset.windows(train_clips, future=model.config.frames, stride=5))
    print(f"{len(windows)} windows from {len(eval_clips)} clips, K = {args.samples}", flush=True)
    say = lambda line: print(line, flush=True)
    results, truth = evaluate(windows, model, neighbours, args.samples, args.seed, METHODS, _sampler(folder), say,
                              limits, args.sampler_k, _screen_limits(folder))
    if compared:
        say("the bundled weights on the same windows:")
        bundled = evaluate(windows, weights.load_model()[0], neighbours, args.samples, args.seed, COMPARED,
                           _sampler(weights.ASSETS), say, limits, args.sampler_k, _screen_limits(weights.ASSETS))[0]
        results.update({"bundled:" + method: rows for method, rows in bundled.items()})
    seconds = time.time() - started
    print(format_table(results, truth))
    print(f"{len(windows)} windows in {seconds:.1f} s")
    if args.json:
        with open(args.json, "w") as handle:
            json.dump({"methods": {method: {"k": by_k} for method, by_k in results.items()}, "ground_truth": truth,
                       "windows": len(windows), "samples": args.samples, "seconds": round(seconds, 1)}, handle, indent=1)
    return 0


def _screen_limits(folder):
    """The joint-angle limits of a weights folder as the add-on reads and screens with them, or None."""
    return numpy_model.read_angle_limits(Path(folder) / weights.LIMITS_FILE, weights.RESTORE)


def _sampler(folder):
    """The folder's diverse sampler, or None (said) where it has none."""
    path = Path(folder) / weights.SAMPLER_FILE
    if not path.exists():
        print(f"no sampler weights at {path}: method 'sampler' skipped", file=sys.stderr)
        return None
    return weights.load_sampler(path)[0]


if __name__ == "__main__":
    sys.exit(main())
