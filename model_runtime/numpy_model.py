"""TrajeVAE and the diverse sampler at inference in plain numpy, from the same .npz weights.

Blender ships numpy but not torch, and extensions may not download code at
run time, so the add-on runs this path; torch is needed only for training.
It mirrors ``model.TrajeVAE`` and ``sampler.DiverseSampler`` in eval mode
(tests check they agree).
"""

import io
import json
import zipfile
import zlib
from pathlib import Path

import numpy as np

from . import joint_angles, selection
from .dct import dct_matrix
from .masks import body_steps, following_given_feet, per_coordinate
from .skeleton import NUM_JOINTS, facing_turns, turned, turned_about_root

REINSTALL = "reinstall the TrajeVAE extension"
# What a cut or damaged archive, member or array header raises.
_UNREADABLE = (OSError, EOFError, ValueError, KeyError, NotImplementedError, zipfile.BadZipFile, zlib.error)


class WeightsError(ValueError):
    """A weights file cannot be read; the message names it and says what to do."""


def load_arrays(path, remedy=REINSTALL):
    """({name: float32 array}, meta dict) of a weights .npz (arrays plus the config as JSON).

    Each member is read whole, so its checksum is verified before numpy parses it (``np.load``
    parses first: a flipped bit in an array header raised tokenize.TokenError), and parsed with
    ``allow_pickle=False``: no pickled code is ever loaded. A missing, truncated or corrupt file
    raises WeightsError.
    """
    path = Path(path)
    if not path.is_file():
        raise WeightsError(f"the weights file {path.name} is missing from {path.parent}; {remedy}")
    try:
        with zipfile.ZipFile(path) as archive:
            stored = {name.removesuffix(".npy"): np.lib.format.read_array(io.BytesIO(archive.read(name)),
                                                                          allow_pickle=False)
                      for name in archive.namelist()}
        meta = json.loads(str(stored.pop("__meta__")))
        arrays = {name: array.astype(np.float32) for name, array in stored.items()}
    except _UNREADABLE as error:
        raise WeightsError(f"the weights file {path.name} in {path.parent} is damaged ({error}); {remedy}") from None
    return arrays, meta


def _sinusoids(length, width):
    position = np.arange(length, dtype=np.float32)[:, None]
    rate = np.exp(np.arange(0, width, 2, dtype=np.float32) * (-np.log(10000.0) / width))
    table = np.zeros((length, width), np.float32)
    table[:, 0::2], table[:, 1::2] = np.sin(position * rate), np.cos(position * rate)
    return table


def _leaky(x):
    return np.maximum(x, 0.1 * x)  # LeakyReLU(0.1)


class _Weights:
    """Layers looked up by their torch state-dict prefix."""

    def __init__(self, arrays):
        self.arrays = arrays

    def linear(self, prefix, x, weight=".weight", bias=".bias"):
        """One 2-D matrix product for any leading shape (a stacked product loops over the batch);
        ``bias`` None for none."""
        matrix = self.arrays[prefix + weight]
        flat = x.reshape(-1, x.shape[-1]) @ matrix.T
        if bias is not None:
            flat += self.arrays[prefix + bias]
        return flat.reshape(*x.shape[:-1], matrix.shape[0])

    def layer_norm(self, prefix, x, eps=1e-5):
        centred = x - x.mean(-1, keepdims=True)
        variance = np.einsum("...i,...i->...", centred, centred)[..., None] / x.shape[-1]
        centred *= 1.0 / np.sqrt(variance + eps)
        centred *= self.arrays[prefix + ".weight"]
        centred += self.arrays[prefix + ".bias"]
        return centred

    def batch_norm(self, prefix, x, eps=1e-5):
        a = self.arrays
        return ((x - a[prefix + ".running_mean"]) / np.sqrt(a[prefix + ".running_var"] + eps)
                * a[prefix + ".weight"] + a[prefix + ".bias"])

    def mlp(self, prefix, x, final_norm=True):
        """Linear, LayerNorm, LeakyReLU, Linear, then LayerNorm, LeakyReLU if ``final_norm`` (model._mlp)."""
        x = self.linear(prefix + ".3", _leaky(self.layer_norm(prefix + ".1", self.linear(prefix + ".0", x))))
        return _leaky(self.layer_norm(prefix + ".4", x)) if final_norm else x

    def transformer(self, prefix, x, heads):
        """Pre-norm transformer encoder layers (batch_first, ReLU feed-forward) on (B, N, W).

        Residual sums, the ReLU and the attention scale work in place (with the layer norm's
        variance as one einsum, 10 variants of 120 frames came a quarter faster: median 108 -> 80 ms
        on the same loaded machine).
        """
        layer = 0
        while f"{prefix}.layers.{layer}.norm1.weight" in self.arrays:
            p = f"{prefix}.layers.{layer}"
            attended = self._attention(p + ".self_attn", self.layer_norm(p + ".norm1", x), heads)
            attended += x
            x = attended  # a new array: the caller's x is left as it was
            hidden = self.linear(p + ".linear1", self.layer_norm(p + ".norm2", x))
            x += self.linear(p + ".linear2", np.maximum(hidden, 0.0, out=hidden))
            layer += 1
        return x

    def _attention(self, prefix, x, heads):
        batch, tokens, width = x.shape
        size = width // heads
        qkv = self.linear(prefix, x, ".in_proj_weight", ".in_proj_bias").reshape(batch, tokens, 3, heads, size)
        q, k, v = np.ascontiguousarray(qkv.transpose(2, 0, 3, 1, 4))  # (B, H, N, size) each, BLAS-ready
        q *= 1.0 / np.sqrt(size)
        scores = q @ k.swapaxes(-1, -2)
        scores -= scores.max(-1, keepdims=True)
        np.exp(scores, out=scores)
        scores /= scores.sum(-1, keepdims=True)
        attended = scores @ v
        return self.linear(prefix + ".out_proj", attended.transpose(0, 2, 1, 3).reshape(batch, tokens, width))


class NumpyTrajeVAE:
    """Prior and decoder of TrajeVAE; arrays as in ``model.TrajeVAE`` (float32). ``angle_limits``:
    (low, high) (16,) of the joint-angle limits beside the weights file (``LIMITS_FILE``, fitted on
    its training data), which screen the candidate variants (``selection``), or None."""

    def __init__(self, path, remedy=REINSTALL):
        arrays, self.meta = load_arrays(path, remedy)
        self.angle_limits = read_angle_limits(Path(path).parent / LIMITS_FILE, remedy)
        self.config = self.meta["config"]
        first, latent = arrays["decoder_input.0.weight"], self.config["latent"]  # split as in model.TrajeVAE.prior
        arrays["decoder_input.0.weight_latent"] = np.ascontiguousarray(first[:, :latent])
        arrays["decoder_input.0.weight_condition"] = np.ascontiguousarray(first[:, latent:])
        self.weights = _Weights(arrays)
        self.frames, width = self.config["frames"], self.config["width"]
        self.dct = dct_matrix(self.frames)[: self.config["dct_keep"]].astype(np.float32)
        self.time_code = _sinusoids(self.frames, width)
        self.coefficient_code = _sinusoids(self.config["dct_keep"], width)

    def _mask_input(self, mask):
        """As ``model.TrajeVAE._mask_input``: (B, T, J, 3) -> (B, T, mask_size)."""
        return mask.reshape(*mask.shape[:2], -1)

    def prior(self, initial, trajectories, mask):
        """(mean, log_var) (B, K, latent) and the encoded condition, for initial (B, 17, 3),
        trajectories (B, T, 17, 3) and mask (B, T, 17, 3) or (B, T, 17)."""
        w, heads = self.weights, self.config["heads"]
        turns = self.turns(initial)
        initial, trajectories = turned(initial, turns), turned(trajectories, turns)
        mask = per_coordinate(mask)
        pose_code = w.mlp("pose_encoder", initial.reshape(len(initial), -1).astype(np.float32))
        flat = (trajectories * mask).reshape(*mask.shape[:2], -1)
        condition = w.mlp("frame_encoder", np.concatenate([flat, self._mask_input(mask)], -1).astype(np.float32))
        tokens = np.concatenate([condition, np.broadcast_to(pose_code[:, None], condition.shape)], -1)
        tokens = w.transformer("frame_transformer", tokens + self.time_code, heads)
        coefficients = self.dct @ tokens  # (K, T) @ (B, T, W)
        coefficients = w.transformer("coefficient_transformer", coefficients + self.coefficient_code, heads)
        out = w.linear("prior_head", w.transformer("prior_transformer", coefficients, heads))
        mean, log_var = np.split(out, 2, axis=-1)
        given = np.concatenate([_given_steps(initial, trajectories, mask), self._mask_input(mask)], -1)
        frames = np.concatenate([condition, np.broadcast_to(pose_code[:, None], condition.shape), given], -1)
        condition_term = w.linear("decoder_input.0", frames.astype(np.float32), ".weight_condition")
        steps = body_steps(given[..., NUM_JOINTS * 3:NUM_JOINTS * 6].reshape(*mask.shape[:2], NUM_JOINTS, 3), mask,
                           self.config.get("feet_lead", False))
        return mean, np.clip(log_var, -10.0, 10.0), (initial, condition_term, steps) + turns

    def decode(self, z, encoded):
        """Poses (B, T, 17, 3) and foot contact logits (B, T, C) from latents (B, K, latent) and the
        encoded condition of ``prior`` (which carries the condition's share of the first layer, as in
        ``model.TrajeVAE.decode``)."""
        w = self.weights
        initial, condition_term, steps, cos, sin = encoded
        in_time = self.dct.T @ z.astype(np.float32)  # (T, K) @ (B, K, latent)
        first = w.linear("decoder_input.0", in_time, ".weight_latent", bias=None) + condition_term
        first = w.linear("decoder_input.3", _leaky(w.layer_norm("decoder_input.1", first)))
        hidden = w.transformer("decoder_transformer", first + self.time_code, self.config["heads"])
        output = w.linear("decoder_output.2", _leaky(w.linear("decoder_output.0", hidden)))
        coords, turning = NUM_JOINTS * 3, self.config.get("heading_channel", False)
        offsets = output[..., :coords].reshape(*hidden.shape[:2], NUM_JOINTS, 3)
        poses = initial[:, None] + np.cumsum(offsets + steps, axis=1)
        if turning:
            heading = np.cumsum(output[..., -1], axis=1)
            poses = turned_about_root(poses, (np.cos(heading), np.sin(heading)))
        return turned(poses, (cos, sin), back=True), output[..., coords:output.shape[-1] - turning]

    def sample(self, initial, trajectories, mask, count, rng, scale=1.0, sampler=None, keep_given=True,
               screen_given=True, decoded_only=False):
        """``count`` motions per condition (B, count, T, 17, 3) and how surely each foot is planted on
        each frame (B, count, T, 2) in [0, 1], right then left: prior samples (where joints are given,
        the most plausible of a larger pool), or with the diverse sampler given, distinct plausible
        ones from a pool of its draws and the prior's; see ``selection``.

        Motions go through the completion stage (``complete``) unless ``decoded_only``. ``keep_given``
        sets known joints exactly to their given positions; without it they are the decoder's own
        close fit, which blends without a step where the given frames end.
        ``screen_given`` False draws plain prior samples even where joints are given (a motion's
        continuation, which follows its own carried frames, at half the cost).
        """
        mask = per_coordinate(mask)
        mean, log_var, encoded = self.prior(initial, trajectories, mask)
        screened = mask.reshape(len(mask), -1).any(axis=1) & screen_given
        if sampler is not None:
            prior_draws = selection.PRIOR_POOL_FACTOR * count
            z = np.concatenate([sampler.latents(mean, log_var, selection.POOL_FACTOR * count, rng, scale),
                                self._prior_latents(mean, log_var, prior_draws, rng, scale)], axis=1)
            draws = z.shape[1]
        else:
            draws = selection.GIVEN_POOL_FACTOR * count if screened.any() else count
            z = self._prior_latents(mean, log_var, draws, rng, scale)
        encoded = tuple(np.repeat(part, draws, axis=0) for part in encoded)
        motion, logits = self.decode(z.reshape(-1, *mean.shape[1:]), encoded)
        motion = motion.reshape(len(initial), draws, -1, NUM_JOINTS, 3)
        planted = (1.0 / (1.0 + np.exp(-logits))).reshape(len(initial), draws, motion.shape[2], -1)
        if not decoded_only:  # screened as completed, with the known joints as decoded (``selection``)
            motion = self.complete(motion, initial, trajectories, mask, keep_given=False)
        if sampler is not None:
            chosen = [selection.distinct_plausible(m, i, count, t, k, self.angle_limits)
                      for m, i, t, k in zip(motion, initial, trajectories, mask)]
        else:
            chosen = [selection.most_plausible(m, i, count, t, k, self.angle_limits) if s and draws > count
                      else np.arange(count)
                      for m, i, t, k, s in zip(motion, initial, trajectories, mask, screened)]
        motion = np.stack([m[c] for m, c in zip(motion, chosen)])
        planted = np.stack([p[c] for p, c in zip(planted, chosen)])
        return (_with_given_joints(motion, trajectories, mask) if keep_given else motion), planted

    def complete(self, motion, initial, trajectories, mask, keep_given=True):
        """Decoded motions (B, count, T, 17, 3) through the completion stage, as ``model.TrajeVAE.complete``."""
        w = self.weights
        mask = per_coordinate(mask)
        motion = following_given_feet(motion, trajectories, mask)
        turns = self.turns(initial)
        pinned = _with_given_joints(motion, trajectories, mask)
        seen, initial = turned(pinned, turns), turned(initial, turns)
        count, frames = motion.shape[1], mask.shape[1]
        relative = (seen - initial[:, None, None]).reshape(len(motion), count, frames, -1)
        pose = np.broadcast_to(initial.reshape(len(motion), 1, 1, -1), relative.shape)
        joint_known = self._mask_input(mask)
        known = np.broadcast_to(joint_known[:, None], (len(motion), count) + joint_known.shape[1:])
        hidden = w.mlp("completion_input", np.concatenate([relative, pose, known], -1).astype(np.float32),
                       final_norm=False)
        hidden = w.transformer("completion_transformer", hidden.reshape(-1, frames, hidden.shape[-1]) + self.time_code,
                               self.config["heads"])
        displacement = turned(w.linear("completion_output", hidden).reshape(motion.shape), turns, back=True)
        return (pinned if keep_given else motion) + displacement * (1.0 - mask[:, None])

    def turns(self, initial):
        """As ``model.TrajeVAE.turns``: (cos, sin) (B,) into the frame the network sees."""
        if self.config.get("facing_frame", False):
            return facing_turns(initial)
        return np.ones(len(initial), initial.dtype), np.zeros(len(initial), initial.dtype)

    @staticmethod
    def _prior_latents(mean, log_var, count, rng, scale):
        """z (B, count, K, latent) = prior mean + scale * sigma * eps."""
        noise = rng.standard_normal((len(mean), count) + mean.shape[1:]).astype(np.float32)
        return mean[:, None] + scale * np.exp(0.5 * log_var)[:, None] * noise


def _with_given_joints(motion, trajectories, mask):
    """As ``model.with_given_joints``: motion (B, count, T, 17, 3) with the known coordinates
    (mask (B, T, 17, 3)) set to the given positions (B, T, 17, 3)."""
    return np.where(mask[:, None] > 0, trajectories[:, None], motion)


def read_angle_limits(path, remedy=REINSTALL):
    """(low, high) (16,) of a weights folder's joint-angle limits, None where it has none;
    WeightsError (one sentence naming the file) where they cannot be read or are for other angles."""
    if not path.exists():
        return None
    try:
        return joint_angles.limit_arrays(joint_angles.read_limits(path))
    except (OSError, ValueError, KeyError, TypeError) as error:
        raise WeightsError(f"the joint-angle limits {path.name} in {path.parent} cannot be used "
                           f"({type(error).__name__}: {error}); {remedy}") from None


def _given_steps(initial, trajectories, mask):
    """As ``TrajeVAE.given_steps``: (B, T, 2 * 17 * 3), for a mask (B, T, 17, 3)."""
    relative = (trajectories - initial[:, None]) * mask
    before = np.concatenate([np.zeros_like(relative[:, :1]), relative[:, :-1]], axis=1)
    known_before = np.concatenate([np.ones_like(mask[:, :1]), mask[:, :-1]], axis=1)
    steps = (relative - before) * (mask * known_before)
    return np.concatenate([relative.reshape(*mask.shape[:2], -1), steps.reshape(*mask.shape[:2], -1)], -1)


class NumpySampler:
    """The diverse sampler's latents, as ``sampler.DiverseSampler.latents`` in eval mode."""

    def __init__(self, path, remedy=REINSTALL):
        arrays, self.meta = load_arrays(path, remedy)
        self.config = self.meta["config"]
        self.weights = _Weights(arrays)

    def standardised(self, prior_mean, prior_log_var, uniform):
        """(mean, log_var) (B, count, latent_size) from Gumbel uniforms (B, count, bases)."""
        w, c = self.weights, self.config
        features = np.concatenate([prior_mean.reshape(len(prior_mean), -1), prior_log_var.reshape(len(prior_mean), -1)], -1)
        features = _leaky(w.linear("condition.2", _leaky(w.linear("condition.0", features))))
        bases = np.tanh(w.batch_norm("bases.1", w.linear("bases.0", features)))
        bases = bases.reshape(len(features), c["bases"], c["base_width"])
        logits = -np.log(-np.log(np.clip(uniform, 1e-9, 1 - 1e-9))) / c["temperature"]
        weights = np.exp(logits - logits.max(-1, keepdims=True))
        points = (weights / weights.sum(-1, keepdims=True)) @ bases
        head = lambda p: w.linear(p + ".3", np.tanh(w.batch_norm(p + ".1", w.linear(p + ".0", points))))
        return head("mean_head"), np.clip(head("log_var_head"), -10.0, 10.0)

    def latents(self, prior_mean, prior_log_var, count, rng, scale=1.0):
        """z (B, count, K, latent) in the prior's space: mu + scale * sigma * (mean_k + sigma_k * eps)."""
        batch = len(prior_mean)
        uniform = rng.random((batch, count, self.config["bases"]))
        mean, log_var = self.standardised(prior_mean, prior_log_var, uniform)
        standard = mean + np.exp(0.5 * log_var) * rng.standard_normal(mean.shape)
        standard = standard.reshape(batch, count, *prior_mean.shape[1:])
        return (prior_mean[:, None] + scale * np.exp(0.5 * prior_log_var)[:, None] * standard).astype(np.float32)


# A weights folder's files (``weights`` names them too).
MODEL_FILE, SAMPLER_FILE, LIMITS_FILE = "trajevae.npz", "sampler.npz", "angle_limits.json"
# What a network whose arrays do not fit its configuration raises on its first run.
_MISFIT = (KeyError, ValueError, IndexError, TypeError)


def load_folder(folder, remedy=REINSTALL):
    """(model, sampler or None) of a weights folder, each checked by a trial run of one condition:
    arrays that do not fit the configuration, a sampler made for another model, or non-finite
    numbers raise WeightsError (one sentence naming the folder)."""
    folder = Path(folder)
    if not folder.is_dir():
        raise WeightsError(f"the weights folder {folder} does not exist")
    model = _tried(lambda: NumpyTrajeVAE(folder / MODEL_FILE, remedy), None,
                   f"the model in {folder} ({MODEL_FILE})", "does not fit its own configuration", remedy)
    sampler = None
    if (folder / SAMPLER_FILE).exists():
        sampler = _tried(lambda: NumpySampler(folder / SAMPLER_FILE, remedy), model,
                         f"the diverse sampler in {folder} ({SAMPLER_FILE})", "was not trained for its model", remedy)
    return model, sampler


def _tried(load, model, name, misfit, remedy):
    """The network ``load`` gives, after one trial sampling (with ``model``'s prior where it is a
    sampler); WeightsError saying ``name`` and ``misfit`` where it fails, or that it holds
    non-finite numbers."""
    try:
        network = load()
        trial = model or network
        frames = trial.config["frames"]
        motion, planted = trial.sample(np.zeros((1, NUM_JOINTS, 3), np.float32),
                                       np.zeros((1, frames, NUM_JOINTS, 3), np.float32),
                                       np.zeros((1, frames, NUM_JOINTS), np.float32), 2, np.random.default_rng(0),
                                       sampler=network if model else None)
    except WeightsError:
        raise
    except _MISFIT as error:
        raise WeightsError(f"{name} {misfit} ({type(error).__name__}: {error}); {remedy}") from None
    arrays = network.weights.arrays.values()
    if not (np.isfinite(motion).all() and np.isfinite(planted).all() and all(np.isfinite(a).all() for a in arrays)):
        raise WeightsError(f"{name} holds non-finite numbers; {remedy}")
    return network
