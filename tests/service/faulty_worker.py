"""A real ``softevo worker`` whose job function misbehaves on cue, for the fault tests.

    SOFTEVO_FAULTY_PLAN=garbage,oversized,badtype python -m tests.service.faulty_worker URL QUEUE NAME

Job k (counted in Redis across attempts) returns, for the k-th word of the plan: ``garbage``
a JSON object instead of a list, ``oversized`` a result padded past 2 MB, ``badtype`` a
distance that is a string, ``ok`` (or past the plan) the true results. With
``SOFTEVO_FAULTY_SLOW=G`` the first task of generation G it meets, and every later attempt
at it, sleeps ``SOFTEVO_FAULTY_SLEEP`` seconds first (past the job timeout). Each call is
counted under ``<queue>:calls:<task id>:<generation>``.
"""

from __future__ import annotations

import os
import sys
import time

from redis import Redis

import softevo.worker.evaluate as evaluate
from softevo.worker.rq_worker import run_worker

real_evaluate = evaluate.evaluate_batch


def main(url: str, queue: str, name: str) -> None:
    plan = [word for word in os.environ.get("SOFTEVO_FAULTY_PLAN", "").split(",") if word]
    slow = os.environ.get("SOFTEVO_FAULTY_SLOW")
    sleep = float(os.environ.get("SOFTEVO_FAULTY_SLEEP", "5"))
    redis = Redis.from_url(url)

    def faulty(tasks: list[dict], threads: int | None = None) -> list[dict]:
        if not any("run_id" in task for task in tasks):  # the worker's own warm-up
            return real_evaluate(tasks, threads)
        for task in tasks:
            redis.incr(f"{queue}:calls:{task.get('id')}:{task.get('generation')}")
        if slow is not None:
            for task in tasks:
                if task.get("generation") == int(slow):
                    redis.set(f"{queue}:slow", task["id"], nx=True)
                    if int(redis.get(f"{queue}:slow")) == task["id"]:
                        time.sleep(sleep)
        results = real_evaluate(tasks, threads)
        job = redis.incr(f"{queue}:jobs")
        fault = plan[job - 1] if job <= len(plan) else "ok"
        if fault == "garbage":
            return {"results": "not a list"}  # type: ignore[return-value]
        if fault == "oversized":
            results[0]["phenotype"] = {"padding": "x" * 2_100_000}
        if fault == "badtype":
            results[0]["distance"] = "far"
        return results

    evaluate.evaluate_batch = faulty  # RQ resolves the job function by name, at each job
    run_worker(url, queue, name=name, heartbeat_ttl=3)


if __name__ == "__main__":
    main(*sys.argv[1:4])
