"""The fixed costs of one ``softevo run`` / ``experiment`` invocation that ``softevo plan``
adds to its wall time (``service.plan.model.LOCAL_STARTUP_SECONDS``), measured in CPU seconds
(user + system: on a busy machine a step's wall time grows with the load, its CPU time
hardly), each the median of ``--repeats``:

- ``command``: the CLI's imports and a new SQLite database created and migrated
  (``softevo run`` before its first evaluation is asked);
- ``cache_check``: ``worker.evaluate.ensure_compiled``'s subprocess (imports the simulator,
  loads numba's cached kernels, simulates one robot);
- ``pool_process``: one pool process started (spawned, imported, warmed) and one land and
  one water robot evaluated in it (each world's kernels loaded on first use); the pool's
  processes start side by side, so one counts on the wall;
- a worker's own work per evaluation (``service.plan.model.WORKER_SECONDS_PER_EVALUATION``):
  developing a random 5^3 genome and its descriptors, per robot.

The kernels must be in numba's cache already (run any simulation once first).

    python bench/plan_startup.py [--repeats 3]
"""

from __future__ import annotations

import argparse
import resource
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

COMMAND = """
from softevo.service.cli import runs  # what softevo run imports before it stores anything
from softevo.service.storage import open_database
open_database({url!r}).dispose()
"""
CACHE_CHECK = "from softevo.worker.evaluate import warm_up; warm_up()"
POOL_PROCESS = """
import multiprocessing
from concurrent.futures import ProcessPoolExecutor
from softevo.evolution.genotype import random_viable_genotype, EncodingConfig
from softevo.worker.evaluate import evaluate_batch, init_pool_process
from softevo.sim import worlds
from softevo.evolution.evaluation import EvaluationSpec
from softevo.worker.tasks import Task
import numpy as np

encoding = EncodingConfig(workspace=(4, 4, 4))
genome = random_viable_genotype(np.random.default_rng(0), encoding)
tasks = [Task.from_genome(genome, EvaluationSpec(world, 1e6, 2, encoding=encoding), id=k).to_json()
         for k, world in enumerate(("land", "water"))]
with ProcessPoolExecutor(1, mp_context=multiprocessing.get_context("spawn"), initializer=init_pool_process,
                         initargs=(worlds.added(),)) as pool:
    pool.submit(evaluate_batch, tasks).result()
"""


def cpu_seconds(code: str) -> float:
    """User + system CPU seconds of ``python -c code`` and every process it started."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    subprocess.run([sys.executable, "-c", code], check=True)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    baseline = statistics.median(cpu_seconds("pass") for _ in range(args.repeats))  # the interpreter
    with tempfile.TemporaryDirectory() as tmp:
        urls = [f"sqlite:///{Path(tmp) / f'{k}.db'}" for k in range(args.repeats)]
        parts = {
            "command": statistics.median(cpu_seconds(COMMAND.format(url=url)) for url in urls),
            "cache_check": statistics.median(cpu_seconds(CACHE_CHECK) for _ in range(args.repeats)),
            # the parent's own interpreter and imports are not the pool process's
            "pool_process": statistics.median(cpu_seconds(POOL_PROCESS) for _ in range(args.repeats))
            - statistics.median(cpu_seconds(POOL_PROCESS.split("with ProcessPool")[0])
                                for _ in range(args.repeats)),
        }
    print(f"interpreter alone {baseline:.2f} s")
    for name, seconds in parts.items():
        print(f"{name:<13} {seconds:.2f} CPU s")
    print(f"local start-up (command + cache_check + pool_process) {sum(parts.values()):.2f} s")
    print(f"worker's own per evaluation {worker_own() * 1000:.1f} ms")


def worker_own(robots: int = 60) -> float:
    """CPU seconds per robot of developing a random 5^3 genome and describing its body."""
    import time

    import numpy as np

    from softevo.evolution.descriptors import describe
    from softevo.evolution.genotype import EncodingConfig, develop, random_viable_genotype

    encoding = EncodingConfig(workspace=(5, 5, 5))
    rng = np.random.default_rng(0)
    genomes = [random_viable_genotype(rng, encoding) for _ in range(robots)]
    started = time.process_time()
    for genome in genomes:
        phenotype = develop(genome, encoding)
        describe(phenotype.body, phenotype.frequency)
    return (time.process_time() - started) / robots


if __name__ == "__main__":
    main()
