"""Resumable training state shared by the training commands: checkpoints and progress lines.

Checkpoints hold tensors and JSON strings only, so they load with
torch.load(weights_only=True).
"""

import json
from pathlib import Path

import torch

from .data import dataset


def default_path(name):
    """Checkpoints live beside the motion cache, outside the work tree: ~/.cache/trajevae/checkpoints."""
    return dataset.cache_dir().parent / "checkpoints" / f"{name}.pt"


class RunState:
    """Step, best score, elapsed time, history and random state of one training run."""

    def __init__(self, path, module, optimizer, rng):
        self.path, self.module, self.optimizer, self.rng = Path(path), module, optimizer, rng
        self.step, self.best, self.elapsed, self.history = 0, float("inf"), 0.0, []

    def resume(self):
        """Load the checkpoint if there is one; True when resumed."""
        if not self.path.exists():
            return False
        state = torch.load(self.path, weights_only=True)
        self.module.load_state_dict(state["model"])
        self.optimizer.load_state_dict(state["optimizer"])
        self.step, self.best, self.elapsed = state["step"], state["best"], state["elapsed"]
        self.history = json.loads(state["history"])
        self.rng.bit_generator.state = json.loads(state["rng"])
        torch.set_rng_state(state["torch_rng"])
        return True

    def save(self):
        self.path.parent.mkdir(parents=True, exist_ok=True)
        temporary = self.path.with_suffix(".tmp")
        torch.save({"model": self.module.state_dict(), "optimizer": self.optimizer.state_dict(),
                    "step": self.step, "best": self.best, "elapsed": self.elapsed,
                    "history": json.dumps(self.history), "rng": json.dumps(self.rng.bit_generator.state),
                    "torch_rng": torch.get_rng_state()}, temporary)
        temporary.replace(self.path)


def progress_line(step, total, running, elapsed, since=(0, 0.0)):
    """A one-line progress bar with smoothed loss terms, elapsed time and ETA; the ETA runs at the
    pace since ``since`` (step, elapsed seconds): this session's, or this stage's."""
    eta = (total - step) * (elapsed - since[1]) / max(step - since[0], 1)
    terms = " ".join(f"{name} {value:.3f}" for name, value in running.items())
    return (f"[{'#' * int(30 * step / total):<30}] step {step}/{total} {terms} "
            f"{elapsed / 60:.1f} min, eta {eta / 60:.1f} min")


def smooth(running, parts, momentum=0.98):
    """Exponential moving averages of loss terms, in place."""
    for name, value in parts.items():
        running[name] = momentum * running.get(name, value) + (1 - momentum) * value
