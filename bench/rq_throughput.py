"""Evaluations per second through Redis + RQ against the local process pool, on the same
genomes, and how many trivial jobs per second one coordinator dispatches.

Usage: python bench/rq_throughput.py [--genomes 24] [--rounds 3] [--cycles 4] [--repeat 2]
                                    [--json OUT]

- local-N: ``LocalExecutor(workers=N)`` (process pool, warmed before timing).
- rq-N: ``RQExecutor`` with N ``softevo worker`` processes (warmed, registered before timing).
  Both split a round into jobs of ``--genomes-per-job`` genomes (at least one per worker).
  The ratio rq-N / local-N is the share of the throughput the queue keeps (target >= 0.9).
- dispatch: trivial jobs (``evaluate_batch([])``) enqueued by the executor's own code path,
  per second (enqueue only), and end to end (enqueue, run by 2 workers, results read back).

Redis: ``$SOFTEVO_TEST_REDIS_URL`` if set, else a private ``redis-server`` on a free port.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import socket
import subprocess
import sys
import tempfile
import time
import uuid
from pathlib import Path

import numpy as np
from redis import Redis

from softevo.evolution.genotype import EncodingConfig, random_viable_genotype
from softevo.service.runs.executors import LocalExecutor
from softevo.service.runs.rq_executor import JobBatch, RQExecutor
from softevo.sim.worlds import LAND

REPO = Path(__file__).resolve().parents[1]


def workload(genomes: int, rounds: int, cycles: int, workspace: int) -> list[list[dict]]:
    """``rounds`` generations of ``genomes`` random viable robots (land, 0.1 MPa)."""
    config = EncodingConfig(workspace=(workspace,) * 3)
    rng = np.random.default_rng(2024)
    return [
        [
            {
                "id": k,
                "run_id": 1,
                "generation": g,
                "genome": random_viable_genotype(rng, config).to_dict(),
                "environment": LAND.name,
                "youngs_modulus": 1e5,
                "cycles": cycles,
                "encoding": config.to_dict(),
            }
            for k in range(genomes)
        ]
        for g in range(rounds)
    ]


RUN_IDS = iter(range(1000, 10**9))


def timed(executor, rounds: list[list[dict]], repeat: int) -> float:
    """Evaluations per second over all rounds, one ``evaluate`` call per round; the best of
    ``repeat`` passes. Each pass has a new run id: no job id (hence no stored result) is
    shared with another pass or measurement."""
    best = 0.0
    for _ in range(repeat):
        run_id = next(RUN_IDS)
        fresh = [[{**task, "run_id": run_id} for task in tasks] for tasks in rounds]
        start = time.perf_counter()
        for tasks in fresh:
            executor.evaluate(tasks)
        best = max(best, sum(len(t) for t in fresh) / (time.perf_counter() - start))
    return best


class Redises:
    """The Redis to use, and a private server to stop at the end (if one was started)."""

    def __init__(self) -> None:
        self.process = None
        self.url = os.environ.get("SOFTEVO_TEST_REDIS_URL")
        if not self.url:
            with socket.socket() as sock:
                sock.bind(("127.0.0.1", 0))
                port = sock.getsockname()[1]
            self.process = subprocess.Popen(
                [shutil.which("redis-server") or "redis-server", "--bind", "127.0.0.1", "--port",
                 str(port), "--save", "", "--appendonly", "no", "--dir", tempfile.mkdtemp()],
                stdout=subprocess.DEVNULL,
            )  # fmt: skip
            self.url = f"redis://127.0.0.1:{port}/0"
            for _ in range(100):
                try:
                    Redis.from_url(self.url).ping()
                    break
                except Exception:
                    time.sleep(0.05)

    def close(self) -> None:
        if self.process:
            self.process.terminate()
            self.process.wait()


def start_workers(n: int, redis_url: str, queue: str) -> list[subprocess.Popen]:
    env = {**os.environ, "SOFTEVO_REDIS_URL": redis_url, "SOFTEVO_QUEUE": queue}
    return [
        subprocess.Popen(
            [sys.executable, "-m", "softevo.service.cli", "worker", "--name", f"bench-{queue}-{i}"],
            cwd=REPO,
            env=env,
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
        )
        for i in range(n)
    ]


def stop(processes: list[subprocess.Popen]) -> None:
    for process in processes:
        process.terminate()
    for process in processes:
        process.wait(30)


def rq_rate(n: int, redis_url: str, rounds, genomes_per_job: int, repeat: int) -> float:
    queue = f"bench-{uuid.uuid4().hex[:6]}"
    workers = start_workers(n, redis_url, queue)
    executor = RQExecutor(redis_url, queue=queue, genomes_per_job=genomes_per_job)
    try:
        while executor.worker_count() < n:
            time.sleep(0.1)
        executor.evaluate(rounds[0][:n])  # first job of each worker out of the timing
        return timed(executor, rounds, repeat)
    finally:
        executor.close()
        stop(workers)


def local_rate(n: int, rounds, genomes_per_job: int, repeat: int) -> float:
    executor = LocalExecutor(workers=n, genomes_per_task=genomes_per_job)
    try:
        executor.warm()
        executor.evaluate(rounds[0][:n])
        return timed(executor, rounds, repeat)
    finally:
        executor.close()


def dispatch_rates(redis_url: str, jobs: int) -> tuple[float, float]:
    """(trivial jobs enqueued per second, trivial jobs completed per second with 2 workers)."""
    queue = f"bench-{uuid.uuid4().hex[:6]}"
    executor = RQExecutor(redis_url, queue=queue)
    batches = [JobBatch(f"trivial-{queue}-{k}", [], []) for k in range(jobs)]
    start = time.perf_counter()
    for k in range(0, jobs, 100):  # the executor's own submission path, 100 jobs a call
        executor._submit(batches[k : k + 100])
    enqueue_rate = jobs / (time.perf_counter() - start)
    executor.queue.empty()
    end_to_end_batches = [JobBatch(f"trivial2-{queue}-{k}", [], []) for k in range(jobs)]
    workers = start_workers(2, redis_url, queue)
    try:
        while executor.worker_count() < 2:
            time.sleep(0.1)
        waiting = {b.job_id: b for b in end_to_end_batches}
        start = time.perf_counter()
        executor._submit(waiting.values())
        while waiting:
            for batch, _ in executor._poll(waiting):
                del waiting[batch.job_id]
        end_to_end = jobs / (time.perf_counter() - start)
    finally:
        stop(workers)
        executor.close()
    return enqueue_rate, end_to_end


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--genomes", type=int, default=24, help="genomes per round")
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--cycles", type=int, default=4)
    parser.add_argument("--workspace", type=int, default=5)
    parser.add_argument("--genomes-per-job", type=int, default=4)
    parser.add_argument("--repeat", type=int, default=2, help="passes; the best counts")
    parser.add_argument("--trivial-jobs", type=int, default=1000)
    parser.add_argument("--json", help="also write the numbers to this file")
    args = parser.parse_args()

    rounds = workload(args.genomes, args.rounds, args.cycles, args.workspace)
    redis = Redises()
    numbers: dict[str, float] = {}
    try:
        for n in (1, 2):
            numbers[f"local-{n}"] = local_rate(n, rounds, args.genomes_per_job, args.repeat)
            numbers[f"rq-{n}"] = rq_rate(n, redis.url, rounds, args.genomes_per_job, args.repeat)
            numbers[f"ratio-{n}"] = numbers[f"rq-{n}"] / numbers[f"local-{n}"]
            print(
                f"{n} worker(s): local {numbers[f'local-{n}']:.2f} eval/s, "
                f"rq {numbers[f'rq-{n}']:.2f} eval/s, rq/local {numbers[f'ratio-{n}']:.1%}",
                flush=True,
            )
        enqueue, end_to_end = dispatch_rates(redis.url, args.trivial_jobs)
        numbers["dispatch-enqueue"] = enqueue
        numbers["dispatch-end-to-end-2-workers"] = end_to_end
        print(f"trivial jobs: {enqueue:.0f} enqueued/s, {end_to_end:.0f} done/s with 2 workers")
    finally:
        redis.close()
    workload_text = (
        f"{args.rounds} rounds x {args.genomes} genomes, workspace {args.workspace}^3, "
        f"{args.cycles} cycles, {args.genomes_per_job} genomes per job, {os.cpu_count()} cores"
    )
    print(f"workload: {workload_text}")
    if args.json:
        Path(args.json).write_text(json.dumps({"workload": workload_text, **numbers}, indent=2))


if __name__ == "__main__":
    main()
