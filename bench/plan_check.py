"""Check ``softevo plan`` against real runs here: predicted vs measured wall time.

Each case is a small experiment (several stiffnesses, land and water) run to the end by the
coordinator on the local executor (``softevo run``'s path: ``service.runs.executors.make_executor``)
with 1 or 2 worker processes, on a fresh SQLite file; its wall time (pool started and warm,
so numba's compilation is not counted) is compared with ``service.plan.model.plan`` on as many
cores. Every run lasts well under a minute. Run it on a quiet machine:

    python bench/plan_check.py            # every case
    python bench/plan_check.py --quick    # the first case only, 1 worker

The local executor splits a round's tasks over the workers across runs, the RQ executor (and
the planner) run by run: with one run per case the two agree.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

from softevo.evolution.treatments import Treatment
from softevo.service.plan.model import plan
from softevo.service.runs.coordinator import Coordinator
from softevo.service.runs.executors import make_executor
from softevo.service.runs.submit import create
from softevo.service.storage import open_database
from softevo.sim.worlds import LAND, WATER

COMMON = {"population": 6, "workspace": (5, 5, 5), "cycles": 2, "max_seconds": 1.0,
          "model": "voxcad-land-water", "algorithm": "pareto", "control_mapping": "evosoro",
          "body_rule": "evosoro"}


def cases() -> list[tuple[str, list[Treatment]]]:
    """(label, treatments): single runs over stiffness and world, then a mixed grid."""
    single = [
        (f"{world} {stiffness:g} MPa", [Treatment(world, stiffness, generations=gens, **COMMON)])
        for world, stiffness, gens in ((LAND.name, 0.01, 8), (WATER.name, 0.1, 8), (LAND.name, 1.0, 6),
                                       (WATER.name, 1.0, 4))
    ]
    mixed = [Treatment(world, stiffness, name=f"{world} {stiffness:g}", generations=4, seed=k, **COMMON)
             for k, (world, stiffness) in enumerate(((LAND.name, 0.01), (WATER.name, 0.1), (LAND.name, 1.0)))]
    return [*single, ("mixed 3 runs", mixed)]


def measured_seconds(treatments: list[Treatment], workers: int, folder: Path) -> float:
    """Wall seconds of the coordinator running ``treatments`` to the end on ``workers``."""
    engine = open_database(f"sqlite:///{folder / f'check-{time.monotonic_ns()}.db'}")
    _, run_ids = create(engine, "plan-check", treatments)
    executor = make_executor(workers)
    try:
        if hasattr(executor, "warm"):
            executor.warm()
        start = time.perf_counter()
        Coordinator(engine, executor).run(run_ids)
        return time.perf_counter() - start
    finally:
        executor.close()
        engine.dispose()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="the first case on 1 worker only")
    args = parser.parse_args()
    chosen = cases()[:1] if args.quick else cases()
    worker_counts = (1,) if args.quick else (1, 2)
    print(f"{'case':<16} {'workers':>7} {'predicted s':>12} {'measured s':>11} {'error':>7}")
    errors = []
    with tempfile.TemporaryDirectory() as folder:
        for label, treatments in chosen:
            for workers in worker_counts:
                predicted = plan(treatments, cores=workers, executor="local").wall_seconds
                measured = measured_seconds(treatments, workers, Path(folder))
                error = (predicted - measured) / measured * 100
                errors.append(abs(error))
                row = f"{label:<16} {workers:>7} {predicted:>12.1f} {measured:>11.1f} {error:>+6.0f}%"
                print(row, flush=True)
    print(f"mean absolute error {sum(errors) / len(errors):.0f}%")


if __name__ == "__main__":
    main()
