"""Coordinator and storage overhead per generation, and local executor throughput.

    python bench/coordinator_overhead.py [--populations 30,100] [--generations 5]
                                         [--cycles 50] [--workspace 7,7,7] [--batch 16]

1. Overhead: the coordinator runs ``--generations`` generations with an executor that
   returns instant results, on a SQLite file: what is left per generation is ask (breeding,
   expression), tell (selection), and the transaction that stores the generation.
2. Evaluation time: one real generation (the initial population) on the local process pool
   over all cores, with paper-like settings (``--cycles``, ``--workspace``); with
   ``--eval-sample N`` only N of its genomes are timed and the time scaled to the population.
3. Share = overhead / evaluation time per generation (target < 2%).
4. Evaluations per second of the local executor with 1 process vs 2 (target >= 1.8x),
   on ``--batch`` random genomes, processes warmed first.
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time
from pathlib import Path

import numpy as np

from softevo.evolution.treatments import Treatment
from softevo.service.runs.coordinator import Coordinator, ask, load_run
from softevo.service.runs.executors import BlockingExecutor, LocalExecutor
from softevo.service.runs.submit import create
from softevo.service.storage import open_database
from softevo.sim.worlds import LAND


class InstantExecutor(BlockingExecutor):
    """Results without simulation: distance from the genome's id (deterministic)."""

    workers = 1

    def evaluate(self, tasks):
        return [
            {
                "id": t["id"],
                "distance": (t["id"] * 0.618) % 1.0,
                "stable": True,
                "error": None,
                "descriptors": {"symmetry": 0.5, "branching": 0.1, "shape_entropy": 1.0, "frequency": 2.0},
                "phenotype": None,
                "seconds": 0.0,
            }
            for t in tasks
        ]


def overhead_per_generation(population: int, generations: int, args, folder: Path) -> float:
    """Seconds of coordinator + storage work per generation (no evaluation cost)."""
    engine = open_database(f"sqlite:///{folder / f'overhead{population}.db'}")
    treatment = Treatment(
        LAND.name,
        0.1,
        population=population,
        generations=generations + 1,
        workspace=args.workspace,
        cycles=args.cycles,
    )
    _, (run_id,) = create(engine, "bench", [treatment])
    coordinator = Coordinator(engine, InstantExecutor())
    coordinator.run([run_id], max_rounds=1)  # generation 0: warm imports and caches
    start = time.perf_counter()
    coordinator.run([run_id], max_rounds=generations)
    return (time.perf_counter() - start) / generations


def generation_tasks(population: int, args, folder: Path) -> list[dict]:
    """The evaluation tasks of a fresh run's first generation."""
    engine = open_database(f"sqlite:///{folder / f'tasks{population}.db'}")
    treatment = Treatment(
        LAND.name, 0.1, population=population, generations=2, workspace=args.workspace, cycles=args.cycles
    )
    _, (run_id,) = create(engine, "bench", [treatment])
    return ask(load_run(engine, run_id))


def timed(executor: LocalExecutor, tasks: list[dict]) -> float:
    start = time.perf_counter()
    executor.evaluate(tasks)
    return time.perf_counter() - start


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--populations", default="30,100")
    parser.add_argument("--generations", type=int, default=5)
    parser.add_argument("--cycles", type=int, default=50)
    parser.add_argument("--workspace", default="7,7,7")
    parser.add_argument("--batch", type=int, default=16)
    parser.add_argument("--parts", default="overhead,speedup")
    parser.add_argument(
        "--eval-sample", type=int, default=0, help="time this many evaluations and scale up (0: all)"
    )
    args = parser.parse_args()
    args.workspace = tuple(int(n) for n in args.workspace.split(","))
    folder = Path(tempfile.mkdtemp(prefix="softevo-bench-"))
    print(f"load average before: {os.getloadavg()[0]:.2f} on {os.cpu_count()} cores")
    if "overhead" in args.parts:
        overheads(args, folder)
    if "speedup" in args.parts:
        speedup(args, folder)


def overheads(args, folder: Path) -> None:
    """Part 1-3: overhead per generation as a share of evaluation time."""
    pool = LocalExecutor()
    pool.warm()
    print(f"workspace {args.workspace}, {args.cycles} cycles, {pool.workers} processes")
    for population in (int(p) for p in args.populations.split(",")):
        overhead = overhead_per_generation(population, args.generations, args, folder)
        tasks = generation_tasks(population, args, folder)
        sample = tasks[: args.eval_sample or len(tasks)]
        evaluation = timed(pool, sample) * len(tasks) / len(sample)
        print(
            f"population {population:4d}: overhead {overhead * 1e3:8.1f} ms/generation, "
            f"evaluation {evaluation:7.2f} s/generation, share {overhead / evaluation:6.2%}"
        )
    pool.close()


def timed_batch(tasks: list[dict]) -> list[dict]:
    """``evaluate_batch`` that also reports its whole time (expression, simulation,
    descriptors) as ``job_seconds`` per result."""
    from softevo.worker.evaluate import evaluate_batch

    start = time.perf_counter()
    results = evaluate_batch(tasks)
    for result in results:
        result["job_seconds"] = (time.perf_counter() - start) / len(results)
    return results


def speedup(args, folder: Path) -> None:
    """Part 4: evaluations/s with 1 and 2 processes, on ``--batch`` copies of one genome
    (equal costs, so the ratio shows the executor's scaling, not the luck of the split).

    Also prints the pool's utilisation: the time the processes spent inside
    ``evaluate_batch`` over (processes x wall time), i.e. what IPC and imbalance leave. On a
    machine shared with other work the measured speed-up says little; utilisation x
    processes is what the executor would give on free cores."""
    first = generation_tasks(2, args, folder)[0]
    tasks = [dict(first, id=k) for k in range(args.batch)]
    rates = {}
    for workers in (1, 2):
        executor = LocalExecutor(workers, genomes_per_task=2, job=timed_batch)
        executor.warm()
        walls, busy = [], []
        for _ in range(2):
            start = time.perf_counter()
            results = executor.evaluate(tasks)
            walls.append(time.perf_counter() - start)
            busy.append(sum(r["job_seconds"] for r in results) / (workers * walls[-1]))
        executor.close()
        rates[workers] = len(tasks) / float(np.median(walls))
        print(
            f"local executor, {workers} process(es): {rates[workers]:.2f} evaluations/s, "
            f"utilisation {np.median(busy):.1%}"
        )
    print(
        f"speed-up 2 vs 1: {rates[2] / rates[1]:.2f}x "
        f"(load average now {os.getloadavg()[0]:.2f} on {os.cpu_count()} cores)"
    )


if __name__ == "__main__":
    main()
