"""``python -m model_runtime.train_sampler``: train the diverse sampler over the frozen TrajeVAE.

It works on the first stage's decodes; the completion stage comes after, on
the pool the variants are picked from (``sampler.sample_motions``), so the
sampler does not depend on it.

Losses: hinge diversity between the K samples of a condition, a hinge on each
sample's distance to its nearest sibling (the duplicate-aware objective of
../shared/papers/003: a mean-based hinge alone leaves near-duplicates),
best-of-K accuracy, KL of the standardised Gaussians to N(0, I), and realism
terms (GSPS joint-angle limits fitted on the training subjects, rigid bone
lengths, the squared speed of the feet the model predicts planted) so diversity never comes from
broken poses. Half the conditions have
no trajectories (the sampler's main use), half have training masks. Model
selection on the validation clips; the model, its limits and the sampler's
weights are in one weights folder (``--weights``, assets/ unless told). Runs
data-parallel under torchrun as ``train`` does (``distributed``).
"""

import argparse
import json
import sys
import time
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np
import torch

from . import augment, checkpoints, distributed, masks, metrics, realism, weights
from .data import clips, dataset
from .model import parameter_count, repeat_encoded
from .sampler import DiverseSampler, SamplerConfig, in_prior_space
from .skeleton import rigid_bone_lengths
from .train import WindowSampler, add_config_flags, config_from_flags, learning_rate

@dataclass(frozen=True)
class SamplerTrainConfig:
    steps: int = 2000
    batch: int = 16
    samples: int = 10  # K per condition in training; any K at inference
    learning_rate: float = 1e-3
    warmup: int = 200
    diversity_margin: float = 2.0  # hinge threshold eta, in multiples of plain sampling's APD
    diversity_weight: float = 1.0
    duplicate_margin: float = 2.5  # nearest-sibling hinge, in multiples of plain sampling's MPD
    duplicate_weight: float = 40.0
    accuracy_weight: float = 100.0
    kl_weight: float = 1.0
    angle_weight: float = 300.0
    bone_weight: float = 12000.0
    skating_weight: float = 100.0
    empty_mask_share: float = 0.5
    seed: int = 0
    validate_every: int = 250
    checkpoint_every: int = 250


def pairwise_distances(motion):
    """Distances between the K samples of each condition in the DLow protocol: (B, K, K)."""
    relative = (motion[..., 1:, :] - motion[..., :1, :]).flatten(2)
    return torch.cdist(relative, relative)


def nearest_sibling_distances(distances):
    """Each sample's distance to the nearest other sample of its condition: (B, K) from (B, K, K)."""
    itself = torch.eye(distances.shape[-1], dtype=torch.bool, device=distances.device)
    return distances.masked_fill(itself, float("inf")).amin(dim=-1)


def sampler_losses(model, sampler, initial, future, mask, limits, margins, config, generator=None):
    """Weighted total and its parts for one batch; margins = (all-pairs hinge, nearest-sibling hinge) in metres."""
    margin, duplicate_margin = margins
    count = config.samples
    prior_mean, prior_log_var, encoded = model.prior(initial, future * masks.per_coordinate(mask), mask)
    mean, log_var = sampler(prior_mean, prior_log_var, count, generator)  # through forward, as DDP needs
    z = in_prior_space(prior_mean, prior_log_var, mean, log_var, generator)
    motion, contacts = model.decode(z, repeat_encoded(encoded, count))
    motion = motion.view(initial.shape[0], count, *motion.shape[1:])
    planted = torch.sigmoid(contacts.view(*motion.shape[:3], -1)).detach()
    distances = pairwise_distances(motion)
    upper = torch.triu(torch.ones(count, count, dtype=torch.bool, device=initial.device), diagonal=1)
    diversity = torch.relu(margin - distances[:, upper]).mean() / margin
    duplicate = torch.relu(duplicate_margin - nearest_sibling_distances(distances)).mean() / duplicate_margin
    accuracy = ((motion - future[:, None]) ** 2).sum(-1).mean(dim=(2, 3)).min(dim=1).values.mean()
    kl = 0.5 * (mean ** 2 + torch.exp(log_var) - log_var - 1.0).mean()
    angles = realism.angle_limit_loss(motion, limits).mean()
    bones = ((rigid_bone_lengths(motion) - rigid_bone_lengths(initial)[:, None, None]) ** 2).mean()
    skating = realism.planted_skating_loss(motion, initial, planted, clips.NATIVE_FPS).mean() / motion.shape[2]
    total = (config.diversity_weight * diversity + config.duplicate_weight * duplicate
             + config.accuracy_weight * accuracy + config.kl_weight * kl + config.angle_weight * angles
             + config.bone_weight * bones + config.skating_weight * skating)
    parts = {"diversity": diversity.item(), "duplicate": duplicate.item(), "accuracy": accuracy.item(),
             "kl": kl.item(), "angles": angles.item(), "bones": bones.item(), "skating": skating.item(),
             "min_dist": distances[:, upper].min().item()}
    return total, parts


@torch.no_grad()
def plain_diversity(model, windows, count):
    """Mean APD and MPD (DLow protocol) of plain prior sampling with no trajectories over windows
    (N, 1 + T, 17, 3)."""
    device = next(model.parameters()).device
    initial, future = torch.from_numpy(windows[:, 0]).to(device), torch.from_numpy(windows[:, 1:]).to(device)
    empty = torch.zeros(future.shape[:-1], device=device)
    motion = model.sample(initial, future * 0, empty, count, generator=torch.Generator().manual_seed(0),
                          decoded_only=True)
    samples = [metrics.to_protocol(m) for m in motion.cpu().numpy()]
    return tuple(float(value) for value in np.mean([metrics.diversity(s) for s in samples], axis=0))


def main(argv=None):
    parser = argparse.ArgumentParser(prog="python -m model_runtime.train_sampler", description=__doc__)
    dataset.add_data_arguments(parser)
    parser.add_argument("--weights", default=str(weights.ASSETS),
                        help=f"weights folder: its {weights.MODEL_FILE} and {weights.LIMITS_FILE} are read, "
                             f"{weights.SAMPLER_FILE} is written")
    parser.add_argument("--steps", type=int, default=SamplerTrainConfig.steps)
    parser.add_argument("--batch", type=int, default=SamplerTrainConfig.batch, help="conditions per process and step")
    parser.add_argument("--seed", type=int, default=SamplerTrainConfig.seed)
    parser.add_argument("--checkpoint", help="default: one per weights folder in ~/.cache/trajevae/checkpoints")
    parser.add_argument("--fresh", action="store_true", help="ignore an existing checkpoint")
    parser.add_argument("--log-every", type=int, default=50, help="steps between progress lines")
    add_config_flags(parser, SamplerTrainConfig)
    return distributed.run(_train, parser, parser.parse_args(argv))


def _train(parser, args, processes):
    config = config_from_flags(SamplerTrainConfig, args)
    folder = Path(args.weights)
    checkpoint = args.checkpoint or checkpoints.default_path("sampler", folder)
    model, _ = weights.load_model(folder / weights.MODEL_FILE)
    model.to(processes.device)
    for parameter in model.parameters():
        parameter.requires_grad_(False)
    split = dataset.split_from_arguments(parser, args)
    limits_file = folder / weights.LIMITS_FILE
    if not limits_file.exists():
        parser.error(f"{limits_file} is missing: the model's training writes it (python -m model_runtime.train --out {folder})")
    limits = realism.load_angle_limits(limits_file)
    frames = model.config.frames
    windows = WindowSampler(split.train, frames)
    validation = dataset.windows(split.validation, future=frames, stride=30)
    plain_apd, plain_mpd = plain_diversity(model, validation[:64], config.samples)
    margins = (config.diversity_margin * plain_apd, config.duplicate_margin * plain_mpd)
    processes.say(f"hinge margins: all pairs {margins[0]:.3f} m ({config.diversity_margin} x plain APD), "
                  f"nearest sibling {margins[1]:.3f} m ({config.duplicate_margin} x plain MPD); "
                  f"{len(validation)} validation windows; {processes.world} process(es), global batch "
                  f"{config.batch * processes.world}; checkpoint {checkpoint}")

    torch.manual_seed(config.seed)
    sampler_config = SamplerConfig(latent_size=model.config.dct_keep * model.config.latent)
    sampler = DiverseSampler(sampler_config).to(processes.device)
    optimizer = torch.optim.Adam(sampler.parameters(), lr=config.learning_rate)
    processes.say(f"sampler {parameter_count(sampler):,} parameters")
    run = checkpoints.RunState(checkpoint, sampler, optimizer)
    if not args.fresh and run.resume(processes):
        processes.say(f"resumed from {checkpoint} at step {run.step}")
    trained = processes.parallel(sampler)

    def validation_loss():
        sampler.eval()
        generator = torch.Generator().manual_seed(1)
        with torch.no_grad():
            motion = torch.from_numpy(validation).to(processes.device)
            empty = torch.zeros(len(validation), frames, 17, device=processes.device)
            total, parts = sampler_losses(model, sampler, motion[:, 0], motion[:, 1:], empty, limits,
                                          margins, config, generator)
        sampler.train()
        return total.item(), parts

    started, running, interval, first_step = time.time() - run.elapsed, {}, [], run.step
    sampler.train()
    while run.step < config.steps:
        rng = processes.rng(config.seed, 1, run.step)
        motion, _ = windows.sample(config.batch, rng)
        motion = augment.rotate_about_z(motion, rng.uniform(0, 2 * np.pi, config.batch)).astype(np.float32)
        mask = masks.sample_training_masks(config.batch, frames, rng)
        mask[rng.random(config.batch) < config.empty_mask_share] = 0.0
        for group in optimizer.param_groups:
            group["lr"] = learning_rate(run.step, config.learning_rate, config.warmup, config.steps)
        motion, mask = torch.from_numpy(motion).to(processes.device), torch.from_numpy(mask).to(processes.device)
        total, parts = sampler_losses(model, trained, motion[:, 0], motion[:, 1:], mask, limits, margins, config)
        optimizer.zero_grad()
        total.backward()
        optimizer.step()
        processes.check_in_step(sampler, run.step)
        run.step += 1
        checkpoints.smooth(running, parts)
        interval.append(total.item())
        run.elapsed = time.time() - started
        if run.step % args.log_every == 0 or run.step == config.steps:
            processes.say(checkpoints.progress_line(run.step, config.steps, float(np.mean(interval)), running,
                                                    run.elapsed))
            interval = []
        if processes.main and (run.step % config.validate_every == 0 or run.step == config.steps):
            loss, parts = validation_loss()
            run.history.append({"step": run.step, "validation_loss": loss, **parts})
            marker = ""
            if loss < run.best:
                run.best, marker = loss, " (best, saved)"
                weights.save(folder / weights.SAMPLER_FILE, sampler, sampler_config, {
                    "train": asdict(config), "step": run.step, "validation_loss": loss,
                    "hinge_margins_m": margins, "training_minutes": run.elapsed / 60,
                    "processes": processes.world, "parameters": parameter_count(sampler)})
            print(f"validation loss {loss:.4f} " + " ".join(f"{k} {v:.3f}" for k, v in parts.items()) + marker,
                  flush=True)
        if processes.main and (run.step % config.checkpoint_every == 0 or run.step == config.steps):
            run.save()
    if processes.world > 1:
        processes.say(f"{processes.world} processes: weights identical after each of {run.step - first_step} steps")
    processes.say(f"done: {run.step} steps in {run.elapsed / 60:.1f} min -> {folder / weights.SAMPLER_FILE}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
