"""Diverse sampling from an auxiliary space (Dang et al.) over the frozen TrajeVAE.

From the condition (the learnable prior's mean and log-variance, so it sees
the initial pose and any trajectories) a network makes M basis vectors;
Gumbel-softmax weights combine them into points; a second network maps each
point to a Gaussian in the prior's standardised latent space:
z = mu_prior + sigma_prior * (mean_k + sigma_k * eps). The frozen decoder
turns each z into a motion. Any number of samples; N variants are picked
from a larger pool of the sampler's and the prior's draws (``selection``).
"""

from dataclasses import asdict, dataclass

import numpy as np
import torch
from torch import nn

from . import selection
from .model import repeat_encoded, with_given_joints


@dataclass(frozen=True)
class SamplerConfig:
    bases: int = 40
    base_width: int = 128
    hidden: int = 256
    head_width: int = 64
    temperature: float = 0.85
    latent_size: int = 640  # TrajeVAE dct_keep x latent

    def to_dict(self):
        return asdict(self)


def _head(config):
    return nn.Sequential(nn.Linear(config.base_width, config.head_width), nn.BatchNorm1d(config.head_width),
                         nn.Tanh(), nn.Linear(config.head_width, config.latent_size))


class DiverseSampler(nn.Module):
    def __init__(self, config=SamplerConfig()):
        super().__init__()
        self.config = config
        self.condition = nn.Sequential(nn.Linear(2 * config.latent_size, config.hidden), nn.LeakyReLU(0.1),
                                       nn.Linear(config.hidden, config.hidden), nn.LeakyReLU(0.1))
        self.bases = nn.Sequential(nn.Linear(config.hidden, config.bases * config.base_width),
                                   nn.BatchNorm1d(config.bases * config.base_width), nn.Tanh())
        self.mean_head = _head(config)
        self.log_var_head = _head(config)

    def forward(self, prior_mean, prior_log_var, count, generator=None):
        """Standardised Gaussians for ``count`` samples per condition: (mean, log_var), each (B, count, latent_size)."""
        batch = prior_mean.shape[0]
        features = self.condition(torch.cat([prior_mean.flatten(1), prior_log_var.flatten(1)], dim=-1))
        bases = self.bases(features).view(batch, self.config.bases, self.config.base_width)
        uniform = torch.rand((batch, count, self.config.bases), generator=generator).to(features.device)
        uniform = uniform.clamp(1e-9, 1 - 1e-9)
        gumbel = -torch.log(-torch.log(uniform))
        weights = torch.softmax(gumbel / self.config.temperature, dim=-1)  # constant (uniform) logits
        points = (weights @ bases).flatten(0, 1)
        mean = self.mean_head(points).view(batch, count, -1)
        log_var = self.log_var_head(points).view(batch, count, -1).clamp(-10.0, 10.0)
        return mean, log_var

    def latents(self, prior_mean, prior_log_var, count, generator=None):
        """z (B * count, K, latent) for the TrajeVAE decoder, and the standardised (mean, log_var)."""
        mean, log_var = self(prior_mean, prior_log_var, count, generator)
        return in_prior_space(prior_mean, prior_log_var, mean, log_var, generator), (mean, log_var)


def in_prior_space(prior_mean, prior_log_var, mean, log_var, generator=None):
    """z (B * count, K, latent): a draw of the standardised Gaussians (mean, log_var) (B, count,
    latent_size) that ``DiverseSampler`` gives, in the prior's space (B, K, latent)."""
    noise = torch.randn(mean.shape, generator=generator, dtype=mean.dtype).to(mean.device)
    standard = mean + torch.exp(0.5 * log_var) * noise
    shape = prior_mean.shape
    z = prior_mean[:, None] + torch.exp(0.5 * prior_log_var)[:, None] * standard.view(shape[0], mean.shape[1], *shape[1:])
    return z.flatten(0, 1)


def prior_motions(model, initial, trajectories, mask, count, generator=None, limits=None):
    """``count`` prior samples per condition, completed, known joints as given: (B, count, T, J, 3).

    Where joints are given, the most plausible of ``selection.GIVEN_POOL_FACTOR`` x count completed
    draws, as the add-on does (``limits``: the joint-angle limits it screens with, numpy (low, high));
    with nothing given, plain prior samples.
    """
    screened = [bool(k.any()) for k in mask]
    if not any(screened):
        return model.sample(initial, trajectories, mask, count, generator=generator)
    draws = selection.GIVEN_POOL_FACTOR * count
    motion = model.sample(initial, trajectories, mask, draws, generator=generator, keep_given=False)
    chosen = [selection.most_plausible(m, i, count, t, k, limits) if s else np.arange(count)
              for m, i, t, k, s in zip(motion.numpy(), initial.numpy(), trajectories.numpy(), mask.numpy(), screened)]
    motion = torch.stack([m[torch.from_numpy(c)] for m, c in zip(motion, chosen)])
    return with_given_joints(motion, trajectories, mask)


def sample_motions(model, sampler, initial, trajectories, mask, count, generator=None, limits=None):
    """``count`` diverse motions per condition with the frozen model, completed, known joints as given:
    (B, count, T, J, 3).

    Distinct plausible ones from a completed pool of the sampler's and the prior's draws
    (``selection.POOL_FACTOR`` and ``selection.PRIOR_POOL_FACTOR`` x count), as the add-on does
    (``limits`` as for ``prior_motions``).
    """
    draws, prior_draws = selection.POOL_FACTOR * count, selection.PRIOR_POOL_FACTOR * count
    prior_mean, prior_log_var, encoded = model.prior(initial, trajectories, mask)
    z, _ = sampler.latents(prior_mean, prior_log_var, draws, generator)
    noise = torch.randn((len(initial), prior_draws) + prior_mean.shape[1:], generator=generator).to(prior_mean.device)
    prior_z = prior_mean[:, None] + torch.exp(0.5 * prior_log_var)[:, None] * noise
    z = torch.cat([z.unflatten(0, (len(initial), draws)), prior_z], dim=1).flatten(0, 1)
    pool = draws + prior_draws
    motion = model.decode(z, repeat_encoded(encoded, pool))[0].view(initial.shape[0], pool, -1, *initial.shape[1:])
    motion = model.complete(motion, initial, trajectories, mask, keep_given=False)
    chosen = [selection.distinct_plausible(m, i, count, t, k, limits)
              for m, i, t, k in zip(motion.numpy(), initial.numpy(), trajectories.numpy(), mask.numpy())]
    motion = torch.stack([m[torch.from_numpy(c)] for m, c in zip(motion, chosen)])
    return with_given_joints(motion, trajectories, mask)
