"""``python -m model_runtime.train``: train TrajeVAE on the shared motion capture, on the CPU.

Two stages. The first trains the network of the paper (encoders, prior,
posterior, decoder) with GSPS's realism terms and foot contacts: the decoder
predicts which feet are planted (labels from the capture's foot height and
speed, ``contacts.foot_contacts``); planted feet are held still, no foot goes
below the window's floor, and poses stay within the joint-angle limits fitted
on the training poses and keep their bone lengths, on the posterior
reconstruction and on one prior sample per window (the prior sample's planted
feet are those it predicts itself). A share of windows starts from a rest
pose (``augment.rest_start``), as the add-on's rigs do. The second trains the completion stage alone
(``TrajeVAE.complete``) on the frozen first stage's decodes (posterior
reconstructions, and for a share of each batch the prior mean's decode), with
its own seed, so it can start from a first stage's saved weights (``--init``)
exactly as it would in one run. Fixed seed, random turns about Z and
mirroring, checkpoints with resume, and model selection on the validation
subjects only (best-of-10 ADE of prior samples over the evaluation masks
k = 0..4, the quantity the evaluation reports; the prior mean's error rewards
standing still). The first stage's learning rate follows cosine cycles with
warm restarts, so a longer run continues a shorter one's checkpoint exactly.
The best model is written to assets/trajevae.npz.
"""

import argparse
import json
import math
import sys
import time
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np
import torch

from . import augment, checkpoints, masks, metrics, realism, weights
from .contacts import foot_contacts
from .data import clips, dataset
from .model import ModelConfig, TrajeVAE, kl_divergence, parameter_count
from .skeleton import FEET, indices, rigid_bone_lengths


@dataclass(frozen=True)
class TrainConfig:
    steps: int = 6000  # first stage
    completion_steps: int = 1500  # second stage: the completion stage alone
    completion_learning_rate: float = 3e-4  # warm-up, then one cosine decay
    completion_mean_share: float = 0.25  # of each second-stage batch, decoded from the prior mean
    batch: int = 64
    learning_rate: float = 4e-4
    warmup: int = 300
    cycle: int = 6000  # steps per cosine cycle
    restart_peak: float = 0.5  # each restart's peak relative to the previous one's
    beta: float = 0.01  # KL weight, the paper's
    bone_weight: float = 1.0  # rigid bones keep the initial pose's lengths
    contact_weight: float = 1.0  # binary cross-entropy of the contact logits, summed over frames and feet
    skating_weight: float = 1.0  # squared horizontal speed (m/s) of planted feet, summed over frames and feet
    floor_weight: float = 100.0  # squared depth of an ankle below the window's lowest, summed over frames
    angle_weight: float = 2.0  # GSPS: squared cosine outside the joint-angle limits, summed over frames
    prior_realism_share: float = 0.5  # weight of the realism terms on the prior sample
    rest_start_share: float = 0.2  # windows whose initial pose is a rest pose (``augment.rest_start``)
    mirror_probability: float = 0.5
    seed: int = 0
    validate_every: int = 500
    checkpoint_every: int = 250


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
    if rest.any():
        motion[rest], soles[rest] = augment.rest_start(motion[rest], soles[rest], rng)
    flip = rng.random(config.batch) < config.mirror_probability
    motion[flip], soles[flip] = augment.mirror(motion[flip]), soles[flip][..., ::-1]
    motion = augment.rotate_about_z(motion, rng.uniform(0, 2 * np.pi, config.batch)).astype(np.float32)
    contacts = foot_contacts(motion, soles, clips.NATIVE_FPS)[:, 1:].astype(np.float32)
    mask = masks.sample_training_masks(config.batch, frames, rng)
    return torch.from_numpy(motion), torch.from_numpy(mask), torch.from_numpy(contacts)


def validation_set(clips, frames, stride=10):
    """Fixed validation windows (N, 1 + T, 17, 3) and masks (N, T, 17) cycling k = 0..4."""
    windows = dataset.windows(clips, future=frames, stride=stride)
    cycle = len(masks.EVALUATION_ORDER) + 1
    mask = np.stack([masks.evaluation_mask(i % cycle, frames) for i in range(len(windows))])
    return windows, mask


def realism_terms(motion, initial, future, planted, limits):
    """GSPS realism of motions (B, T, J, 3), each summed over frames and meaned over the batch:
    rigid bone lengths against the initial pose, joint angles outside ``limits``, planted feet's
    squared horizontal speed (m/s; ``planted`` (B, T, 2) weights in [0, 1]) and ankles below the
    window's lowest captured ankle (``future`` (B, T, J, 3))."""
    bones = ((rigid_bone_lengths(motion) - rigid_bone_lengths(initial)[:, None]) ** 2).flatten(1).sum(-1).mean()
    angles = realism.angle_limit_loss(motion, limits).sum(-1).mean()
    skating = realism.planted_skating_loss(motion, initial, planted, clips.NATIVE_FPS).mean()
    below = realism.floor_loss(motion, future[:, :, indices(FEET), 2].amin(dim=1, keepdim=True)).mean()
    return {"bones": bones, "angles": angles, "skating": skating, "floor": below}


def weighted_realism(terms, config):
    return (config.bone_weight * terms["bones"] + config.angle_weight * terms["angles"]
            + config.skating_weight * terms["skating"] + config.floor_weight * terms["floor"])


def losses(model, initial, future, mask, contacts, limits, config):
    """Loss terms per the paper (summed squared error and KL per sample), the contact logits' cross-entropy,
    and the realism terms on the reconstruction (its planted feet: the labels) and on the prior sample
    (its planted feet: its own predictions)."""
    decoded = model(initial, future, mask)
    squared = (decoded.reconstruction - future) ** 2
    mask = masks.per_coordinate(mask)
    known = (squared * mask).flatten(1).sum(-1).mean()
    unknown = (squared * (1 - mask)).flatten(1).sum(-1).mean()
    kl = kl_divergence(decoded.posterior, decoded.prior).mean()
    contact = torch.nn.functional.binary_cross_entropy_with_logits(
        decoded.contacts, contacts, reduction="none").flatten(1).sum(-1).mean()
    realism_now = realism_terms(decoded.reconstruction, initial, future, contacts, limits)
    realism_prior = realism_terms(decoded.prior_motion, initial, future,
                                  torch.sigmoid(decoded.prior_contacts).detach(), limits)
    total = (known + unknown + config.beta * kl + config.contact_weight * contact
             + weighted_realism(realism_now, config) + config.prior_realism_share * weighted_realism(realism_prior, config))
    parts = {"known": known.item(), "unknown": unknown.item(), "kl": kl.item(), "contact": contact.item()}
    parts.update({name: value.item() for name, value in realism_now.items()})
    parts.update({"prior_" + name: value.item() for name, value in realism_prior.items()})
    return total, parts


def completion_losses(model, initial, future, mask, contacts, limits, config):
    """Second-stage loss: ``root_and_body_error`` plus the realism terms of the completed decodings
    (planted feet: the labels), with the first stage frozen and without dropout.

    Most of the batch is decoded from posterior samples; ``completion_mean_share`` of it from
    the prior mean, the model's point prediction, which the stage otherwise never sees (trained on
    posterior samples alone, completing the prior mean's decode added up to 9 mm to its
    final-frame error).
    """
    given = future * masks.per_coordinate(mask)
    model.eval()
    with torch.no_grad():
        decoded = model(initial, future, mask).reconstruction
        means = round(config.completion_mean_share * len(initial))
        if means:
            decoded[:means] = model.sample(initial[:means], given[:means], mask[:means], 1, use_mean=True,
                                           decoded_only=True)[:, 0]
    model.train()
    completed = model.complete(decoded[:, None], initial, given, mask)[:, 0]
    error = root_and_body_error(completed, future).mean()
    terms = realism_terms(completed, initial, future, contacts, limits)
    return error + weighted_realism(terms, config), {"completion": error.item(),
                                                     **{name: value.item() for name, value in terms.items()}}


def root_and_body_error(motion, truth):
    """Squared error (B,) of motions (B, T, J, 3), summed per sample: the root's, and the other
    joints' relative to the root, so a body is scored on its pose apart from where its root went
    (scored in absolute positions, the root's error spread over every joint)."""
    difference = motion - truth
    root = difference[..., :1, :]
    return (torch.cat([root, difference[..., 1:, :] - root], dim=-2) ** 2).flatten(1).sum(-1)


def freeze_first_stage(model):
    """Only the completion stage trains in the second stage."""
    for name, parameter in model.named_parameters():
        parameter.requires_grad_(name.startswith("completion_"))


def stage_learning_rate(step, config):
    """The learning rate of either stage at an overall step."""
    if step < config.steps:
        return learning_rate(step, config.learning_rate, config.warmup, config.cycle, config.restart_peak)
    return learning_rate(step - config.steps, config.completion_learning_rate, config.warmup // 3,
                         config.completion_steps)


@torch.no_grad()
def validate(model, windows, mask, samples=10, batch=64, seed=0):
    """Best-of-``samples`` ADE (DLow protocol, metres) of prior samples, over validation windows and masks.

    Its own generator, so validating does not change the training run's random stream.
    """
    model.eval()
    generator = torch.Generator().manual_seed(seed)
    errors = []
    for start in range(0, len(windows), batch):
        motion = torch.from_numpy(windows[start:start + batch])
        known = torch.from_numpy(mask[start:start + batch])
        initial, future = motion[:, 0], motion[:, 1:]
        predictions = model.sample(initial, future * known[..., None], known, samples, generator=generator)
        truth = torch.from_numpy(metrics.to_protocol(future.numpy()))
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
    parser.add_argument("--data", nargs="+", default=[str(root) for root in dataset.DATA_ROOTS])
    parser.add_argument("--steps", type=int, default=TrainConfig.steps, help="first-stage steps")
    parser.add_argument("--completion-steps", type=int, default=TrainConfig.completion_steps)
    parser.add_argument("--init", help="first-stage weights (.npz from this command) to start the second stage from")
    parser.add_argument("--batch", type=int, default=TrainConfig.batch)
    parser.add_argument("--seed", type=int, default=TrainConfig.seed)
    parser.add_argument("--out", default=str(weights.MODEL_WEIGHTS), help="where the best model goes")
    parser.add_argument("--limits", default=str(realism.ANGLE_LIMITS),
                        help="where the joint-angle limits fitted on the training poses go")
    parser.add_argument("--checkpoint", default=str(checkpoints.default_path("trajevae")))
    parser.add_argument("--fresh", action="store_true", help="ignore an existing checkpoint")
    parser.add_argument("--threads", type=int, default=0, help="torch threads (0: all cores)")
    args = parser.parse_args(argv)
    config = TrainConfig(steps=args.steps, completion_steps=args.completion_steps, batch=args.batch, seed=args.seed)
    model_config = ModelConfig()
    if args.threads:
        torch.set_num_threads(args.threads)

    clips, errors = dataset.load_clips(args.data)
    for error in errors:
        print(f"skipped: {error}", file=sys.stderr)
    manifest = dataset.read_manifest()
    train_clips, validation_clips = dataset.split_by_subject(clips, manifest)
    sampler = WindowSampler(train_clips, model_config.frames)
    Path(args.limits).parent.mkdir(parents=True, exist_ok=True)
    Path(args.limits).write_text(json.dumps(realism.fit_angle_limits(sampler.motion), indent=1))
    limits = realism.load_angle_limits(args.limits)
    val_windows, val_mask = validation_set(validation_clips, model_config.frames)
    print(f"training windows {len(sampler)} from {len(train_clips)} clips; "
          f"validation windows {len(val_windows)} from {len(validation_clips)} clips "
          f"({', '.join(dataset.VALIDATION_SUBJECTS)})", flush=True)

    torch.manual_seed(config.seed)
    rng = np.random.default_rng(config.seed)
    model = TrajeVAE(model_config)
    optimizer = torch.optim.Adam(model.parameters(), lr=config.learning_rate, betas=(0.9, 0.99))
    print(f"TrajeVAE {parameter_count(model):,} parameters; {model_config}", flush=True)
    run = checkpoints.RunState(args.checkpoint, model, optimizer, rng)
    if args.init:
        state, meta = weights.load_state(args.init)
        missing, unexpected = model.load_state_dict(
            {name: value for name, value in state.items() if not name.startswith("completion_")}, strict=False)
        if unexpected or not all(name.startswith("completion_") for name in missing):
            parser.error(f"{args.init} is not a TrajeVAE of this configuration")
        run.step, run.elapsed = config.steps, 60 * (meta.get("first_stage_minutes") or meta["training_minutes"])
        print(f"second stage from the first stage's weights in {args.init}", flush=True)
    elif not args.fresh and run.resume():
        print(f"resumed from {args.checkpoint} at step {run.step}", flush=True)
    if run.step > config.steps:  # resumed inside the second stage, its random state restored
        freeze_first_stage(model)

    model.train()
    started, running = time.time() - run.elapsed, {}
    total_steps = config.steps + config.completion_steps
    first_stage_minutes = run.elapsed / 60 if run.step >= config.steps else None
    pace_since = (run.step, run.elapsed)
    while run.step < total_steps:
        if run.step == config.steps:  # the second stage starts from the first stage's weights and its own seed
            freeze_first_stage(model)
            rng.bit_generator.state = np.random.default_rng(config.seed + 1).bit_generator.state
            torch.manual_seed(config.seed + 1)
            first_stage_minutes, running, pace_since = run.elapsed / 60, {}, (run.step, run.elapsed)
        motion, mask, contacts = training_batch(sampler, config, model_config.frames, rng)
        for group in optimizer.param_groups:
            group["lr"] = stage_learning_rate(run.step, config)
        stage_losses = losses if run.step < config.steps else completion_losses
        total, parts = stage_losses(model, motion[:, 0], motion[:, 1:], mask, contacts, limits, config)
        optimizer.zero_grad()
        total.backward()
        torch.nn.utils.clip_grad_norm_(model.parameters(), 100.0)
        optimizer.step()
        run.step += 1
        checkpoints.smooth(running, parts)
        run.elapsed = time.time() - started
        stage_end = run.step in (config.steps, total_steps)
        if run.step % 50 == 0 or stage_end:
            print(checkpoints.progress_line(run.step, total_steps, running, run.elapsed, pace_since), flush=True)
        if run.step % config.validate_every == 0 or stage_end:
            error = validate(model, val_windows, val_mask)
            run.history.append({"step": run.step, "validation_ade_m": error, "minutes": run.elapsed / 60})
            marker = ""
            if error < run.best:
                run.best, marker = error, " (best, saved)"
                weights.save(args.out, model, model_config, {
                    "train": asdict(config), "step": run.step, "validation_ade_m": error,
                    "training_minutes": run.elapsed / 60,
                    "first_stage_minutes": run.elapsed / 60 if first_stage_minutes is None else first_stage_minutes,
                    "validation_subjects": list(dataset.VALIDATION_SUBJECTS),
                    "parameters": parameter_count(model)})
            print(f"validation: best-of-10 ADE {error:.4f} m{marker}", flush=True)
        if run.step % config.checkpoint_every == 0 or stage_end:
            run.save()
    print(f"done: {run.step} steps in {run.elapsed / 60:.1f} min, "
          f"best validation error {run.best:.4f} m -> {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
