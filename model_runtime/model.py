"""TrajeVAE: motion as pose completion, a transformer CVAE with DCT latents and a learnable prior.

Inputs (all in the window frame of ``data.dataset.windows``: metres, Z up,
initial root at the ground-plane origin):

- initial pose x0 (B, 17, 3)
- future poses X (B, T, 17, 3) (training only)
- known-coordinate mask M (B, T, 17, 3), 1 where a joint coordinate is given
  on a frame (a drawn curve, a key, an end pose, a ground path's horizontal
  position); a joint mask (B, T, 17) stands for all three coordinates
  (``masks.per_coordinate``). Trajectories are X * M.

Prior p(z | X*M, M, x0) and posterior q(z | X*(1-M), 1-M, x0) share the frame
encoder and the first transformers (the paper's design, with the mask given as
input because a zero coordinate is ambiguous). Latents are the first
``dct_keep`` DCT coefficients of the sequence codes. The decoder turns z back
to time, sees the encoded trajectories and initial pose, and predicts
per-frame offsets summed from x0. It also sees, uncompressed, where each known
joint is relative to x0 and its step from the previous frame (where both are
known), and those steps are added to its offsets: a known joint follows its
curve unless the network corrects it. Where the root's horizontal position is
given (a ground path, a root curve), its step is also every unknown joint's
horizontal base step (``body_steps``): the body travels with its hips unless
the network moves it otherwise, so the decoder learns the gait, not the
travel (a torso decoded without it lagged a given ground path by 0.2 m in 1 s).
Under trial (``feet_lead``): where the root's is not given but feet are, the
base step follows the given feet's mean position averaged over about a gait
cycle (README, "Not shipped").

Summed offsets drift, and a body decoded from a prior sample barely follows
its given wrists and feet (elbows 0.2-0.3 m off with the wrists given). A
completion stage therefore sees each decoded motion with its known joints
pinned to their given positions, and moves the other joints by absolute
displacements, not offsets (``complete``; trained after the rest, which stays
frozen, on posterior samples' and the prior mean's decodes; see ``train``).
The decoder also predicts, per frame, whether each foot is planted (logits
(B, T, 2), right then left; trained on ``contacts.foot_contacts`` labels).
With ``facing_frame`` the network works in its initial pose's facing frame:
each condition is turned about Z so that x0 faces +Y (as motion matching
stores its windows) and its decodes are turned back, so callers see the frame
they gave and the network need not learn each motion at every heading
(trained with random turns, as it is, it spent its capacity on them: 800
steps from scratch validated at 0.759 m against 0.786 without).
Native rate: 30 fps; T = 60 (2 s).
"""

import math
from dataclasses import asdict, dataclass

import torch
from torch import nn

from .dct import dct_matrix
from .masks import body_steps, following_given_feet, per_coordinate
from .skeleton import NUM_JOINTS, facing_turns, turned, turned_about_root

DECODE_CHUNK = 128  # sequences decoded at once


@dataclass(frozen=True)
class ModelConfig:
    frames: int = 60
    width: int = 128
    latent: int = 32
    dct_keep: int = 20
    heads: int = 4
    feedforward: int = 256
    frame_layers: int = 2
    coefficient_layers: int = 1
    branch_layers: int = 1
    decoder_layers: int = 2
    completion_layers: int = 2
    dropout: float = 0.0  # in every transformer layer; 0.1 cost a third of each CPU step while the model underfits
    facing_frame: bool = True  # the network sees each condition turned to face +Y (``TrajeVAE.turns``)
    heading_channel: bool = False  # the decoder also turns the body about its hips (``TrajeVAE._decode``)
    feet_lead: bool = False  # unknown joints' base step also follows the given feet (``masks.body_steps``)
    mask_size = NUM_JOINTS * 3  # mask values per frame that the network sees: one per coordinate
    contact_size = 2  # foot contact logits per frame beside the poses: right, left

    @property
    def output_size(self):
        """Decoder outputs per frame: the joints' steps, the contact logits and, with ``heading_channel``,
        the turn rate."""
        return NUM_JOINTS * 3 + self.contact_size + int(self.heading_channel)

    def to_dict(self):
        return asdict(self)

    def network(self):
        """The fields that shape the weights: all but dropout, which only training uses (weights
        trained with one dropout fine-tune with another), the frame the network sees and its base steps."""
        return {name: value for name, value in self.to_dict().items()
                if name not in ("dropout", "facing_frame", "feet_lead")}


def _mlp(inputs, width, outputs, final_norm=True):
    layers = [nn.Linear(inputs, width), nn.LayerNorm(width), nn.LeakyReLU(0.1), nn.Linear(width, outputs)]
    if final_norm:
        layers += [nn.LayerNorm(outputs), nn.LeakyReLU(0.1)]
    return nn.Sequential(*layers)


def _transformer(config, layers):
    layer = nn.TransformerEncoderLayer(config.width, config.heads, config.feedforward, config.dropout,
                                       batch_first=True, norm_first=True)
    return nn.TransformerEncoder(layer, layers, enable_nested_tensor=False)


def _sinusoids(length, width):
    position = torch.arange(length, dtype=torch.float32)[:, None]
    rate = torch.exp(torch.arange(0, width, 2, dtype=torch.float32) * (-math.log(10000.0) / width))
    table = torch.zeros(length, width)
    table[:, 0::2] = torch.sin(position * rate)
    table[:, 1::2] = torch.cos(position * rate)
    return table


@dataclass
class TrainingPass:
    """What one training pass decodes: poses (B, T, J, 3), contact logits (B, T, C), and the
    latent distributions (mean, log_var) (B, K, latent)."""

    reconstruction: torch.Tensor  # from a posterior sample
    contacts: torch.Tensor
    prior_motions: torch.Tensor  # (B, draws, T, J, 3) from prior samples, as the product draws
    prior_contacts: torch.Tensor  # (B, draws, T, C)
    prior: tuple
    posterior: tuple


class TrajeVAE(nn.Module):
    def __init__(self, config=ModelConfig()):
        super().__init__()
        self.config = config
        half = config.width // 2
        coords = NUM_JOINTS * 3
        self.frame_encoder = _mlp(coords + config.mask_size, half, half)
        self.pose_encoder = _mlp(coords, half, half)
        self.frame_transformer = _transformer(config, config.frame_layers)
        self.coefficient_transformer = _transformer(config, config.coefficient_layers)
        self.prior_transformer = _transformer(config, config.branch_layers)
        self.posterior_transformer = _transformer(config, config.branch_layers)
        self.prior_head = nn.Linear(config.width, 2 * config.latent)
        self.posterior_head = nn.Linear(config.width, 2 * config.latent)
        self.decoder_input = _mlp(config.latent + half + half + 2 * coords + config.mask_size, config.width,
                                  config.width, final_norm=False)
        self.decoder_transformer = _transformer(config, config.decoder_layers)
        self.decoder_output = nn.Sequential(nn.Linear(config.width, config.width), nn.LeakyReLU(0.1),
                                            nn.Linear(config.width, config.output_size))
        self.completion_input = _mlp(2 * coords + config.mask_size, config.width, config.width, final_norm=False)
        self.completion_transformer = _transformer(config, config.completion_layers)
        self.completion_output = nn.Linear(config.width, coords)
        for layer in (self.decoder_output[-1], self.prior_head, self.posterior_head, self.completion_output):
            nn.init.zeros_(layer.weight)  # start from a still pose, KL = 0 and no completion
            nn.init.zeros_(layer.bias)
        dct = torch.tensor(dct_matrix(config.frames)[: config.dct_keep], dtype=torch.float32)
        self.register_buffer("dct", dct, persistent=False)  # (K, T)
        self.register_buffer("time_code", _sinusoids(config.frames, config.width), persistent=False)
        self.register_buffer("coefficient_code", _sinusoids(config.dct_keep, config.width), persistent=False)

    def turns(self, initial):
        """The turn about Z (cos, sin) (B,) into the frame the network sees, for initial poses (B, 17, 3):
        with ``facing_frame``, the one that makes each face +Y, as motion matching turns its windows
        (the network then need not learn the same motion at every heading); else none."""
        if self.config.facing_frame:
            return facing_turns(initial)
        return torch.ones_like(initial[:, 0, 0]), torch.zeros_like(initial[:, 0, 0])

    def _mask_input(self, mask):
        """The mask (B, T, J, 3) as the network sees it: (B, T, mask_size)."""
        return mask.flatten(2)

    def _frame_codes(self, values, mask):
        """Per-frame codes (B, T, W/2) of masked positions (B, T, J, 3) and their mask (B, T, J, 3)."""
        return self.frame_encoder(torch.cat([(values * mask).flatten(2), self._mask_input(mask)], dim=-1))

    def _distribution(self, frame_codes, pose_code, branch, head):
        """Mean and log-variance (B, K, latent) of z from per-frame codes."""
        tokens = torch.cat([frame_codes, pose_code[:, None].expand_as(frame_codes)], dim=-1)
        tokens = self.frame_transformer(tokens + self.time_code)
        coefficients = torch.einsum("kt,btw->bkw", self.dct, tokens)
        coefficients = self.coefficient_transformer(coefficients + self.coefficient_code)
        mean, log_var = head(branch(coefficients)).chunk(2, dim=-1)
        return mean, log_var.clamp(-10.0, 10.0)

    def prior(self, initial, trajectories, mask):
        """p(z | trajectories, mask, initial pose): mean and log_var (B, K, latent), and the encoded
        condition that ``decode`` takes (repeat it per sample with ``repeat_encoded``)."""
        return self._prior(initial, trajectories, mask)[:3]

    def _prior(self, initial, trajectories, mask):
        """``prior``'s three results and the initial pose's code (B, W/2), which the posterior shares;
        the encoded condition carries the turn its decodes are turned back by."""
        turns = self.turns(initial)
        initial, trajectories = turned(initial, turns), turned(trajectories, turns)
        mask = per_coordinate(mask)
        pose_code = self.pose_encoder(initial.flatten(1))
        condition = self._frame_codes(trajectories, mask)
        mean, log_var = self._distribution(condition, pose_code, self.prior_transformer, self.prior_head)
        given = torch.cat([self.given_steps(initial, trajectories, mask), self._mask_input(mask)], dim=-1)
        frames = torch.cat([condition, pose_code[:, None].expand(-1, condition.shape[1], -1), given], dim=-1)
        first = self.decoder_input[0]
        condition_term = nn.functional.linear(frames, first.weight[:, self.config.latent:], first.bias)
        steps = body_steps(given[..., NUM_JOINTS * 3:NUM_JOINTS * 6].unflatten(-1, (NUM_JOINTS, 3)), mask,
                           self.config.feet_lead)
        return mean, log_var, (initial, condition_term, steps) + turns, pose_code

    def posterior(self, initial, future, mask, pose_code):
        """q(z | future poses with the known joints hidden): (mean, log_var)."""
        codes = self._frame_codes(turned(future, self.turns(initial)), 1.0 - per_coordinate(mask))
        return self._distribution(codes, pose_code, self.posterior_transformer, self.posterior_head)

    @staticmethod
    def given_steps(initial, trajectories, mask):
        """Known coordinates relative to x0 and their steps from the previous frame: (B, T, 2 * J * 3),
        for a mask (B, T, J, 3).

        Unknown entries are zero; x0 counts as known before the first frame.
        """
        relative = (trajectories - initial[:, None]) * mask
        before = torch.cat([torch.zeros_like(relative[:, :1]), relative[:, :-1]], dim=1)
        known_before = torch.cat([torch.ones_like(mask[:, :1]), mask[:, :-1]], dim=1)
        steps = (relative - before) * (mask * known_before)
        return torch.cat([relative.flatten(2), steps.flatten(2)], dim=-1)

    def decode(self, z, encoded):
        """Poses (B, T, J, 3) and foot contact logits (B, T, contact_size) from latents (B, K, latent)
        and the encoded condition of ``prior``.

        The condition's share of the decoder's first layer comes with ``encoded``, computed once per
        condition rather than once per sample. Large batches go in chunks (``_in_chunks``).
        """
        decoded = _in_chunks(self._decode, z, *encoded)
        coords = NUM_JOINTS * 3
        return decoded[..., :coords].unflatten(-1, (NUM_JOINTS, 3)), decoded[..., coords:]

    def _decode(self, z, initial, condition_term, steps, cos, sin):
        """``decode`` for one chunk, the encoded condition unpacked: poses and logits as (B, T, J * 3 + C),
        the poses turned back from the network's frame.

        The poses are the initial pose plus the summed steps, and with ``heading_channel`` each frame
        turned about the hips by the summed turn rate. In steps of joint positions alone, turning the
        body means moving every joint around the hips together: the shipped weights' samples never
        turn more than 45 degrees in 2 s where the capture does in 23 % of the validation windows, and
        even their posterior's decodes of training windows turn 43 degrees where the capture turns 108.
        Under trial: 2500 steps with the channel validated as without it (best-of-10 ADE 0.734 against
        0.732) and had not yet learned to use it (2 degrees summed over 2 s).
        """
        in_time = torch.einsum("kt,bkl->btl", self.dct, z)
        first = nn.functional.linear(in_time, self.decoder_input[0].weight[:, :self.config.latent]) + condition_term
        hidden = self.decoder_transformer(self.decoder_input[1:](first) + self.time_code)
        output = self.decoder_output(hidden)
        coords = NUM_JOINTS * 3
        poses = initial.flatten(1)[:, None] + torch.cumsum(output[..., :coords] + steps.flatten(2), dim=1)
        poses = poses.unflatten(-1, (NUM_JOINTS, 3))
        if self.config.heading_channel:
            heading = torch.cumsum(output[..., -1], dim=1)
            poses = turned_about_root(poses, (torch.cos(heading), torch.sin(heading)))
        poses = turned(poses, (cos, sin), back=True).flatten(2)
        return torch.cat([poses, output[..., coords:coords + self.config.contact_size]], dim=-1)

    def forward(self, initial, future, mask, draws=1):
        """Training pass: a ``TrainingPass`` (a posterior sample's reconstruction and ``draws`` prior
        samples, each with its contact logits, in one decoder batch)."""
        prior_mean, prior_log_var, encoded, pose_code = self._prior(initial, future * per_coordinate(mask), mask)
        post_mean, post_log_var = self.posterior(initial, future, mask, pose_code)
        prior_std = torch.exp(0.5 * prior_log_var)
        z = torch.cat([post_mean + torch.randn_like(post_mean) * torch.exp(0.5 * post_log_var)]
                      + [prior_mean + torch.randn_like(prior_mean) * prior_std for _ in range(draws)])
        motion, contacts = self.decode(z, tuple(torch.cat([part] * (1 + draws)) for part in encoded))
        motion, contacts = motion.unflatten(0, (1 + draws, -1)), contacts.unflatten(0, (1 + draws, -1))
        return TrainingPass(motion[0], contacts[0], motion[1:].transpose(0, 1), contacts[1:].transpose(0, 1),
                            (prior_mean, prior_log_var), (post_mean, post_log_var))

    def complete(self, motion, initial, trajectories, mask, keep_given=True):
        """Decoded samples (B, count, T, J, 3) through the completion stage, for conditions (B, ...).

        The stage sees each sample moved with its given feet (``masks.following_given_feet``) and
        its known joints pinned to their given positions (as ``with_given_joints``), with the initial
        pose and the mask, and displaces the unknown joints. ``keep_given`` returns known joints as
        given, else as decoded and moved (their own close fit). Sequences go in chunks
        (``_in_chunks``), as in ``decode``.
        """
        mask = per_coordinate(mask)
        motion = following_given_feet(motion, trajectories, mask)
        turns = self.turns(initial)
        pinned = with_given_joints(motion, trajectories, mask)
        seen, initial = turned(pinned, turns), turned(initial, turns)
        count = motion.shape[1]
        initial, known = initial.repeat_interleave(count, 0), self._mask_input(mask).repeat_interleave(count, 0)
        frames = torch.cat([(seen.flatten(0, 1) - initial[:, None]).flatten(2),
                            initial.flatten(1)[:, None].expand(-1, known.shape[1], -1), known], dim=-1)
        displacement = turned(_in_chunks(self._displacement, frames).view(motion.shape), turns, back=True)
        return (pinned if keep_given else motion) + displacement * (1.0 - mask[:, None])

    def _displacement(self, frames):
        """The completion stage's displacements (N, T, J * 3) from its per-frame inputs (N, T, 2 * J * 3 + mask_size)."""
        hidden = self.completion_transformer(self.completion_input(frames) + self.time_code)
        return self.completion_output(hidden)

    @torch.no_grad()
    def sample(self, initial, trajectories, mask, count, scale=1.0, generator=None, use_mean=False,
               keep_given=True, decoded_only=False):
        """``count`` motions per condition: (B, count, T, J, 3).

        z = prior mean + scale * sigma * eps; ``use_mean`` decodes the prior mean once per condition;
        ``keep_given`` sets the known joints to their given positions (else the decoder's own fit);
        ``decoded_only`` skips the completion stage (the first stage's own decodes, the diverse
        sampler's training ground).
        """
        prior_mean, prior_log_var, encoded = self.prior(initial, trajectories, mask)
        count = 1 if use_mean else count
        mean, std = prior_mean.repeat_interleave(count, 0), torch.exp(0.5 * prior_log_var).repeat_interleave(count, 0)
        noise = torch.zeros_like(mean) if use_mean else torch.randn(
            mean.shape, generator=generator, dtype=mean.dtype).to(mean.device)
        motion = self.decode(mean + scale * std * noise, repeat_encoded(encoded, count))[0]
        motion = motion.view(initial.shape[0], count, *motion.shape[1:])
        return motion if decoded_only else self.complete(motion, initial, trajectories, mask, keep_given)


@torch.no_grad()
def reconstruct(model, initial, future, mask):
    """The posterior mean's decode, completed, known joints as given: (B, 1, T, J, 3) for the
    whole future poses (B, T, J, 3) and a mask (B, T, J) or (B, T, J, 3).

    An oracle (the posterior sees the future): how much of a motion the latents carry at all,
    the bound that prior samples approach. Where it comes no nearer the capture than the prior
    mean's decode, the latents do not carry the pose.
    """
    trajectories = future * per_coordinate(mask)
    _, _, encoded, pose_code = model._prior(initial, trajectories, mask)
    mean, _ = model.posterior(initial, future, mask, pose_code)
    return model.complete(model.decode(mean, encoded)[0][:, None], initial, trajectories, mask)


def _in_chunks(function, *tensors):
    """``function`` over ``DECODE_CHUNK`` sequences of the tensors (N, ...) at a time, its results
    concatenated: on the CPU that keeps attention in cache (2400 sequences at once ran 1.6-2x
    slower than in chunks of 100-200)."""
    return torch.cat([function(*(tensor[start:start + DECODE_CHUNK] for tensor in tensors))
                      for start in range(0, len(tensors[0]), DECODE_CHUNK)])


def with_given_joints(motion, trajectories, mask):
    """Samples (B, count, T, J, 3) with the known coordinates (mask (B, T, J, 3) or (B, T, J)) set to
    their given positions (B, T, J, 3).

    Pose completion: what was given is kept as given, as every baseline does; the decoder already
    brings the rest of the body along (its residual there is a few centimetres), and
    ``TrajeVAE.complete`` fits the rest to what is pinned.
    """
    return torch.where(per_coordinate(mask)[:, None] > 0, trajectories[:, None], motion)


def repeat_encoded(encoded, count):
    """The encoded condition of ``TrajeVAE.prior`` repeated for ``count`` samples per condition."""
    return tuple(part.repeat_interleave(count, dim=0) for part in encoded)


def kl_divergence(post, prior):
    """KL(q || p) of diagonal Gaussians given as (mean, log_var), summed over latents: (B,)."""
    (mq, lq), (mp, lp) = post, prior
    kl = 0.5 * (lp - lq + (torch.exp(lq) + (mq - mp) ** 2) / torch.exp(lp) - 1.0)
    return kl.flatten(1).sum(-1)


def parameter_count(model):
    return sum(p.numel() for p in model.parameters())
