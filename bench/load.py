"""The service under load: read latency per endpoint and the experiment's throughput.

Usage: python bench/load.py [--quick] [--clients 50,200] [--interval 1] [--seconds S]
                            [--generations G] [--max-requests N] [--json OUT]

Starts ``softevo serve`` on a free loopback port (SQLite in a temporary directory, the
coordinator with 2 local worker processes, no Redis), then runs the same experiment (same
seed, so the same evaluations in the same order) in phases of ``--seconds`` each:

- unloaded: alone; one before the first loaded phase and one after each (the host's speed
  drifts, so each loaded phase is compared with the mean of the two around it);
- loaded: for each client count (default 50, then 200) a fresh copy of the experiment runs
  while that many concurrent clients (one asyncio task and keep-alive connection each, a
  plain HTTP/1.1 client, so that the clients' own CPU stays small) poll
  ``GET /experiments/{id}`` (status), ``/runs?experiment=``, ``/runs/{id}/generations``,
  ``/runs/{id}/front``, ``/individuals/{best}/lineage`` and ``/dashboard/runs/{id}`` in
  turn, each request awaited and followed by ``--interval`` seconds (default 1 s: twice as
  often as the dashboard polls a live run; 0: at once, a stress test).

Printed: per loaded phase and endpoint, requests, requests per second, p50 and p99 latency
(ms), errors (status >= 400 or no answer; 5xx counted apart); and the experiment's
evaluations per second (sum of evaluations / sum of ``evaluation_seconds`` of the
generations it stored in the phase: the evaluations' own simulation times, so it shows the
CPU the server takes from the workers, not queue waits) against the unloaded phases around it. Bounded: every
phase ends after ``--seconds`` (the run is cancelled there) or ``--max-requests``; the
default takes about 4 minutes, ``--quick`` about one. The clients run on the same machine as
the server and its workers (loopback only): on a small machine they take CPU from both, so
compare runs on the same machine only.
"""

from __future__ import annotations

import argparse
import asyncio
import json
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import httpx
import numpy as np

from softevo.evolution.environments import LAND
from softevo.service.api.loopback import free_port, wait_healthy

REPO = Path(__file__).resolve().parents[1]
TOKEN = "bench-load-token"
ENDPOINTS = ("status", "runs", "generations", "front", "lineage", "dashboard")


def treatment(generations: int, seed: int) -> dict:
    return {
        "environment": LAND.name,
        "stiffness_mpa": 0.1,
        "population": 8,
        "generations": generations,
        "workspace": [5, 5, 5],
        "cycles": 4,
        "seed": seed,
    }


class Server:
    """``softevo serve`` with 2 local workers on a temporary SQLite database."""

    def __init__(self, workdir: Path) -> None:
        self.port = free_port()
        self.base = f"http://127.0.0.1:{self.port}"
        env = {
            **os.environ,
            "SOFTEVO_DB": f"sqlite:///{workdir / 'load.db'}",
            "SOFTEVO_TOKEN": TOKEN,
            "SOFTEVO_WORKERS": "2",
            "SOFTEVO_REPORTS": str(workdir / "reports"),
        }
        env.pop("SOFTEVO_REDIS_URL", None)
        self.log = open(workdir / "serve.log", "w")  # noqa: SIM115 - closed in stop()
        self.process = subprocess.Popen(
            [sys.executable, "-m", "softevo.service.cli", "serve", "--port", str(self.port)],
            cwd=REPO, env=env, stdout=self.log, stderr=subprocess.STDOUT, start_new_session=True,
        )  # fmt: skip
        try:
            wait_healthy(self.base, self.process, 120)
        except RuntimeError as exc:
            raise SystemExit(f"softevo serve did not start ({exc}); see {workdir / 'serve.log'}") from None

    def submit(self, name: str, generations: int, seed: int) -> tuple[int, int]:
        body = {"name": name, "treatments": [treatment(generations, seed)]}
        response = httpx.post(
            f"{self.base}/experiments", json=body, headers={"Authorization": f"Bearer {TOKEN}"}
        )
        response.raise_for_status()
        data = response.json()
        return data["id"], data["runs"][0]

    def run(self, run_id: int) -> dict:
        return httpx.get(f"{self.base}/runs/{run_id}", timeout=30).json()

    def cancel(self, run_id: int) -> None:
        httpx.post(f"{self.base}/runs/{run_id}/cancel", headers={"Authorization": f"Bearer {TOKEN}"})

    def throughput(self, run_id: int) -> tuple[int, float]:
        """(evaluations, evaluations per second) of the run's stored generations."""
        rows = httpx.get(f"{self.base}/runs/{run_id}/generations", timeout=30).json()
        evaluations = sum(r["evaluations"] for r in rows)
        seconds = sum(r["evaluation_seconds"] for r in rows)
        return evaluations, evaluations / seconds if seconds else 0.0

    def stop(self) -> None:
        self.process.send_signal(signal.SIGTERM)
        try:
            self.process.wait(30)
        except subprocess.TimeoutExpired:
            os.killpg(self.process.pid, signal.SIGKILL)
        self.log.close()


def wait_generation(server: Server, run_id: int, generation: int, limit: float) -> dict:
    deadline = time.monotonic() + limit
    while True:
        run = server.run(run_id)
        if run["generation"] >= generation or run["status"] in ("finished", "failed", "cancelled"):
            return run
        if time.monotonic() > deadline:
            raise SystemExit(f"run {run_id} stored no generation {generation} within {limit:.0f} s")
        time.sleep(0.2)


def run_alone(server: Server, name: str, args) -> dict:
    """The experiment with no clients, cut at ``--seconds`` as the loaded phases are."""
    experiment_id, run_id = server.submit(name, args.generations, args.seed)
    wait_generation(server, run_id, 0, 120)
    started = time.monotonic()
    while time.monotonic() - started < args.seconds:
        if server.run(run_id)["status"] in ("finished", "failed", "cancelled"):
            break
        time.sleep(0.5)
    if server.run(run_id)["status"] != "finished":
        server.cancel(run_id)
    evaluations, rate = server.throughput(run_id)
    return {"evaluations": evaluations, "eval_per_s": rate, "wall_s": time.monotonic() - started}


class Connection:
    """One keep-alive HTTP/1.1 connection on loopback, a GET at a time: a plain asyncio
    client, so that the clients' own CPU (on the server's machine) stays small."""

    def __init__(self, host: str, port: int) -> None:
        self.host, self.port = host, port
        self.reader: asyncio.StreamReader | None = None
        self.writer: asyncio.StreamWriter | None = None

    async def get(self, path: str) -> int:
        """The status code of ``GET path`` (the body read and dropped); 0 when the
        connection failed (the next call opens a new one)."""
        try:
            if self.writer is None:
                self.reader, self.writer = await asyncio.open_connection(self.host, self.port)
            self.writer.write(f"GET {path} HTTP/1.1\r\nHost: {self.host}\r\n\r\n".encode())
            head = await asyncio.wait_for(self.reader.readuntil(b"\r\n\r\n"), 30)
            lines = head.decode("latin-1").split("\r\n")
            code = int(lines[0].split()[1])
            headers = dict(line.lower().split(": ", 1) for line in lines[1:] if ": " in line)
            if "content-length" in headers:
                await self.reader.readexactly(int(headers["content-length"]))
            elif headers.get("transfer-encoding") == "chunked":
                while True:
                    size = int((await self.reader.readuntil(b"\r\n")).strip(), 16)
                    await self.reader.readexactly(size + 2)
                    if size == 0:
                        break
            if headers.get("connection") == "close":
                self.close()
            return code
        except (OSError, asyncio.IncompleteReadError, asyncio.LimitOverrunError, TimeoutError,
                ValueError, IndexError):
            self.close()
            return 0

    def close(self) -> None:
        if self.writer is not None:
            self.writer.close()
        self.reader = self.writer = None


async def client(
    connection: Connection, paths: dict[str, str], stats: dict, stop: asyncio.Event,
    budget: list, interval: float, start: float, first: int,
):
    """One client: the endpoints in turn from the ``first``, each request awaited and
    followed by ``interval`` seconds of waiting (0: the next at once), from ``start`` seconds
    in, until ``stop`` or the request budget is spent."""
    k = first
    await asyncio.sleep(start)
    while not stop.is_set() and budget[0] > 0:
        budget[0] -= 1
        name = ENDPOINTS[k % len(ENDPOINTS)]
        k += 1
        began = time.perf_counter()
        code = await connection.get(paths[name])
        stats[name]["latency"].append(time.perf_counter() - began)
        if code >= 400 or code == 0:
            stats[name]["errors"] += 1
        if code >= 500:
            stats[name]["server_errors"] += 1
        if interval > 0:
            await asyncio.sleep(interval)
    connection.close()


async def load_phase(server: Server, clients: int, run_id: int, experiment_id: int, best: int, args) -> dict:
    paths = {
        "status": f"/experiments/{experiment_id}",
        "runs": f"/runs?experiment={experiment_id}",
        "generations": f"/runs/{run_id}/generations",
        "front": f"/runs/{run_id}/front",
        "lineage": f"/individuals/{best}/lineage",
        "dashboard": f"/dashboard/runs/{run_id}",
    }
    stats = {name: {"latency": [], "errors": 0, "server_errors": 0} for name in ENDPOINTS}
    stop, budget = asyncio.Event(), [args.max_requests]
    rng = np.random.default_rng(clients)  # clients start spread over one interval
    tasks = [
        asyncio.create_task(client(Connection("127.0.0.1", server.port), paths, stats, stop,
                                   budget, args.interval, float(rng.uniform(0, args.interval)),
                                   c % len(ENDPOINTS)))
        for c in range(clients)
    ]  # fmt: skip
    started = time.monotonic()
    try:
        while time.monotonic() - started < args.seconds and budget[0] > 0:
            await asyncio.sleep(0.5)
            finished = await asyncio.to_thread(server.run, run_id)
            if finished.get("status") in ("finished", "failed", "cancelled"):
                break
    finally:
        stop.set()
        await asyncio.gather(*tasks)
    return {"stats": stats, "seconds": time.monotonic() - started}


def run_loaded(server: Server, clients: int, args) -> dict:
    experiment_id, run_id = server.submit(f"loaded-{clients}", args.generations, args.seed)
    run = wait_generation(server, run_id, 0, 120)  # the front and a best exist from here
    best = (run.get("best") or {}).get("individual_id") or 1
    phase = asyncio.run(load_phase(server, clients, run_id, experiment_id, best, args))
    if server.run(run_id)["status"] != "finished":
        server.cancel(run_id)
    evaluations, rate = server.throughput(run_id)
    rows = []
    for name in ENDPOINTS:
        s = phase["stats"][name]
        latency = np.array(s["latency"]) * 1000.0
        rows.append(
            {
                "endpoint": name,
                "requests": len(latency),
                "req_per_s": len(latency) / phase["seconds"],
                "p50_ms": float(np.percentile(latency, 50)) if len(latency) else float("nan"),
                "p99_ms": float(np.percentile(latency, 99)) if len(latency) else float("nan"),
                "errors": s["errors"],
                "server_errors": s["server_errors"],
            }
        )
    return {"clients": clients, "seconds": phase["seconds"], "rows": rows, "evaluations": evaluations,
            "eval_per_s": rate}  # fmt: skip


def print_table(unloaded: list[dict], loaded: list[dict]) -> None:
    rates = ", ".join(f"{u['eval_per_s']:.2f}" for u in unloaded)
    print(f"unloaded phases (before, between and after the loaded ones): {rates} evaluations/s")
    print()
    print("| clients | endpoint | requests | req/s | p50 ms | p99 ms | errors (5xx) |")
    print("| ---: | --- | ---: | ---: | ---: | ---: | ---: |")
    for k, phase in enumerate(loaded):
        for row in phase["rows"]:
            print(
                f"| {phase['clients']} | {row['endpoint']} | {row['requests']} | {row['req_per_s']:.0f} "
                f"| {row['p50_ms']:.0f} | {row['p99_ms']:.0f} | {row['errors']} ({row['server_errors']}) |"
            )
        total = sum(r["requests"] for r in phase["rows"])
        alone = (unloaded[k]["eval_per_s"] + unloaded[k + 1]["eval_per_s"]) / 2
        ratio = phase["eval_per_s"] / alone if alone else float("nan")
        print(
            f"| {phase['clients']} | **all** | {total} | {total / phase['seconds']:.0f} | | | "
            f"experiment {phase['eval_per_s']:.2f} eval/s = {ratio:.0%} of unloaded around it |"
        )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="short phases (about a minute in all)")
    parser.add_argument("--clients", default="50,200", help="client counts, one phase each")
    parser.add_argument("--seconds", type=float, default=None, help="each phase (default 40, quick 8)")
    parser.add_argument(
        "--generations", type=int, default=None,
        help="of the experiment, more than a phase stores (default 400, quick 100)",
    )  # fmt: skip
    parser.add_argument("--max-requests", type=int, default=200_000, help="requests per phase, at most")
    parser.add_argument(
        "--interval", type=float, default=1.0,
        help="seconds each client waits between its requests (default 1: twice as often as the "
        "dashboard polls a live run); 0 for clients that ask again at once (a stress test)",
    )  # fmt: skip
    parser.add_argument("--seed", type=int, default=3)
    parser.add_argument("--json", type=Path, default=None)
    args = parser.parse_args()
    args.seconds = args.seconds or (8.0 if args.quick else 40.0)
    args.generations = args.generations or (100 if args.quick else 400)
    counts = [int(c) for c in args.clients.split(",") if c]
    workdir = Path(tempfile.mkdtemp(prefix="softevo-load-"))
    server = Server(workdir)
    try:
        _, warm_run = server.submit("warm-up", 1, args.seed + 1000)  # spawns and warms the pool
        wait_generation(server, warm_run, 0, 300)
        # unloaded phases around every loaded one: the host's speed drifts
        unloaded, loaded = [run_alone(server, "unloaded-0", args)], []
        for k, clients in enumerate(counts):
            loaded.append(run_loaded(server, clients, args))
            unloaded.append(run_alone(server, f"unloaded-{k + 1}", args))
    finally:
        server.stop()
    print_table(unloaded, loaded)
    if args.json:
        args.json.write_text(json.dumps({"unloaded": unloaded, "loaded": loaded}, indent=2))
    shutil.rmtree(workdir, ignore_errors=True)


if __name__ == "__main__":
    main()
