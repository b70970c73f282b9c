"""``python -m model_runtime.model_card [EVALUATION.json] [--weights DIR]``: write a weights folder's
MODEL_CARD.md (assets/ unless told) from its model's own facts and an evaluation report, so the card
never drifts from the model. Training writes one without the evaluation."""

import argparse
import json
import sys
from dataclasses import asdict
from pathlib import Path

from . import masks, selection, weights
from .data import clips
from .evaluate import METRICS
from .skeleton import FLOOR_CONTACT_M

ATTRIBUTION = """- The data used in this project was obtained from mocap.cs.cmu.edu. The database was created
  with funding from NSF EIA-0196217.
- Motion capture data from The Ohio State University ACCAD Open Motion Project (CC BY 3.0)."""


def table(evaluation):
    """The evaluation as a Markdown table, the ground truth's realism last."""
    rows = ["| method | k | " + " | ".join(METRICS) + " |", "|---|---|" + "---|" * len(METRICS)]
    for method, entry in evaluation["methods"].items():
        for k, row in entry["k"].items():
            rows.append(f"| {method} | {k} | " + " | ".join(
                "-" if row.get(m) is None else f"{row[m]:.3f}" for m in METRICS) + " |")  # older tables lack turn
    truth = evaluation.get("ground_truth", {})
    rows.append("| ground truth | | " + " | ".join(f"{truth[m]:.3f}" if m in truth else "" for m in METRICS) + " |")
    return "\n".join(rows)


def evaluation_section(evaluation, folder):
    """The card's evaluation text and table, or how to make them."""
    if evaluation is None:
        return f"""Not evaluated yet: `python -m model_runtime.evaluate --weights {folder} --data HELD_OUT... --json
eval.json`, then `python -m model_runtime.model_card eval.json --weights {folder}`."""
    return f"""{evaluation['windows']} validation windows, K = {evaluation.get('samples', 50)} samples,
DLow protocol (metres; APD diversity, ADE/FDE best of K, MMADE/MMFDE over pseudo
ground truths), traj_err = mean distance of conditioned joints to their trajectories,
MPD = minimum pairwise distance among the K samples; realism: bone_dev = mean rigid
bone-length deviation from the initial pose (m), angle_out = share of frames outside
the joint-angle limits fitted on the training poses, skating = mean horizontal foot
speed while the foot is within 5 cm of the floor (m/s). "trajevae" samples the prior:
with trajectories given, the {selection.GIVEN_POOL_FACTOR}K draws' most plausible half (least
straying from the trajectories and, with the given joints pinned as the rig plays them, least bone
stretch and joint angles outside the limits). "trajevae_posterior" decodes
the posterior's mean, which sees the future: an oracle, what the latents carry at all. "sampler" is what the add-on ships: the
diverse Gumbel-softmax sampler over the frozen model ({weights.SAMPLER_FILE}), its K variants
picked from a pool of {selection.POOL_FACTOR}K sampler draws and {selection.PRIOR_POOL_FACTOR}K prior draws (the least
plausible {selection.SCREENED_SHARE:.0%} dropped and, with no trajectories, the
{selection.LEAN_SCREENED_SHARE:.0%} bent over furthest beyond the start pose, then the widest spacing that
typical-first picking allows). Rows prefixed "bundled:" are the bundled weights on the same windows.
k = number of trajectories given, in the order RFoot, LFoot, RWrist, LWrist.
Run in {evaluation['seconds']:.0f} s with `python -m model_runtime.evaluate`.

{table(evaluation)}"""


def _shown(path):
    """A data path as the README writes it: ../shared/... when beside the repository."""
    try:
        return "../" + Path(path).resolve().relative_to(weights.ASSETS.parents[1]).as_posix()
    except ValueError:
        return str(path)


def render(meta, evaluation=None, before=None, folder=weights.ASSETS):
    config, train, data = meta["config"], meta["train"], meta["data"]
    paths = " ".join(map(_shown, data["paths"]))
    init = meta.get("init")
    fine_tuned = "" if init is None else (f"\nFine-tuned from the weights then in `{init}`: the line above starts from"
                                          " them, so reproduce those first, with their own card's line.")
    command = f"python -m model_runtime.train --data {paths}" + ("" if init is None else f" --init {init}") + _flags(train, config)
    count = train.get("best_of_draws", 1)
    draws = "one prior sample" if count == 1 else f"each of {count} prior samples"
    relative = (f", {train['best_of_relative_share']} x the root's error taken off the other joints'"
                if train.get("best_of_relative_share") else ", in absolute positions")
    best_of = ("" if not train.get("best_of_weight") else
               f"; the one nearest the capture answers for its squared error ({train['best_of_weight']} x{relative}, best of many)")
    floor = ("their own lowest ankle, those whose path is given left free" if train.get("prior_floor") == "own"
             else "the window's floor")
    still = (f" and whose ankles stay within {train['rest_start_still_m']} m through the blend"
             if train.get("rest_start_still_m") else "")
    facing = (" (the network sees each condition turned so its initial pose faces +Y, and turns its decodes back)"
              if config.get("facing_frame") else "")
    if meta.get("second_stage_from"):
        fine_tuned += (f"\nThe second stage was trained alone (`--second-stage-from {meta['second_stage_from']}`) on the"
                       " first stage of the weights then there; a whole run trains the same second stage on its own"
                       " first stage.")
    previous = "" if before is None else f"""
### The previous model, measured the same way
{before.get('label', 'Before')}: {before['windows']} windows, K = {before.get('samples', 50)}, run in {before['seconds']:.0f} s.

{table(before)}
"""
    return f"""# TrajeVAE model card

Pose completion for motion from trajectories (Kania, Kowalski, Trzcinski), scaled
for the CPU. File: `{weights.MODEL_FILE}` in this folder (plain arrays and a JSON config; no
pickled code). Reproduce with `{command}`
(then `python -m model_runtime.train_sampler` with the same data).

## What it does
Given an initial pose and any joint coordinates known on any frames (drawn curves, keys,
an end pose, a ground path's horizontal positions, or nothing), it samples full-body
motions of {config['frames']} frames at {clips.NATIVE_FPS} fps (2 s), metres, Z up, initial root at
the ground-plane origin, and says on each frame which feet are planted.
Beyond the paper: the known-coordinate mask is an input (a zero coordinate is ambiguous),
training masks vary over time as well as joints (keys, end poses, partial curves, ground
paths and waypoints of the hips), and the decoder also sees, uncompressed, the known
coordinates relative to the initial pose and their per-frame steps, so given curves are
followed closely; where the hips' horizontal path is given, its step is every other joint's
horizontal base step too, so the body travels with its hips; where feet are given (and the
hips are not), each decode goes along the ground with them, every joint by their mean offset
from the decoded feet. Samples keep the known coordinates exactly as given (pose completion;
every baseline below does the same), and a completion stage, trained after the rest,
moves the other joints to fit what is given (absolute displacements from the decoded
motion with the given joints pinned).

## Data
{data['train_clips']} clips ({data['train_minutes']} minutes) of BVH motion capture under {paths},
mapped to 17 canonical joints; {data['validation_clips']} clips ({data['validation_minutes']} minutes) held out for
validation and never trained on: {data['validation']}. Model selection used them only
(best-of-10 ADE of prior samples over the evaluation masks k = 0..4).{fine_tuned}

The bundled weights were trained on real optical capture of ../shared/mocap and
../shared/mocap-extra (CMU and ACCAD, 24 subjects; validation subjects CMU 02 everyday
motion, CMU 08 walks, ACCAD Male2 martial arts):
{ATTRIBUTION}

## Configuration
{json.dumps(config, indent=1)}

Parameters: {meta['parameters']:,}. Training: {train['steps']} steps planned, batch
{train['batch']}, Adam (lr {train['learning_rate']}, warm-up then cosine cycles of {train['cycle']} steps),
beta {train['beta']}, random turns about Z{facing} and mirroring, seed {train['seed']}; masks mix the
paper's Bernoulli trajectories (p = 0.85 masked), the evaluation order, sparse keys, end
poses, partial curves, ground paths and waypoints, and {masks.CARRIED_SHARE:.0%} of them carry their first
1-{masks.CARRIED_FRAMES} frames{_carried(train)}. {train['rest_start_share']:.0%} of the windows whose first
pose stands{still} start from a rest pose of their own skeleton (T to A, arms 0-50 degrees down)
and turn into the capture over 15-30 frames, as rigs start in the add-on. Losses: the
paper's (squared error, KL; the error in absolute positions where a coordinate is known and, where
it is not, with {train.get('body_relative_share', 0.0)} x the root's error taken off the other joints' (off the feet's,
{1 - train.get('absolute_feet', 0.0)} x that) and the root's own
at {train.get('unknown_root_weight', 1.0)} x, its height at {train.get('unknown_root_height_scale', 1.0)} x that)
plus foot contacts (cross-entropy of the predicted contacts against labels from the capture's sole
height and ankle speed, weight {train['contact_weight']}) and
GSPS realism on the reconstruction and, at {train['prior_realism_share']} x, on {draws} per window,
whose squared error on the known coordinates also counts ({train['prior_known_weight']} x){best_of}:
lengths of the rigid bones and torso segments ({train['bone_weight']}), joint-angle limits fitted on the
training poses ({train['angle_weight']}),
squared speed of planted feet ({train['skating_weight']}; on the prior samples {train.get('prior_skating_weight', train['skating_weight'])}, the feet
they predict planted and those within {train.get('prior_contact_m', FLOOR_CONTACT_M) * 100:.0f} cm of {floor})
and ankles below the window's floor ({train['floor_weight']}).{_refit(train)}
Then the second stage: the completion stage alone ({config['completion_layers']} transformer layers) for
{train['completion_steps']} steps (lr {train['completion_learning_rate']}, warm-up then one cosine decay), from the
last stage's best validated weights, on their frozen decodes of posterior samples and, for
{train['completion_mean_share']:.0%} of each batch, of the prior mean (squared error of the root and of the
body relative to it, plus the realism terms, the bone lengths at
{train.get('completion_bone_weight', train['bone_weight'])} and the joint-angle limits at
{train.get('completion_angle_weight', train['angle_weight'])}), and of one prior draw per window, which answers
for its squared displacement ({train.get('completion_draw_weight', 0.0)} x), that displacement's squared
frame-to-frame acceleration ({train.get('completion_draw_smoothness', 0.0)} x) and the realism terms but foot sliding
(the product's foot lock holds planted feet), so the stage fits draws to what is given without
pulling them together. Best checkpoint at step {meta['step']} after
{meta['training_minutes']:.0f} minutes in {meta['processes']} process(es) ({meta['first_stage_minutes']:.0f} for the first stage);
validation best-of-10 ADE {meta['validation_ade_m']:.4f} m.

## Evaluation
{evaluation_section(evaluation, folder)}
{previous}"""


def _refit(train):
    """The prior's refit in words ('' where the run had none)."""
    if not train.get("prior_refit_steps"):
        return ""
    return (f"\nThen the prior's refit: the prior branch alone for {train['prior_refit_steps']} steps (lr "
            f"{train['prior_refit_learning_rate']}, warm-up then one cosine decay), from the first stage's best "
            f"validated weights, under the same losses with the KL term at {train['prior_refit_beta']} "
            f"(the first stage's {train['beta']}), so the prior's draws cover what the frozen posterior encodes, "
            f"and the draws' realism at {train.get('prior_refit_realism_share', train['prior_realism_share'])} x "
            f"(their planted feet's speed at {train.get('prior_refit_skating_weight', train['prior_skating_weight'])}).")


def _carried(train):
    """How the card's training masks carry a previous window's frames (``masks.carried_legs``)."""
    share = train.get("carried_legs_share", 0.0)
    legs = "the legs and the hips' horizontal position only, as a long shot's later windows carry them"
    if share >= 1.0:
        return f" with {legs}"
    if share > 0.0:
        return f" whole, or for {share:.0%} of them {legs}"
    return " whole (a long shot's later windows carry the legs and the hips' horizontal position only)"


def _flags(train, config):
    """The training command's flags for the fields of a weights file's training and network
    configurations that differ from ``TrainConfig``'s and ``ModelConfig``'s defaults ('' for a
    default run): ``--name value``, or ``--name`` / ``--no-name`` for a switch."""
    from .model import ModelConfig  # train writes cards: imported here, not at the top
    from .train import TrainConfig
    flags = []
    for values, defaults in ((train, asdict(TrainConfig())), (config, asdict(ModelConfig()))):
        for name, value in values.items():
            if name not in defaults or value == defaults[name]:
                continue
            flag = name.replace("_", "-")
            flags.append(f" --{flag}" if value is True else f" --no-{flag}" if value is False else f" --{flag} {value}")
    return "".join(flags)


def write(folder, evaluation=None, before=None):
    """MODEL_CARD.md in the weights ``folder``, from its model's meta and the evaluation dicts."""
    folder = Path(folder)
    _, meta = weights.load_state(folder / weights.MODEL_FILE)
    (folder / weights.CARD_FILE).write_text(render(meta, evaluation, before, folder))
    return folder / weights.CARD_FILE


def main(argv=None):
    parser = argparse.ArgumentParser(prog="python -m model_runtime.model_card")
    parser.add_argument("evaluation", nargs="?", help="JSON written by model_runtime.evaluate --json")
    parser.add_argument("--weights", default=str(weights.ASSETS), help="the weights folder whose card is written")
    parser.add_argument("--before", help="an earlier model's evaluation JSON, shown beside (its 'label' says which)")
    args = parser.parse_args(argv)
    read = lambda path: json.loads(Path(path).read_text()) if path else None
    print(f"wrote {write(args.weights, read(args.evaluation), read(args.before))}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
