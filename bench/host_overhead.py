"""Host time per evaluation outside the simulator, by stage, for paper-like 7^3 robots.

    python bench/host_overhead.py [--robots 60] [--repeats 5] [--worlds land,water]
                                  [--modulus 1e5] [--seed 0] [--threads 1] [--clock cpu|wall]

Random genomes of the paper presets' encoding as it was when this bench was written (a 7^3
workspace, the ``evosoro-bounded`` control mapping, which the presets have since replaced by
``evosoro-logistic``, and the ``evosoro`` body rule: every body holds at least 30% of the
workspace; kept so that its figures stay comparable) go through ``worker.evaluate.evaluate_batch`` exactly as
a worker runs them, in the paper's model, one batch of ``--robots`` tasks per world. The
simulation is one cycle capped at a few milliseconds: the kernel's time is measured and left
out, so the duration changes nothing below.

Each stage is timed by wrapping the function that does it where the worker's code looks it
up (exclusive times: a stage called inside another is not counted twice):

- decode: ``Task.from_json`` (the genome's JSON into CPPNs happens in develop's caller: other);
- develop: ``evolution.genotype.develop`` (both CPPNs expressed, the body's component kept);
- to_scene: ``evolution.evaluation.evaluation_scenes`` (the phenotype's arrays into scene dicts);
- parse: ``sim.scene.parse_scene`` as the engine calls it (validation, the arrays back);
- build: ``sim.system.build_robot`` as the engine calls it (lattice, constants, the water
  mesh, the contact neighbourhoods);
- descriptors: ``worker.tasks._descriptors`` (symmetry, branching, shape entropy);
- other: the rest of ``evaluate_batch`` outside the kernel (the result dicts, the phenotype's
  hash and summary, packing the robots, reading the results back).

Printed per world: milliseconds per evaluation (this thread's CPU time by default: what a
worker's core spends; ``--clock wall`` for elapsed time), the median over ``--repeats``
batches of each stage, and how many times per evaluation the genome was developed and the body's
components labelled (``scipy.ndimage.label`` or the flood fill of ``sim.system``). The CPU
and the load average are printed beside them: compare runs made on the same machine at
similar load only.
"""

from __future__ import annotations

import argparse
import importlib
import os
import platform
import statistics
import subprocess
import time
from collections import defaultdict
from contextlib import contextmanager

import numpy as np

from softevo.evolution import environments as worlds
from softevo.evolution.evaluation import EvaluationSpec
from softevo.evolution.genotype import EncodingConfig, random_viable
from softevo.worker.evaluate import evaluate_batch
from softevo.worker.tasks import Task

PAPER_ENCODING = EncodingConfig(
    workspace=(7, 7, 7), control_mapping="evosoro-bounded", body_rule="evosoro"
)
PAPER_MODEL = "voxcad-land-water"
ENGINES = ("softevo.sim.result", "softevo.sim.numba_engine", "softevo.sim.engine")  # where the
# numba engine looks up parse_scene and build_robot: now, and in older versions
STAGES = {  # name: [(module, attribute)] where the worker's code looks the function up
    "decode": [("softevo.worker.tasks", "Task.from_json")],
    "develop": [("softevo.evolution.genotype", "develop")],
    "to_scene": [("softevo.evolution.evaluation", "evaluation_scenes")],
    "parse": [(engine, "parse_scene") for engine in ENGINES],
    "build": [(engine, "build_robot") for engine in ENGINES],
    "descriptors": [("softevo.worker.tasks", "_descriptors")],
    "simulator": [("softevo.sim.kernels", "run_batch")],
}
COUNTED = {  # name: [(module, attribute)] of functions counted, not timed
    "labels": [("scipy.ndimage", "label"), ("softevo.sim.system", "_largest_component_mask")],
}
SHOWN = ("decode", "develop", "to_scene", "parse", "build", "descriptors", "other")


class StageClock:
    """Exclusive seconds and calls per stage of wrapped functions (a stage that runs inside
    another is taken out of the outer one's time), on ``clock`` (``time.thread_time``: CPU
    seconds of this thread, which a busy machine's other processes disturb less than
    ``time.perf_counter``'s wall-clock seconds)."""

    def __init__(self, clock=time.thread_time) -> None:
        self.clock = clock
        self.seconds: dict[str, float] = defaultdict(float)
        self.calls: dict[str, int] = defaultdict(int)
        self._inner: list[float] = []

    def count(self, name: str, function):
        def counted(*args, **kwargs):
            self.calls[name] += 1
            return function(*args, **kwargs)

        return counted

    def wrap(self, name: str, function):
        def timed(*args, **kwargs):
            self._inner.append(0.0)
            start = self.clock()
            try:
                return function(*args, **kwargs)
            finally:
                elapsed = self.clock() - start
                inner = self._inner.pop()
                self.seconds[name] += elapsed - inner
                self.calls[name] += 1
                if self._inner:
                    self._inner[-1] += elapsed

        return timed


def _owner_and_name(module: str, attribute: str):
    owner = importlib.import_module(module)
    *path, name = attribute.split(".")
    for part in path:
        owner = getattr(owner, part)
    return owner, name


@contextmanager
def timed_stages(clock: StageClock):
    """Every stage of ``STAGES`` wrapped by ``clock`` and every function of ``COUNTED``
    counted (where a stage has several places, those the code holds; a stage found nowhere is
    reported), restored on exit."""
    saved = []
    places = [(stage, place, clock.wrap) for stage, places in STAGES.items() for place in places]
    places += [(name, place, clock.count) for name, places in COUNTED.items() for place in places]
    found = set()
    for stage, (module, attribute), wrap in places:
        try:
            owner, name = _owner_and_name(module, attribute)
            original = owner.__dict__[name]
        except (ImportError, AttributeError, KeyError):
            continue
        function = original.__func__ if isinstance(original, classmethod) else original
        wrapped = wrap(stage, function)
        setattr(owner, name, classmethod(wrapped) if isinstance(original, classmethod) else wrapped)
        saved.append((owner, name, original))
        found.add(stage)
    for stage in (*STAGES, *COUNTED):
        if stage not in found:
            print(f"  ({stage}: none of {STAGES.get(stage) or COUNTED[stage]} found, not timed)")
    try:
        yield
    finally:
        for owner, name, original in reversed(saved):
            setattr(owner, name, original)


def paper_tasks(world: str, robots: int, modulus: float, seed: int) -> list[dict]:
    """``robots`` JSON tasks of random viable genomes in the paper's encoding and model, one
    cycle capped at 5 ms of simulated time."""
    rng = np.random.default_rng(seed)
    tasks = []
    for k in range(robots):
        genome, _ = random_viable(rng, PAPER_ENCODING)
        spec = EvaluationSpec(world, modulus, 1, model=PAPER_MODEL, max_seconds=0.005,
                              encoding=PAPER_ENCODING)
        task = Task.from_genome(genome, spec, id=k)
        tasks.append(task.to_json())
    return tasks


CLOCKS = {"cpu": time.thread_time, "wall": time.perf_counter}


def measure(tasks: list[dict], threads: int, clock_name: str = "cpu") -> dict[str, float]:
    """Milliseconds per evaluation of each stage (and per-evaluation counts) for one batch."""
    clock = StageClock(CLOCKS[clock_name])
    with timed_stages(clock):
        start = clock.clock()
        evaluate_batch(tasks, threads=threads)
        total = clock.clock() - start
    n = len(tasks)
    row = {stage: 1e3 * clock.seconds[stage] / n for stage in SHOWN if stage != "other"}
    named = sum(clock.seconds[stage] for stage in STAGES)
    row["other"] = 1e3 * (total - named) / n
    row["host"] = 1e3 * (total - clock.seconds["simulator"]) / n
    row["simulator"] = 1e3 * clock.seconds["simulator"] / n
    row["develops"] = clock.calls["develop"] / n
    row["labellings"] = clock.calls["labels"] / n
    return row


def machine() -> str:
    cpu = platform.processor() or platform.machine()
    try:
        lines = subprocess.run(["lscpu"], capture_output=True, text=True, check=False).stdout
        cpu = next((line.split(":", 1)[1].strip() for line in lines.splitlines()
                    if line.startswith("Model name")), cpu)
    except OSError:
        pass
    return f"{cpu}, {os.cpu_count()} logical CPUs"


def load() -> str:
    return " ".join(f"{x:.2f}" for x in os.getloadavg())


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--robots", type=int, default=60)
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--worlds", default=",".join(worlds.PAPER))
    parser.add_argument("--modulus", type=float, default=1e5, help="Pa (the paper's S3: 0.1 MPa)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--threads", type=int, default=1)
    parser.add_argument("--clock", choices=tuple(CLOCKS), default="cpu",
                        help="cpu: this thread's CPU time (default); wall: elapsed time")
    args = parser.parse_args()

    print(f"CPU: {machine()}; load average before: {load()}; {args.clock} time")
    columns = (*SHOWN, "host", "simulator")
    print(f"{'world':8s}" + "".join(f"{c:>12s}" for c in columns) + f"{'develops':>10s}{'labels':>8s}"
          + "   (ms per evaluation, medians; counts per evaluation)")
    for world in args.worlds.split(","):
        tasks = paper_tasks(world, args.robots, args.modulus, args.seed)
        evaluate_batch(tasks[:2], threads=args.threads)  # compiled (or loaded) before timing
        rows = [measure(tasks, args.threads, args.clock) for _ in range(args.repeats)]
        median = {key: statistics.median(row[key] for row in rows) for key in rows[0]}
        print(f"{world:8s}" + "".join(f"{median[c]:12.3f}" for c in columns)
              + f"{median['develops']:10.2f}{median['labellings']:8.2f}")
    print(f"load average after: {load()}")


if __name__ == "__main__":
    main()
