"""``python -m model_runtime.train``: train TrajeVAE on motion capture, on the CPU or GPUs.

Two stages. The first trains the network of the paper (encoders, prior,
posterior, decoder) with GSPS's realism terms and foot contacts: the decoder
predicts which feet are planted (labels from the capture's foot height and
speed, ``contacts.foot_contacts``); planted feet are held still, no foot goes
below the window's floor, and poses stay within the joint-angle limits fitted
on the training poses and keep their bone lengths, on the posterior
reconstruction and on one prior sample per window (the prior sample's planted
feet are those it predicts itself and those low enough to count as planted), and the prior sample also answers for its
error on the known coordinates. A share of windows starts from a rest
pose (``augment.rest_start``), as the add-on's rigs do. Where asked
(``--prior-refit-steps``), the prior's refit then trains the prior branch
alone (``PRIOR_BRANCH``) under the same losses with a larger KL weight, so
its draws cover what the frozen posterior encodes. The second trains the
completion stage alone (``TrajeVAE.complete``) on the frozen first stage's
decodes, from the last stage's best validated weights: posterior
reconstructions (and for a share of each batch the prior mean's decode) are
fitted to the capture, prior draws are fitted to what is given and to the
realism terms with as little displacement as that takes
(``completion_losses``); ``--second-stage-from`` trains the stages after the
first (the refit where asked, and the completion stage) again on the first
stage of a saved model, such as the first stage's best weights a run keeps
beside its checkpoint (``first_stage_file``). Each step's
random draws come from the seed, the stage and the step
(``distributed.Processes.rng``), so a run resumes exactly from its checkpoint,
with any number of processes, and a second stage started from a first stage's
saved weights (``--init W --steps 0``) is the one a whole run makes. Random
turns about Z and mirroring; model selection on the validation clips only
(best-of-10 ADE of prior samples over the evaluation masks k = 0..4, the
quantity the evaluation reports; the prior mean's error rewards standing still). The first stage's learning rate follows cosine cycles with
warm restarts, so a longer run continues a shorter one's checkpoint exactly.

The data: ../shared's CMU and ACCAD capture by default, or any BVH files and
folders (``--data``, ``--validation``, ``--mapping``: ``dataset.add_data_arguments``);
``--init`` fine-tunes given weights. The best model, the joint-angle limits and a
model card go to the weights folder ``--out`` (assets/ by default). Under
torchrun the same command trains data-parallel (``distributed``).
"""

import argparse
import json
import math
import shutil
import sys
import time
from dataclasses import asdict, dataclass, fields, replace
from pathlib import Path

import numpy as np
import torch

from . import augment, checkpoints, distributed, masks, metrics, model_card, realism, weights
from .contacts import foot_contacts
from .data import clips, dataset
from .model import ModelConfig, TrajeVAE, kl_divergence, parameter_count, with_given_joints
from .skeleton import (FEET, FLOOR_CONTACT_M, JOINT_NAMES, NUM_JOINTS, PARENTS, RIGID_BONE_JOINTS, indices,
                       rigid_bone_lengths)

# The segments (parent, joint) that RIGID_BONE_JOINTS leaves out: hips-spine-thorax-neck and the clavicles.
TORSO_SEGMENTS = tuple((JOINT_NAMES[parent], name) for name, parent in zip(JOINT_NAMES, PARENTS)
                       if parent >= 0 and name not in RIGID_BONE_JOINTS)


PRIOR_FLOORS = ("window", "own")  # what a prior draw's planted feet are found against (``prior_planted``)
FIRST_STAGE, COMPLETION_STAGE, PRIOR_REFIT = 1, 2, 3  # each also names the stage's random stream
PRIOR_BRANCH = ("prior_transformer", "prior_head")  # what the prior's refit trains


@dataclass(frozen=True)
class TrainConfig:
    steps: int = 7000  # first stage: two cosine cycles
    completion_steps: int = 1000  # second stage: the completion stage alone
    # The prior's refit between them (``PRIOR_BRANCH`` alone; off by default): in the first stage the KL
    # term (beta) is all that fits the prior to the posterior, against the realism of its draws, and the
    # draws hedge. f3's first stage (``--learning-rate 1e-3 --body-relative-share 1 --unknown-root-weight
    # 2``): its posterior's decode 0.581 / 0.621 best-of-1 ADE / FDE at k = 0 / 1, its prior's best of 50
    # 0.722 / 0.719; refitted 1000 steps at beta 0.3, 0.700 / 0.643 (the draws' bones 0.0172 m against
    # 0.0132; at beta 0.1, 0.710 / 0.659 and 0.0161; by KL alone, 0.696 / 0.640 and 0.0199). On the
    # shipped first stage it gains less (0.711 / 0.708 against 0.722 / 0.738) and its draws leave the
    # joint-angle limits on 1.9 % of frames at k = 0 (1.3 %): the realism targets fail.
    prior_refit_steps: int = 0
    prior_refit_beta: float = 0.3
    prior_refit_learning_rate: float = 5e-4  # warm-up, then one cosine decay
    # The draws' realism in the refit (``losses``' prior_realism_share and prior_skating_weight there).
    # Their skating term leans bodies: draws that may not slide a planted foot lean forward and lift a
    # foot instead. f3's first stage, refitted with its draws' realism at 0.5 and skating 1: their chest
    # 0.042 m ahead of the hips at the last frame, with nothing given, where the capture's is 0.004;
    # with skating 0, 0.014; with no realism at all, 0.009, but after the completion stage 2.6 % of its
    # frames at k = 0 off the joint-angle limits (f3c).
    prior_refit_realism_share: float = 0.5
    prior_refit_skating_weight: float = 1.0
    completion_learning_rate: float = 3e-4  # warm-up, then one cosine decay
    completion_mean_share: float = 0.25  # of each second-stage batch, decoded from the prior mean
    completion_draw_weight: float = 1.0  # squared displacement of a prior draw's completion from the draw
    completion_draw_smoothness: float = 100.0  # squared frame-to-frame acceleration of that displacement
    batch: int = 64
    learning_rate: float = 4e-4
    warmup: int = 300
    cycle: int = 3500  # steps per cosine cycle
    restart_peak: float = 0.5  # each restart's peak relative to the previous one's
    beta: float = 0.01  # KL weight, the paper's
    bone_weight: float = 1.0  # rigid bones keep the initial pose's lengths, torso segments too
    contact_weight: float = 1.0  # binary cross-entropy of the contact logits, summed over frames and feet
    skating_weight: float = 1.0  # squared horizontal speed (m/s) of planted feet, summed over frames and feet
    floor_weight: float = 100.0  # squared depth of an ankle below the window's lowest, summed over frames
    angle_weight: float = 2.0  # GSPS: squared cosine outside the joint-angle limits, summed over frames
    completion_angle_weight: float = 20.0  # the same in the second stage (``completion_losses``)
    completion_bone_weight: float = 4.0  # the bone and torso lengths in the second stage
    prior_realism_share: float = 0.5  # weight of the realism terms on the prior sample
    prior_known_weight: float = 1.0  # the prior sample's squared error on the known coordinates
    prior_skating_weight: float = 1.0  # the prior samples' skating term, in place of skating_weight
    prior_floor: str = "window"  # a draw's planted feet: near the window's lowest captured ankle, or "own" (``prior_planted``)
    prior_contact_m: float = FLOOR_CONTACT_M  # ... within this of it (fully within half of it)
    best_of_draws: int = 1  # prior samples decoded per window, the best of which answers for its error (``losses``)
    best_of_weight: float = 0.0  # weight of that best draw's squared error
    best_of_relative_share: float = 0.0  # of the root's error taken from the other joints' in it (``body_relative``)
    body_relative_share: float = 0.0  # of the root's error taken from unknown joints' (``body_relative``)
    unknown_root_weight: float = 1.0  # scales the root's own error where the root is unknown
    # Of that share, the part the feet keep in absolute positions. Why: scored about the root alone (f3,
    # share 1), a standing foot rose to 10 cm over a 10 s wave's continuations (held up on 35 % of its
    # frames; f4, share 0.5: 19 %; share 0: none): a root that drifts up costs the feet nothing.
    absolute_feet: float = 0.0
    # ... and the root's height error scaled by this x unknown_root_weight. Why: with the feet absolute
    # (f5) a root height that costs little bends the knees: with nothing given its draws' hips end at
    # 0.86 of their standing height over the lower ankle (f3 0.91, the shipped weights 0.92, capture 0.92).
    unknown_root_height_scale: float = 1.0
    rest_start_share: float = 0.2  # windows whose initial pose is a rest pose (``augment.rest_start``)
    rest_start_still_m: float = 0.0  # ... among those whose feet stand still (``augment.still_through_blend``; 0: any)
    mirror_probability: float = 0.5
    curve_mask_share: float = masks.FAMILY_SHARES[1]  # of training masks, the evaluation order's curves
    # Of the masks that carry a previous window's frames, those that carry what a long shot's later
    # window does (``masks.carried_legs``: the legs and the hips' horizontal position), not whole poses.
    carried_legs_share: float = 0.0
    seed: int = 0
    validate_every: int = 500
    checkpoint_every: int = 250

    def __post_init__(self):
        if self.prior_floor not in PRIOR_FLOORS:
            raise ValueError(f"prior_floor {self.prior_floor!r}: one of {', '.join(PRIOR_FLOORS)}")


class WindowSampler:
    """Random training windows (B, 1 + T, 17, 3) and their sole heights (B, 1 + T, 2) drawn from
    whole clips, any start frame."""

    def __init__(self, clip_list, frames):
        self.length = frames + 1
        kept = [c for c in clip_list if c.frames >= self.length]
        self.motion = np.concatenate([c.positions for c in kept])
        self.soles = np.concatenate([c.soles for c in kept])
        ends = np.cumsum([c.frames for c in kept])
        self.starts = np.concatenate([np.arange(end - c.frames, end - self.length + 1)
                                      for c, end in zip(kept, ends)])

    def __len__(self):
        return len(self.starts)

    def sample(self, batch, rng):
        frames = rng.choice(self.starts, size=batch)[:, None] + np.arange(self.length)
        return dataset.normalise(self.motion[frames]), self.soles[frames]


def training_batch(sampler, config, frames, rng):
    """One batch as tensors: motion (B, 1 + T, 17, 3), mask (B, T, 17, 3), contact labels (B, T, 2)
    of the frames after the initial one. Rest starts, mirroring (feet swapped) and turns about Z."""
    motion, soles = sampler.sample(config.batch, rng)
    rest = (rng.random(config.batch) < config.rest_start_share) & augment.stands_upright(motion)
    if config.rest_start_still_m:
        rest &= augment.still_through_blend(motion, config.rest_start_still_m)
    if rest.any():
        motion[rest], soles[rest] = augment.rest_start(motion[rest], soles[rest], rng)
    flip = rng.random(config.batch) < config.mirror_probability
    motion[flip], soles[flip] = augment.mirror(motion[flip]), soles[flip][..., ::-1]
    motion = augment.rotate_about_z(motion, rng.uniform(0, 2 * np.pi, config.batch)).astype(np.float32)
    contacts = foot_contacts(motion, soles, clips.NATIVE_FPS)[:, 1:].astype(np.float32)
    mask = masks.sample_training_masks(config.batch, frames, rng, config.curve_mask_share, config.carried_legs_share)
    return torch.from_numpy(motion), torch.from_numpy(mask), torch.from_numpy(contacts)


def validation_set(clips, frames, stride=10):
    """Fixed validation windows (N, 1 + T, 17, 3) and masks (N, T, 17) cycling k = 0..4."""
    windows = dataset.windows(clips, future=frames, stride=stride)
    cycle = len(masks.EVALUATION_ORDER) + 1
    mask = np.stack([masks.evaluation_mask(i % cycle, frames) for i in range(len(windows))])
    return windows, mask


def realism_terms(motion, initial, future, planted, limits):
    """GSPS realism of motions (B, T, J, 3), each summed over frames and meaned over the batch:
    rigid bone and torso segment lengths against the initial pose, joint angles outside ``limits``,
    planted feet's squared horizontal speed (m/s; ``planted`` (B, T, 2) weights in [0, 1]) and
    ankles below the window's lowest captured ankle (``future`` (B, T, J, 3))."""
    bones = ((body_lengths(motion) - body_lengths(initial)[:, None]) ** 2).flatten(1).sum(-1).mean()
    angles = realism.angle_limit_loss(motion, limits).sum(-1).mean()
    skating = realism.planted_skating_loss(motion, initial, planted, clips.NATIVE_FPS).mean()
    below = realism.floor_loss(motion, future[:, :, indices(FEET), 2].amin(dim=1, keepdim=True)).mean()
    return {"bones": bones, "angles": angles, "skating": skating, "floor": below}


def body_lengths(poses):
    """Lengths (..., 11 + 5) of the rigid bones and the torso segments (``TORSO_SEGMENTS``) of poses
    (..., 17, 3): a torso bends a few centimetres between its joints, but it does not grow (a neck
    decoded without this reached 2.8x its length in 2 s)."""
    first, second = (poses[..., indices(ends), :] for ends in zip(*TORSO_SEGMENTS))
    return torch.cat([rigid_bone_lengths(poses), ((second - first) ** 2).sum(-1) ** 0.5], dim=-1)


def weighted_realism(terms, config, bone_weight, angle_weight, skating_weight):
    return (bone_weight * terms["bones"] + angle_weight * terms["angles"]
            + skating_weight * terms["skating"] + config.floor_weight * terms["floor"])


def losses(model, initial, future, mask, contacts, limits, config):
    """Loss terms per the paper (summed squared error and KL per sample), the contact logits' cross-entropy,
    and the realism terms on the reconstruction (its planted feet: the labels) and on each prior sample
    (its planted feet: its own predictions), with the prior samples' error on the known coordinates:
    the product draws prior samples, and with realism alone on them they learned to lag their given
    joints (a given hip moved at 60 % of its speed). The reconstruction's error counts in absolute
    positions where a coordinate is known and per ``body_relative_share`` and ``unknown_root_weight``
    where it is not: the root's travel counted on every joint keeps the pose out of the latents.
    With ``best_of_draws`` > 1 the best of that many prior samples answers for its squared error
    (``best_of_weight``; "best of many", which the evaluation's best of K scores): alone, the prior's
    samples hedge toward the mean, and given a foot's path their hips travelled 61 % as far as the
    capture's, its draws 1.5x narrower than with nothing given. In absolute positions (at
    ``best_of_relative_share`` 0 the root's travel counts on all 17 joints) four draws learned to
    cover travel the evaluation, relative to the root, does not score: with nothing given their hips
    went 0.84 m in 2 s against the capture's 0.47 and their feet skated 4.4x as fast (0.347 m/s against
    0.078, realism scored on every draw); with the root's error counted once (share 1), 0.51 m, and
    best-of-10 validation error 0.6966 m against 0.7009 after 500 steps. The draws' skating:
    ``prior_skating_weight`` and ``prior_floor`` "own" (as the evaluation finds planted feet) took it
    from 0.31 to 0.11 m/s in 600 steps."""
    decoded = model(initial, future, mask, config.best_of_draws)
    difference = decoded.reconstruction - future
    relative = body_relative(difference, config.body_relative_share, config.unknown_root_weight, config.absolute_feet,
                             config.unknown_root_height_scale)
    mask = masks.per_coordinate(mask)
    known = ((difference ** 2) * mask).flatten(1).sum(-1).mean()
    draws = decoded.prior_motions
    prior_known = (((draws - future[:, None]) ** 2) * mask[:, None]).flatten(2).sum(-1).mean()
    best_of = (body_relative(draws - future[:, None], config.best_of_relative_share) ** 2
               ).flatten(2).sum(-1).amin(dim=1).mean()
    unknown = ((relative ** 2) * (1 - mask)).flatten(1).sum(-1).mean()
    kl = kl_divergence(decoded.posterior, decoded.prior).mean()
    contact = torch.nn.functional.binary_cross_entropy_with_logits(
        decoded.contacts, contacts, reduction="none").flatten(1).sum(-1).mean()
    realism_now = realism_terms(decoded.reconstruction, initial, future, contacts, limits)
    each = lambda tensor: tensor.repeat_interleave(draws.shape[1], dim=0)  # per draw
    flat = draws.flatten(0, 1)
    realism_prior = realism_terms(flat, each(initial), each(future),
                                  prior_planted(flat, decoded.prior_contacts.flatten(0, 1), each(future),
                                                each(mask), config.prior_floor, config.prior_contact_m), limits)
    total = (known + unknown + config.prior_known_weight * prior_known + config.beta * kl
             + config.best_of_weight * best_of
             + config.contact_weight * contact
             + weighted_realism(realism_now, config, config.bone_weight, config.angle_weight, config.skating_weight)
             + config.prior_realism_share * weighted_realism(realism_prior, config, config.bone_weight,
                                                             config.angle_weight, config.prior_skating_weight))
    parts = {"known": known.item(), "prior_known": prior_known.item(), "unknown": unknown.item(), "kl": kl.item(),
             "best_of": best_of.item(), "contact": contact.item()}
    parts.update({name: value.item() for name, value in realism_now.items()})
    parts.update({"prior_" + name: value.item() for name, value in realism_prior.items()})
    return total, parts


def prior_planted(motion, logits, future, mask, floor="window", contact_m=FLOOR_CONTACT_M):
    """Planted-foot weights (B, T, 2) in [0, 1] of prior samples (B, T, J, 3) for their skating term: the
    feet they predict planted (``logits`` (B, T, 2)) and the feet low enough to count as planted (ankles
    within ``contact_m`` of the floor, fully within half of it: at FLOOR_CONTACT_M, as the evaluation
    finds them; the add-on's cleanup holds feet up to 6 cm up, ``cleanup.STEP_LIFT_M``). The floor:
    the window's lowest captured ankle ("window") or, as the evaluation measures, each foot's own
    lowest in the sample ("own"), where a foot whose horizontal position is known (``mask``
    (B, T, J, 3)) is not held: it follows its given path. With their own predictions alone, feet
    gliding along a ground path and predicted in the air went free: prior samples learned to glide
    (ankles lifted 3.5 cm in captured walks' 20); holding given feet at 10x, draws let their known
    coordinates go (squared error 10 against 3)."""
    ankles = motion[..., indices(FEET), 2].detach()
    if floor == "window":
        lowest, free = future[:, :, indices(FEET), 2], 1.0
    else:
        lowest, free = ankles, 1 - mask[..., indices(FEET), :2].amax(-1)
    height = ankles - lowest.amin(dim=1, keepdim=True)
    low = ((contact_m - height) / (0.5 * contact_m)).clamp(0.0, 1.0)
    return torch.maximum(torch.sigmoid(logits).detach(), low) * free


class CompletionStage(torch.nn.Module):
    """The completion stage as a module of its own, so the second stage's data-parallel wrapper
    averages just its gradients."""

    def __init__(self, model):
        super().__init__()
        self.model = model

    def forward(self, decoded, initial, given, mask):
        return self.model.complete(decoded, initial, given, mask)


def completion_losses(model, completion, initial, future, mask, contacts, limits, config):
    """Second-stage loss, with the first stage frozen and without dropout; ``completion`` is the
    model's ``CompletionStage`` (as ``distributed.Processes.parallel`` wraps it).

    Each window is completed twice. A decode of a posterior sample (for ``completion_mean_share`` of
    the batch, of the prior mean, the model's point prediction; trained on posterior samples alone,
    completing the prior mean's decode added up to 9 mm to its final-frame error) answers for
    ``root_and_body_error`` against the capture and the realism terms (planted feet: the labels).
    A prior draw, as the product completes them, answers for its displacement
    (``completion_draw_weight``), that displacement's acceleration from frame to frame
    (``completion_draw_smoothness``) and the realism terms but foot sliding: the stage fits it to
    what is given, within the joint-angle limits and bone lengths, smoothly, and otherwise leaves it
    as drawn. (Without the smoothness, keys given on single frames were met by displacing those
    frames alone: a blocking shot's worst frame 9x its median frame's acceleration.)
    Trained on the first kind alone the stage took every draw toward the capture's one future;
    holding the draws' feet as well froze the shifts of weight and shuffles the variants differ by
    (a standing shot's five variants 0.10 m apart, against 0.15 without), and the product's foot
    lock holds planted feet anyway. Draws alone, without the capture's future, left bodies leaning
    half a metre off their feet. The joint-angle limits weigh ``completion_angle_weight`` here, 10x the
    first stage's, and the bones ``completion_bone_weight``, 4x. At 10 and 1 the facing-frame weights'
    frames off the limits at k = 0 / 1 were 2.7x / 3.7x the capture's (3.1x / 5.8x at 2 and 1), bones
    0.0158 / 0.0212 m; at 20 and 4, 2.4x / 3.1x and 0.0145 / 0.0201 m, best-of-50 error 0.2 % more at
    k = 0 / 1 and less at k = 3 / 4 (evaluated as the add-on screens draws, ``selection``). At 40 the
    limits stretched the bones unless they weighed 8 or more, and then the stage fitted draws further
    (squared displacement 2.8 against 1.9 at 20 and 4): standing variants with both feet and a hand
    given stretched their shins 2 cm (their bones 1.22x plain draws', 1.10x at 20 and 4, 0.98x at 10
    and 1), and as played idle bodies leaned 5 degrees further.
    """
    given = future * masks.per_coordinate(mask)
    model.eval()
    with torch.no_grad():
        decoded = model(initial, future, mask)
        fitted = decoded.reconstruction
        means = round(config.completion_mean_share * len(initial))
        if means:
            fitted[:means] = model.sample(initial[:means], given[:means], mask[:means], 1, use_mean=True,
                                          decoded_only=True)[:, 0]
        drawn = with_given_joints(masks.following_given_feet(decoded.prior_motions, given, mask), given, mask)[:, 0]
    model.train()
    completed_fit, completed_draw = completion(torch.stack([fitted, drawn], dim=1), initial, given, mask).unbind(1)
    error = root_and_body_error(completed_fit, future).mean()
    moved = completed_draw - drawn
    displacement = (moved ** 2).flatten(1).sum(-1).mean()
    jerk = ((moved[:, 2:] - 2 * moved[:, 1:-1] + moved[:, :-2]) ** 2).flatten(1).sum(-1).mean()
    completion_weights = config.completion_bone_weight, config.completion_angle_weight, config.skating_weight
    terms = realism_terms(completed_fit, initial, future, contacts, limits)
    draw_terms = realism_terms(completed_draw, initial, future, torch.zeros_like(contacts), limits)  # no feet held
    total = (error + config.completion_draw_weight * displacement + config.completion_draw_smoothness * jerk
             + weighted_realism(terms, config, *completion_weights)
             + weighted_realism(draw_terms, config, *completion_weights))
    parts = {"completion": error.item(), "displacement": displacement.item(), "jerk": jerk.item()}
    parts.update({name: value.item() for name, value in terms.items()})
    parts.update({"draw_" + name: value.item() for name, value in draw_terms.items() if name != "skating"})
    return total, parts


def root_and_body_error(motion, truth):
    """Squared error (B,) of motions (B, T, J, 3), summed per sample: the root's, and the other
    joints' relative to the root, so a body is scored on its pose apart from where its root went
    (scored in absolute positions, the root's error spread over every joint)."""
    return (body_relative(motion - truth) ** 2).flatten(1).sum(-1)


def body_relative(difference, share=1.0, root_weight=1.0, absolute_feet=0.0, root_height_scale=1.0):
    """Differences (..., J, 3) of poses with ``share`` x the root's difference taken from the other
    joints': at 1 the root's own error and the pose's apart from it, at 0 absolute positions; the
    root's row scaled by ``root_weight``, its height by ``root_height_scale`` x that; from the feet's,
    (1 - ``absolute_feet``) x that share."""
    root = difference[..., :1, :]
    shares = torch.full((NUM_JOINTS - 1, 1), float(share), dtype=difference.dtype, device=difference.device)
    shares[[index - 1 for index in indices(FEET)]] *= 1.0 - absolute_feet
    scale = torch.tensor([root_weight, root_weight, root_weight * root_height_scale], dtype=difference.dtype,
                         device=difference.device)
    return torch.cat([scale * root, difference[..., 1:, :] - shares * root], dim=-2)


def stage_at(step, config):
    """(stage, its first overall step) of an overall step: the first stage, the prior's refit, then
    the completion stage."""
    if step < config.steps:
        return FIRST_STAGE, 0
    if step < config.steps + config.prior_refit_steps:
        return PRIOR_REFIT, config.steps
    return COMPLETION_STAGE, config.steps + config.prior_refit_steps


def train_stage(model, stage):
    """Make the stage's parameters the trainable ones: all but the completion stage in the first,
    the prior branch alone in the refit, the completion stage alone in the second."""
    for name, parameter in model.named_parameters():
        if stage == PRIOR_REFIT:
            parameter.requires_grad_(name.startswith(PRIOR_BRANCH))
        else:
            parameter.requires_grad_(name.startswith("completion_") == (stage == COMPLETION_STAGE))


def from_best_of_last_stage(model, best_file, run, processes):
    """Start a stage from the last stage's best validated weights (``best_file``, this run's), not
    its last: selection then picks among the new stage's own validations (a first stage's best
    beside an untrained completion stage is no model to ship)."""
    state = processes.share(weights.load_state(best_file)[0] if processes.main else None)
    model.load_state_dict(state)
    run.best = float("inf")
    processes.say(f"step {run.step}: from the last stage's best weights ({best_file})")


def first_stage_file(checkpoint):
    """Where a run keeps its first stage's best weights: beside its checkpoint, out of the weights folder."""
    return Path(checkpoint).with_name(Path(checkpoint).stem + "-first-stage.npz")


def keep_first_stage(best_file, kept, processes):
    """Copy the first stage's best weights (``best_file``) to ``kept`` before the later stages replace
    them: ``--second-stage-from`` on that file trains other refits and completion stages on the same
    first stage in minutes, where running it again took 41."""
    kept.parent.mkdir(parents=True, exist_ok=True)
    shutil.copyfile(best_file, kept)
    processes.say(f"the first stage's best weights kept at {kept} (--second-stage-from trains later stages on them)")


def with_fresh_completion_stage(state, model):
    """``state`` (a saved model's) with the completion stage's parameters of the freshly seeded
    ``model``, in place: the first stage's best weights as a whole run hands them to its later
    stages (``from_best_of_last_stage``), whose completion stage the first never trained."""
    state.update({name: value for name, value in model.state_dict().items() if name.startswith("completion_")})


def stage_learning_rate(step, config):
    """The learning rate of any stage at an overall step."""
    stage, start = stage_at(step, config)
    if stage == FIRST_STAGE:
        return learning_rate(step, config.learning_rate, config.warmup, config.cycle, config.restart_peak)
    if stage == PRIOR_REFIT:
        return learning_rate(step - start, config.prior_refit_learning_rate, config.warmup // 3,
                             config.prior_refit_steps)
    return learning_rate(step - start, config.completion_learning_rate, config.warmup // 3, config.completion_steps)


@torch.no_grad()
def validate(model, windows, mask, samples=10, batch=64, seed=0):
    """Best-of-``samples`` ADE (DLow protocol, metres) of prior samples, over validation windows and masks.

    Its own generator, so validating does not change the training run's random stream.
    """
    model.eval()
    generator = torch.Generator().manual_seed(seed)
    device = next(model.parameters()).device
    errors = []
    for start in range(0, len(windows), batch):
        motion = torch.from_numpy(windows[start:start + batch]).to(device)
        known = torch.from_numpy(mask[start:start + batch]).to(device)
        initial, future = motion[:, 0], motion[:, 1:]
        predictions = model.sample(initial, future * known[..., None], known, samples, generator=generator).cpu()
        truth = torch.from_numpy(metrics.to_protocol(future.cpu().numpy()))
        distance = torch.linalg.norm(torch.from_numpy(metrics.to_protocol(predictions.numpy())) - truth[:, None],
                                     dim=-1)  # (B, samples, T)
        errors.append(distance.mean(-1).min(-1).values)
    model.train()
    return torch.cat(errors).mean().item()


def learning_rate(step, peak, warmup, cycle, restart_peak=0.5):
    """Linear warm-up to ``peak``, then cosine cycles of ``cycle`` steps, each decaying to 2% of its
    peak; each restart peaks at ``restart_peak`` x the previous peak."""
    if step < warmup:
        return peak * (step + 1) / warmup
    index, position = divmod(step, cycle)
    start = warmup if index == 0 else 0
    progress = (position - start) / max(1, cycle - start)
    return peak * restart_peak ** index * (0.02 + 0.98 * 0.5 * (1 + math.cos(math.pi * progress)))


def main(argv=None):
    parser = argparse.ArgumentParser(prog="python -m model_runtime.train", description=__doc__)
    dataset.add_data_arguments(parser)
    parser.add_argument("--out", default=str(weights.ASSETS),
                        help=f"weights folder: {weights.MODEL_FILE}, {weights.LIMITS_FILE} and {weights.CARD_FILE} go here")
    start = parser.add_mutually_exclusive_group()
    start.add_argument("--init", help="weights folder (or its .npz) to fine-tune from")
    start.add_argument("--second-stage-from", metavar="WEIGHTS",
                        help="weights folder (or its .npz) whose first stage to keep: train the stages after it "
                             "(the prior's refit where asked, and the second), as a whole run with that first "
                             "stage would")
    parser.add_argument("--steps", type=int, default=TrainConfig.steps, help="first-stage steps")
    parser.add_argument("--completion-steps", type=int, default=TrainConfig.completion_steps)
    parser.add_argument("--batch", type=int, default=TrainConfig.batch, help="windows per process and step")
    parser.add_argument("--learning-rate", type=float, default=TrainConfig.learning_rate, help="first-stage peak")
    parser.add_argument("--warmup", type=int, default=TrainConfig.warmup, help="first-stage warm-up steps")
    parser.add_argument("--seed", type=int, default=TrainConfig.seed)
    parser.add_argument("--checkpoint", help="default: one per --out folder (and one for a fine-tune into it) in "
                                              "~/.cache/trajevae/checkpoints")
    parser.add_argument("--fresh", action="store_true", help="ignore an existing checkpoint")
    parser.add_argument("--threads", type=int, default=0, help="torch threads per process (0: torch's choice)")
    parser.add_argument("--log-every", type=int, default=50, help="steps between progress lines")
    parser.add_argument("--validate-every", type=int, default=TrainConfig.validate_every)
    parser.add_argument("--facing-frame", action=argparse.BooleanOptionalAction, default=ModelConfig.facing_frame,
                        help="the network sees each condition turned to face +Y (ModelConfig.facing_frame)")
    parser.add_argument("--heading-channel", action=argparse.BooleanOptionalAction, default=ModelConfig.heading_channel,
                        help="the decoder turns the body about its hips (ModelConfig.heading_channel)")
    parser.add_argument("--feet-lead", action=argparse.BooleanOptionalAction, default=ModelConfig.feet_lead,
                        help="the body's base step follows the given feet (ModelConfig.feet_lead)")
    add_config_flags(parser, TrainConfig, taken=("steps", "completion_steps", "batch", "learning_rate", "warmup", "seed",
                                                 "validate_every"), kinds=(float, int, str))
    add_config_flags(parser, ModelConfig, kinds=(float, int))  # the network's sizes too
    return distributed.run(_train, parser, parser.parse_args(argv))


def add_config_flags(parser, config_type, taken=(), kinds=(float,)):
    """A --flag per field of a config dataclass of the ``kinds`` (loss weights, shares, margins: for
    experiments one command reproduces), but the fields in ``taken``, which have flags of their own."""
    for field in fields(config_type):
        if field.type in kinds and field.name not in taken:
            parser.add_argument("--" + field.name.replace("_", "-"), type=field.type, default=field.default)


def config_from_flags(config_type, args):
    """The config dataclass with every field the command line has a flag for taken from it."""
    return config_type(**{field.name: getattr(args, field.name) for field in fields(config_type)
                          if hasattr(args, field.name)})


def _train(parser, args, processes):
    config = config_from_flags(TrainConfig, args)
    model_config = config_from_flags(ModelConfig, args)
    if args.threads:
        torch.set_num_threads(args.threads)
    out = Path(args.out)
    # a fine-tune has a checkpoint of its own, so it can follow a whole run into the same folder
    checkpoint = args.checkpoint or checkpoints.default_path("trajevae-fine-tune" if args.init else "trajevae", out)

    split = dataset.split_from_arguments(parser, args)
    sampler = WindowSampler(split.train, model_config.frames)
    fitted = realism.fit_angle_limits(sampler.motion)
    limits = realism.angle_limit_tensors(fitted)
    val_windows, val_mask = validation_set(split.validation, model_config.frames)
    processes.say(f"training windows {len(sampler)} from {len(split.train)} clips; validation windows "
                  f"{len(val_windows)} from {len(split.validation)} clips ({split.validation_rule}); "
                  f"{processes.world} process(es), global batch {config.batch * processes.world}; checkpoint {checkpoint}")
    if processes.main:
        out.mkdir(parents=True, exist_ok=True)
        (out / weights.LIMITS_FILE).write_text(json.dumps(fitted, indent=1))

    torch.manual_seed(config.seed)
    model = TrajeVAE(model_config).to(processes.device)
    optimizer = torch.optim.Adam(model.parameters(), lr=config.learning_rate, betas=(0.9, 0.99))
    processes.say(f"TrajeVAE {parameter_count(model):,} parameters; {model_config}")
    run = checkpoints.RunState(checkpoint, model, optimizer)
    if not args.fresh and run.resume(processes):
        processes.say(f"resumed from {checkpoint} at step {run.step}")
    elif args.init or args.second_stage_from:
        source = args.second_stage_from or args.init
        state, meta = weights.load_state(weights.model_file(source))
        if ModelConfig(**meta["config"]).network() != model_config.network():
            parser.error(f"{source} holds a TrajeVAE of another configuration ({meta['config']})")
        if args.second_stage_from:
            with_fresh_completion_stage(state, model)
            run.step, run.elapsed = config.steps, 60 * meta.get("first_stage_minutes", 0.0)
            processes.say(f"the stages after the first alone, from the first stage of {source}")
        else:
            processes.say(f"fine-tuning the weights of {source}")
        model.load_state_dict(state)

    started, running, interval = time.time() - run.elapsed, {}, []
    total_steps = config.steps + config.prior_refit_steps + config.completion_steps
    refit_config = replace(config, beta=config.prior_refit_beta, prior_realism_share=config.prior_refit_realism_share,
                           prior_skating_weight=config.prior_refit_skating_weight)
    first_stage_minutes = run.elapsed / 60 if run.step >= config.steps else None
    pace_since, first_step = (run.step, run.elapsed), run.step
    stage = None
    while run.step < total_steps:
        now, start = stage_at(run.step, config)
        if stage != now:  # start or resume a stage: its trainable set, wrapped
            stage, stage_start = now, start
            if run.step == stage_start > 0:
                optimizer.state.clear()  # fresh moments, as in a stage started from saved weights (``--init``)
                if run.best < float("inf"):
                    if run.step == config.steps and processes.main:
                        keep_first_stage(out / weights.MODEL_FILE, first_stage_file(checkpoint), processes)
                    from_best_of_last_stage(model, out / weights.MODEL_FILE, run, processes)
            train_stage(model, stage)
            trained = processes.parallel(CompletionStage(model) if stage == COMPLETION_STAGE else model)
            if stage != FIRST_STAGE:
                first_stage_minutes = run.elapsed / 60 if first_stage_minutes is None else first_stage_minutes
                running, pace_since = {}, (run.step, run.elapsed)
        stage_step = run.step - stage_start
        batch = training_batch(sampler, config, model_config.frames, processes.rng(config.seed, stage, stage_step))
        motion, mask, contacts = (tensor.to(processes.device) for tensor in batch)
        for group in optimizer.param_groups:
            group["lr"] = stage_learning_rate(run.step, config)
        if stage != COMPLETION_STAGE:
            total, parts = losses(trained, motion[:, 0], motion[:, 1:], mask, contacts, limits,
                                  config if stage == FIRST_STAGE else refit_config)
        else:
            total, parts = completion_losses(model, trained, motion[:, 0], motion[:, 1:], mask, contacts, limits, config)
        optimizer.zero_grad()
        total.backward()
        torch.nn.utils.clip_grad_norm_(model.parameters(), 100.0)
        optimizer.step()
        processes.check_in_step(model, run.step)
        run.step += 1
        checkpoints.smooth(running, parts)
        interval.append(total.item())
        run.elapsed = time.time() - started
        stage_end = run.step in (config.steps, config.steps + config.prior_refit_steps, total_steps)
        if run.step % args.log_every == 0 or stage_end:
            processes.say(checkpoints.progress_line(run.step, total_steps, float(np.mean(interval)), running,
                                                    run.elapsed, pace_since))
            interval = []
        if processes.main and (run.step % config.validate_every == 0 or stage_end):
            error = validate(model, val_windows, val_mask)
            run.history.append({"step": run.step, "validation_ade_m": error, "minutes": run.elapsed / 60})
            marker = ""
            if error < run.best:
                run.best, marker = error, " (best, saved)"
                weights.save(out / weights.MODEL_FILE, model, model_config, {
                    "train": asdict(config), "step": run.step, "validation_ade_m": error,
                    "training_minutes": run.elapsed / 60,
                    "first_stage_minutes": run.elapsed / 60 if first_stage_minutes is None else first_stage_minutes,
                    "data": split.describe(), "processes": processes.world, "init": args.init,
                    "second_stage_from": args.second_stage_from,
                    "parameters": parameter_count(model)})
            print(f"validation: best-of-10 ADE {error:.4f} m{marker}", flush=True)
        if processes.main and (run.step % config.checkpoint_every == 0 or stage_end):
            run.save()
    if processes.world > 1:
        processes.say(f"{processes.world} processes: weights identical after each of {run.step - first_step} steps")
    if processes.main:
        model_card.write(out)
        print(f"done: {run.step} steps in {run.elapsed / 60:.1f} min, "
              f"best validation error {run.best:.4f} m -> {out / weights.MODEL_FILE}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
