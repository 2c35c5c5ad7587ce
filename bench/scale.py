"""How many workers one coordinator feeds: the paper's grid on hundreds of simulated workers,
through real Redis and real PostgreSQL, on one machine.

    python bench/scale.py [--workers 100,500,1000] [--seconds 60] [--warmup 25]
                          [--speed-up 1] [--processes 4] [--coordinators 1]
                          [--generations G --to-end] [--postgres URL] [--json OUT]

Per load level (a number of workers):
- a fresh PostgreSQL database holds the paper grid at paper scale (180 runs, population 30,
  7^3, the paper's algorithm and model), a private ``redis-server`` on a free loopback port
  carries the jobs;
- the workers are real ``softevo worker`` job loops (``worker.rq_worker.EvaluationWorker``)
  on the sleep engine (``sim.sleep_engine``: each evaluation sleeps its modelled cost, by
  voxel count, stiffness and world, divided by ``--speed-up``), as threads of ``--processes``
  processes: a sleeping worker uses no CPU, so hundreds fit on 2 cores;
- the coordinator is ``softevo serve``'s loop (``service.runs.driver.CoordinatorLoop`` with the RQ
  executor and Redis run locks), in a process of its own; ``--coordinators K`` starts K, which
  split the runs between them;
- after ``--warmup`` seconds, for ``--seconds`` seconds it measures: evaluations per second
  (genomes of the jobs that ended in the window), database writes per second (rows inserted,
  updated or deleted, from PostgreSQL's own statistics) and commits per second, queue latency
  (a job's start less its enqueueing; p50 and p99), worker utilisation (busy worker-seconds
  over the window's worker-seconds), and the CPU share of the coordinator, Redis, PostgreSQL
  and the workers, and what one coordinator process carries per CPU-second (evaluations per
  second at a whole core: the rate at which it becomes the bottleneck); then it names the
  bottleneck.
With ``--to-end`` a level runs the grid (every treatment cut to ``--generations`` G) to its
end instead of a window, and sets the wall time from the coordinators' start to the last
run's end beside what ``softevo plan`` predicts for the same grid, workers, coordinators and
speed-up (``service.plan.model.plan`` with the cost model scaled as the sleep engine scales it):
the planner checked against hundreds of workers.
Everything stays on 127.0.0.1; every level ends by itself (the processes are stopped, the
database dropped; a run to the end gives up after ``--seconds`` x 10).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time
from datetime import UTC, datetime
from pathlib import Path
from urllib.parse import urlsplit, urlunsplit

import numpy as np

from softevo.service.api.loopback import free_port

REPO = Path(__file__).resolve().parents[1]
QUEUE = "softevo-scale"
TICK = os.sysconf("SC_CLK_TCK")
CORES = os.cpu_count() or 1


# -- roles (subprocesses) ---------------------------------------------------------------------


def workers_role(redis_url: str, count: int, first: int) -> None:
    """``count`` evaluation workers as threads of this process, until it is terminated."""
    from redis import Redis
    from rq.serializers import JSONSerializer
    from rq.timeouts import TimerDeathPenalty

    from softevo.worker.rq_worker import EvaluationJob, EvaluationWorker

    class ThreadWorker(EvaluationWorker):
        """The evaluation worker in a thread: no signal handlers (a thread cannot install
        them; the bench ends the process), a timer for the job timeout instead of SIGALRM."""

        death_penalty_class = TimerDeathPenalty

        def _install_signal_handlers(self) -> None:
            pass

    def one(k: int) -> None:
        connection = Redis.from_url(redis_url, socket_timeout=600)
        worker = ThreadWorker([QUEUE], name=f"sim-{first + k}", connection=connection,
                              serializer=JSONSerializer, job_class=EvaluationJob, worker_ttl=600)
        worker.work(logging_level="WARNING")

    threads = [threading.Thread(target=one, args=(k,), daemon=True) for k in range(count)]
    for thread in threads:
        thread.start()
        time.sleep(0.002)
    signal.sigwait({signal.SIGTERM})


def coordinator_role(db_url: str, redis_url: str) -> None:
    """``softevo serve``'s coordinator loop on the database's runs, until terminated: with
    ``--coordinators K`` there are K of these, sharing the runs through Redis locks."""
    from softevo.service.runs.driver import CoordinatorLoop
    from softevo.service.runs.locks import RedisLocks
    from softevo.service.runs.rq_executor import RQExecutor
    from softevo.service.storage import open_database

    stop = threading.Event()
    engine = open_database(db_url)
    executor = RQExecutor(redis_url, queue=QUEUE, genomes_per_job=4, stop=stop)
    locks = RedisLocks(redis_url, "scale")
    loop = CoordinatorLoop(engine, executor, locks, poll_seconds=0.2, stop=stop)
    loop.start()
    signal.sigwait({signal.SIGTERM})
    stop.set()


# -- measuring --------------------------------------------------------------------------------


def cpu_seconds(pids: list[int]) -> float:
    total = 0.0
    for pid in pids:
        try:
            fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
            total += (int(fields[11]) + int(fields[12])) / TICK
        except (FileNotFoundError, ProcessLookupError, IndexError):
            continue
    return total


def pids_of_user(user: str) -> list[int]:
    import pwd

    uid = pwd.getpwnam(user).pw_uid
    return [int(p.name) for p in Path("/proc").iterdir() if p.name.isdigit() and _owner(p) == uid]


def _owner(path: Path) -> int | None:
    try:
        return path.stat().st_uid
    except FileNotFoundError:
        return None


def machine_busy() -> float:
    """Busy CPU seconds of the whole machine so far (all cores)."""
    fields = [int(x) for x in Path("/proc/stat").read_text().split("\n", 1)[0].split()[1:]]
    idle = fields[3] + fields[4]
    return (sum(fields[:8]) - idle) / TICK


def pg_counters(admin_url: str, name: str) -> tuple[int, int]:
    """(rows written, commits) of database ``name`` so far."""
    import psycopg

    with psycopg.connect(admin_url, autocommit=True) as conn:
        row = conn.execute(
            "SELECT tup_inserted + tup_updated + tup_deleted, xact_commit FROM pg_stat_database "
            "WHERE datname = %s", (name,)).fetchone()
    return int(row[0]), int(row[1])


def parse_time(value: bytes | None) -> float | None:
    if not value:
        return None
    text = value.decode().rstrip("Z")
    return datetime.fromisoformat(text).replace(tzinfo=UTC).timestamp()


def job_times(redis_url: str) -> list[tuple[float, float | None, float | None, int]]:
    """(enqueued, started, ended, genomes) of every evaluation job Redis holds."""
    from redis import Redis

    r = Redis.from_url(redis_url)
    keys = [k for k in r.scan_iter("rq:job:*", count=5000) if k.count(b":") == 2]
    out = []
    for start in range(0, len(keys), 2000):
        part = keys[start : start + 2000]
        with r.pipeline(transaction=False) as pipe:
            for key in part:
                pipe.hmget(key, "enqueued_at", "started_at", "ended_at", "description")
            rows = pipe.execute()
        for enqueued, started, ended, description in rows:
            if not enqueued or not description:
                continue
            genomes = int(description.split()[1]) if description.startswith(b"evaluate ") else 1
            out.append((parse_time(enqueued), parse_time(started), parse_time(ended), genomes))
    return out


def window_figures(jobs, t0: float, t1: float, workers: int) -> dict:
    seconds = t1 - t0
    ended = [j for j in jobs if j[2] is not None and t0 <= j[2] < t1]
    started = [j for j in jobs if j[1] is not None and t0 <= j[1] < t1]
    latency = np.array([j[1] - j[0] for j in started]) if started else np.zeros(1)
    busy = 0.0
    for _, s, e, _ in jobs:
        if s is None:
            continue
        e = t1 if e is None else e
        busy += max(0.0, min(e, t1) - max(s, t0))
    return {
        "evaluations_per_s": sum(j[3] for j in ended) / seconds,
        "jobs_per_s": len(ended) / seconds,
        "queue_p50_s": float(np.percentile(latency, 50)),
        "queue_p99_s": float(np.percentile(latency, 99)),
        "utilisation": busy / (workers * seconds),
    }


def bottleneck(row: dict) -> str:
    """The component that limits the level, in words."""
    if row["utilisation"] >= 0.9:
        return "none: the workers (over 90% busy)"
    shares = {
        "the coordinator (one process)": row["cpu_coordinator"] / row["coordinators"],
        "Redis (one thread)": row["cpu_redis"],
        "PostgreSQL": row["cpu_postgres"] / CORES,
    }
    name, share = max(shares.items(), key=lambda item: item[1])
    if share >= 0.8:
        return f"{name}: {share:.0%} of a core"
    if row["cpu_machine"] >= 0.9:
        return f"this machine's {CORES} cores ({row['cpu_machine']:.0%} busy)"
    if row["queue_p50_s"] > 1.0:  # jobs wait while workers idle: the time between a worker's jobs
        return "the workers' turnaround between jobs (jobs queue while workers are idle)"
    return "the barriers: runs waiting on their slowest evaluations"


# -- one level --------------------------------------------------------------------------------


def with_database(url: str, name: str) -> str:
    parts = urlsplit(url)
    return urlunsplit(parts._replace(path=f"/{name}"))


def level(workers: int, args, admin_url: str, folder: Path) -> dict:
    import psycopg
    from redis import Redis

    from softevo.service.runs.submit import create
    from softevo.service.storage import open_database

    name = f"softevo_scale_{workers}"
    with psycopg.connect(admin_url, autocommit=True) as conn:
        conn.execute(f'DROP DATABASE IF EXISTS "{name}"')
        conn.execute(f'CREATE DATABASE "{name}"')
    db_url = with_database(args.postgres, name)
    engine = open_database(db_url)
    _, run_ids = create(engine, "scale bench", grid(args.generations))
    engine.dispose()

    port = free_port()
    redis = subprocess.Popen(
        ["redis-server", "--bind", "127.0.0.1", "--port", str(port), "--save", "", "--appendonly", "no",
         "--maxclients", "20000", "--dir", str(folder)], stdout=subprocess.DEVNULL)
    redis_url = f"redis://127.0.0.1:{port}/0"
    env = {**os.environ, "SOFTEVO_ENGINE": "sleep", "SOFTEVO_DEVICE": f"x{args.speed_up:g}"}
    procs: list[subprocess.Popen] = []
    try:
        client = Redis.from_url(redis_url)
        for _ in range(50):
            try:
                client.ping()
                break
            except Exception:
                time.sleep(0.1)
        per = [workers // args.processes + (k < workers % args.processes) for k in range(args.processes)]
        first = 0
        for count in per:
            role = ["--role", "workers", "--redis", redis_url, "--count", str(count), "--first", str(first)]
            procs.append(subprocess.Popen([sys.executable, __file__, *role], env=env))
            first += count
        deadline = time.monotonic() + 120
        while int(client.scard("rq:workers")) < workers and time.monotonic() < deadline:
            time.sleep(0.5)
        registered = int(client.scard("rq:workers"))
        worker_pids = [p.pid for p in procs]
        role = [sys.executable, __file__, "--role", "coordinator", "--redis", redis_url, "--db", db_url]
        started = time.time()
        coordinators = [subprocess.Popen(role, env=env) for _ in range(args.coordinators)]
        procs += coordinators
        if args.to_end:
            return to_end(workers, args, db_url, redis_url, run_ids, started, registered)
        time.sleep(args.warmup)
        pg_pids = pids_of_user("postgres")

        def snapshot():
            return {"t": time.time(), "coordinator": cpu_seconds([c.pid for c in coordinators]),
                    "redis": cpu_seconds([redis.pid]), "postgres": cpu_seconds(pg_pids),
                    "workers": cpu_seconds(worker_pids), "machine": machine_busy(),
                    "pg": pg_counters(admin_url, name)}

        a = snapshot()
        time.sleep(args.seconds)
        b = snapshot()
        seconds = b["t"] - a["t"]
        row = {"workers": workers, "coordinators": args.coordinators, "registered": registered,
               **window_figures(job_times(redis_url), a["t"], b["t"], workers),
               "db_writes_per_s": (b["pg"][0] - a["pg"][0]) / seconds,
               "commits_per_s": (b["pg"][1] - a["pg"][1]) / seconds}
        for key in ("coordinator", "redis", "postgres", "workers"):
            row[f"cpu_{key}"] = (b[key] - a[key]) / seconds
        row["cpu_machine"] = (b["machine"] - a["machine"]) / seconds / CORES
        # what one coordinator process would carry at a whole core: evaluations per CPU-second
        per_process = row["cpu_coordinator"] / args.coordinators
        row["coordinator_capacity"] = row["evaluations_per_s"] / args.coordinators / max(per_process, 1e-9)
        row["bottleneck"] = bottleneck(row)
        return row
    finally:
        for proc in procs:
            proc.send_signal(signal.SIGTERM)
        for proc in procs:
            try:
                proc.wait(10)
            except subprocess.TimeoutExpired:
                proc.kill()
        redis.terminate()
        redis.wait(10)
        with psycopg.connect(admin_url, autocommit=True) as conn:
            conn.execute(f'DROP DATABASE IF EXISTS "{name}" WITH (FORCE)')


def grid(generations: int | None):
    """The paper's grid at paper scale, each treatment cut to ``generations`` if given."""
    from softevo.evolution.treatments import preset_grid

    treatments = preset_grid("paper", "paper")
    if generations is None:
        return treatments
    return [dataclasses.replace(t, generations=min(t.generations, generations)) for t in treatments]


def to_end(
    workers: int, args, db_url: str, redis_url: str, run_ids: list[int], started: float, registered: int
) -> dict:
    """Wait for every run to finish (at most ``--seconds`` x 10); the measured wall time
    beside the planner's prediction of the same grid on as many workers."""
    from softevo.service.storage import open_database
    from softevo.service.storage.runs import active_run_ids

    engine = open_database(db_url)
    deadline = started + 10 * args.seconds
    try:
        while time.time() < deadline:
            with engine.connect() as conn:
                if not active_run_ids(conn, run_ids):
                    break
            time.sleep(0.5)
        else:
            raise SystemExit(f"the grid did not end within {10 * args.seconds:g} s")
    finally:
        engine.dispose()
    ended = time.time()
    measured = ended - started
    utilisation = window_figures(job_times(redis_url), started, ended, workers)["utilisation"]
    predicted = planned(workers, args)
    return {"workers": workers, "coordinators": args.coordinators, "registered": registered,
            "runs": len(run_ids), "generations": args.generations, "speed_up": args.speed_up,
            "measured_seconds": measured, "predicted_seconds": predicted["wall_seconds"],
            "predicted_utilisation": predicted["utilisation"], "utilisation": utilisation,
            "error": predicted["wall_seconds"] / measured - 1.0}


def planned(workers: int, args) -> dict:
    """``softevo plan``'s answer for the bench's grid: the cost model the sleep engine sleeps
    by, divided by its speed-up; the RQ executor's coordinator cost."""
    from softevo.service.plan.model import plan
    from softevo.sim.cost import MEASURED

    scaled = dataclasses.replace(
        MEASURED, rates={k: v * args.speed_up for k, v in MEASURED.rates.items()},
        default_rate=MEASURED.default_rate * args.speed_up,
        overhead_seconds=MEASURED.overhead_seconds / args.speed_up)
    return plan(grid(args.generations), cores=workers, cost=scaled, coordinators=args.coordinators,
                executor="rq").to_json()


def show_to_end(rows: list[dict]) -> None:
    print("| workers | coordinators | runs x generations | speed-up | measured s | predicted s | "
          "error | utilisation measured / predicted |")
    print("| --- | --- | --- | --- | ---: | ---: | ---: | ---: |")
    for r in rows:
        print(f"| {r['workers']} | {r['coordinators']} | {r['runs']} x {r['generations']} | "
              f"x{r['speed_up']:g} | {r['measured_seconds']:.1f} | {r['predicted_seconds']:.1f} | "
              f"{r['error']:+.0%} | {r['utilisation']:.2f} / {r['predicted_utilisation']:.2f} |")


def show(rows: list[dict]) -> None:
    head = ("workers", "coordinators", "evals/s", "DB writes/s", "commits/s", "queue p50 s", "queue p99 s",
            "utilisation", "CPU coord / redis / pg / workers", "evals per coordinator CPU-s", "bottleneck")
    print("| " + " | ".join(head) + " |")
    print("|" + " --- |" * len(head))
    for r in rows:
        parts = ("cpu_coordinator", "cpu_redis", "cpu_postgres", "cpu_workers")
        cpu = " / ".join(f"{r[k]:.2f}" for k in parts)
        print(f"| {r['workers']} | {r['coordinators']} | {r['evaluations_per_s']:.0f} | "
              f"{r['db_writes_per_s']:.0f} | "
              f"{r['commits_per_s']:.1f} | {r['queue_p50_s']:.3f} | {r['queue_p99_s']:.2f} | "
              f"{r['utilisation']:.2f} | {cpu} | {r['coordinator_capacity']:.0f} | {r['bottleneck']} |")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n", 1)[0])
    parser.add_argument("--workers", default="100,500,1000")
    parser.add_argument("--seconds", type=float, default=60.0)
    parser.add_argument("--warmup", type=float, default=25.0)
    parser.add_argument("--speed-up", type=float, default=1.0)
    parser.add_argument("--processes", type=int, default=4)
    parser.add_argument("--coordinators", type=int, default=1)
    parser.add_argument("--generations", type=int, help="cut every treatment to G generations")
    parser.add_argument("--to-end", action="store_true",
                        help="run the grid to its end and compare with softevo plan")
    parser.add_argument("--postgres", default=os.environ.get(
        "SOFTEVO_BENCH_POSTGRES", "postgresql+psycopg://postgres:postgres@127.0.0.1:5432/postgres"))
    parser.add_argument("--json", type=Path)
    parser.add_argument("--role", choices=("workers", "coordinator"), help=argparse.SUPPRESS)
    parser.add_argument("--redis", help=argparse.SUPPRESS)
    parser.add_argument("--db", help=argparse.SUPPRESS)
    parser.add_argument("--count", type=int, help=argparse.SUPPRESS)
    parser.add_argument("--first", type=int, default=0, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.role == "workers":
        signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGTERM})
        return workers_role(args.redis, args.count, args.first)
    if args.role == "coordinator":
        signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGTERM})
        return coordinator_role(args.db, args.redis)
    if shutil.which("redis-server") is None:
        sys.exit("bench/scale.py needs redis-server on PATH")
    admin_url = with_database(args.postgres, "postgres").replace("postgresql+psycopg://", "postgresql://")
    if args.to_end and args.generations is None:
        sys.exit("--to-end needs --generations G (the paper's own lengths take days)")
    print(f"paper grid (180 runs, population 30, 7^3) on the sleep engine x{args.speed_up:g}, "
          f"{args.processes} worker processes, {args.coordinators} coordinator(s), {CORES} cores; "
          f"window {args.seconds:g} s after {args.warmup:g} s")
    rows = []
    with tempfile.TemporaryDirectory() as folder:
        for workers in [int(w) for w in args.workers.split(",")]:
            rows.append(level(workers, args, admin_url, Path(folder)))
            (show_to_end if args.to_end else show)(rows[-1:])
    print()
    (show_to_end if args.to_end else show)(rows)
    if args.json:
        args.json.write_text(json.dumps(rows, indent=1))


if __name__ == "__main__":
    main()
