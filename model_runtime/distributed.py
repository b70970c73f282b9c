"""Data-parallel training across processes, as torchrun starts them; one process when not.

Each process trains on its GPU where there is one, else on the CPU. Under ``torchrun``
(RANK and WORLD_SIZE in the environment) every process runs the
same training command: gradients are averaged by DistributedDataParallel (gloo on
CPUs, nccl on GPUs), each process draws its own windows, so the global batch is
the per-process batch times the processes, and only rank 0 logs, validates and
writes files. Random draws come from (seed, stage, step, rank), not from a saved
random state, so a run resumes from its checkpoint with any number of processes.
"""

import os

import numpy as np
import torch
import torch.distributed as dist


class Processes:
    """This process's place among the training processes."""

    def __init__(self):
        self.world = int(os.environ.get("WORLD_SIZE", "1"))
        self.rank = int(os.environ.get("RANK", "0"))
        self.device = torch.device("cpu")
        if torch.cuda.is_available():
            self.device = torch.device("cuda", int(os.environ.get("LOCAL_RANK", "0")))
            torch.cuda.set_device(self.device)
        if self.world > 1:
            dist.init_process_group("nccl" if self.device.type == "cuda" else "gloo")

    @property
    def main(self):
        """Whether this process logs, validates and writes files."""
        return self.rank == 0

    def say(self, *args, **kwargs):
        if self.main:
            print(*args, **kwargs, flush=True)

    def parallel(self, module):
        """``module`` whose backward averages the gradients of its trainable parameters over the
        processes (itself in a single process). Wrap again whenever the trainable set changes."""
        if self.world == 1:
            return module
        return torch.nn.parallel.DistributedDataParallel(
            module, device_ids=[self.device.index] if self.device.type == "cuda" else None)

    def rng(self, seed, stage, step):
        """The numpy generator of one step of one process, and torch seeded alike."""
        torch.manual_seed(int(np.random.SeedSequence([seed, stage, step, self.rank]).generate_state(1)[0]))
        return np.random.default_rng([seed, stage, step, self.rank])

    def share(self, value):
        """Rank 0's ``value`` (any picklable object) on every process."""
        if self.world == 1:
            return value
        box = [value]
        dist.broadcast_object_list(box, src=0)
        return box[0]

    def check_in_step(self, module, step):
        """Raise if the processes' parameters differ (they must stay identical after every step)."""
        if self.world == 1:
            return
        with torch.no_grad():
            flat = torch.cat([p.detach().reshape(-1).double() for p in module.parameters()])
            ramp = torch.linspace(1, 2, len(flat), dtype=torch.float64, device=flat.device)
            weighted = torch.stack([flat.sum(), (flat * ramp).sum()]).to(self.device)
        gathered = [torch.empty_like(weighted) for _ in range(self.world)]
        dist.all_gather(gathered, weighted)
        if any(not torch.equal(gathered[0].cpu(), other.cpu()) for other in gathered[1:]):
            raise RuntimeError(f"the training processes' weights differ after step {step}")

    def close(self):
        """Close the process group once every process has finished its work. A process that closed
        it while rank 0 still validated and wrote its files aborted in gloo's teardown (SIGABRT,
        "terminate called without an active exception"; once in CI)."""
        if self.world > 1:
            dist.barrier()
            dist.destroy_process_group()


def run(train, parser, args):
    """``train(parser, args, processes)`` in this process's place among the training processes,
    the process group closed after it. Not after a failure: closing waits for every process, and one
    that failed leaves the others in a collective, which torchrun ends once this one exits."""
    processes = Processes()
    result = train(parser, args, processes)
    processes.close()
    return result
