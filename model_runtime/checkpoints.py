"""Resumable training state shared by the training commands: checkpoints and progress lines.

Checkpoints hold tensors and JSON strings only, so they load with
torch.load(weights_only=True). They hold no random state: each step's draws
come from its step number (``distributed.Processes.rng``), so a run resumes
with any number of processes.
"""

import hashlib
import json
from pathlib import Path

import torch

from .data import dataset


def default_path(name, out):
    """A run's checkpoint, beside the motion cache and outside the work tree, one folder per output
    folder ``out``: ~/.cache/trajevae/checkpoints/<digest of out>/<name>.pt."""
    digest = hashlib.sha1(str(Path(out).resolve()).encode()).hexdigest()[:12]
    return dataset.cache_dir().parent / "checkpoints" / digest / f"{name}.pt"


class RunState:
    """Step, best score, elapsed time and history of one training run."""

    def __init__(self, path, module, optimizer):
        self.path, self.module, self.optimizer = Path(path), module, optimizer
        self.step, self.best, self.elapsed, self.history = 0, float("inf"), 0.0, []

    def resume(self, processes):
        """Load the checkpoint if there is one (rank 0 reads it, every process gets it); True when
        resumed."""
        state = torch.load(self.path, map_location="cpu", weights_only=True) if processes.main and self.path.exists() else None
        state = processes.share(state)
        if state is None:
            return False
        self.module.load_state_dict(state["model"])
        self.optimizer.load_state_dict(state["optimizer"])
        self.step, self.best, self.elapsed = state["step"], state["best"], state["elapsed"]
        self.history = json.loads(state["history"])
        return True

    def save(self):
        self.path.parent.mkdir(parents=True, exist_ok=True)
        temporary = self.path.with_suffix(".tmp")
        torch.save({"model": self.module.state_dict(), "optimizer": self.optimizer.state_dict(),
                    "step": self.step, "best": self.best, "elapsed": self.elapsed,
                    "history": json.dumps(self.history)}, temporary)
        temporary.replace(self.path)


def progress_line(step, total, loss, running, elapsed, since=(0, 0.0)):
    """A one-line progress bar with the mean total ``loss`` since the last line, smoothed loss terms,
    elapsed time and ETA; the ETA runs at the pace since ``since`` (step, elapsed seconds): this
    session's, or this stage's."""
    eta = (total - step) * (elapsed - since[1]) / max(step - since[0], 1)
    terms = " ".join(f"{name} {value:.3f}" for name, value in running.items())
    return (f"[{'#' * int(30 * step / total):<30}] step {step}/{total} loss {loss:.3f} {terms} "
            f"{elapsed / 60:.1f} min, eta {eta / 60:.1f} min")


def smooth(running, parts, momentum=0.98):
    """Exponential moving averages of loss terms, in place."""
    for name, value in parts.items():
        running[name] = momentum * running.get(name, value) + (1 - momentum) * value
