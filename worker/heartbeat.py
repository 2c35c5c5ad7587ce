"""Heartbeat of a ``softevo worker``: a small companion process that keeps the worker's
running job marked alive in Redis, so that a worker killed mid-job (SIGKILL, power loss)
has its job re-dispatched within ``ttl`` seconds instead of RQ's default of the job timeout
plus a minute.

Why a process and not a thread: the simulator's compiled kernels hold the GIL for the whole
batch, which would starve a heartbeat thread and make a busy worker look dead.

The worker writes its current RQ worker name on this process's stdin (one line per name;
it changes when the worker restarts after Redis went away). Every second (or ``ttl / 5``
if shorter) this process moves the score of each of that worker's executions in the
queue's ``StartedJobRegistry`` to ``now + ttl`` (RQ's own score is the job timeout plus a
minute), only for entries still there (``XX``), and shortens the worker key's expiry to
``2 * ttl``. When the worker dies its end of the pipe closes: stdin reads EOF, this process
marks the worker's executions expired at once and exits. The coordinator's periodic
``StartedJobRegistry.cleanup()`` then re-queues the job (RQ's ``Retry``). If the whole
machine goes, the entries expire ``ttl`` seconds after the last beat.

    SOFTEVO_HEARTBEAT_REDIS=redis://... python -m softevo.worker.heartbeat QUEUE TTL_SECONDS

(the URL travels in the environment, not on the command line where ``ps`` shows it).

SIGTERM and SIGINT are ignored (the worker starts this process so: ``rq_worker.start_heartbeat``):
they are meant for the worker, but reach this process too when they go to all of the
worker's processes (Ctrl-C in a terminal, ``scancel`` or a time limit under SLURM). This
process ends with the worker's pipe.
"""

from __future__ import annotations

import os
import select
import sys
import time

from redis import Redis
from redis.exceptions import RedisError
from rq.executions import WORKER_EXECUTIONS_KEY_TEMPLATE
from rq.registry import StartedJobRegistry
from rq.utils import current_timestamp
from rq.worker import Worker


def beat(connection: Redis, registry_key: str, worker_name: str, ttl: int) -> int:
    """Keep the worker's running executions alive ``ttl`` more seconds (``ttl`` 0: expire
    them now); return how many there were."""
    executions = connection.smembers(WORKER_EXECUTIONS_KEY_TEMPLATE.format(worker_name))
    deadline = current_timestamp() + ttl if ttl > 0 else 1
    with connection.pipeline(transaction=False) as pipe:
        for composite_key in executions:
            pipe.zadd(registry_key, {composite_key: deadline}, xx=True)
        pipe.expire(Worker.redis_worker_namespace_prefix + worker_name, max(1, 2 * ttl))
        pipe.execute()
    return len(executions)


def run(redis_url: str, queue: str, ttl: int, stream=None) -> None:
    """Beat until ``stream`` (stdin) reaches EOF, i.e. until the worker process is gone."""
    fd = (stream or sys.stdin).fileno()
    connection = Redis.from_url(redis_url, socket_timeout=5, socket_connect_timeout=5)
    registry_key = StartedJobRegistry(queue, connection=connection).key
    interval = min(1.0, ttl / 5)
    name: str | None = None
    pending = b""
    next_beat = 0.0
    while True:
        wait = max(0.0, next_beat - time.monotonic())
        if select.select([fd], [], [], wait)[0]:
            data = os.read(fd, 4096)
            if not data:  # the worker is gone: its job is abandoned
                _beat_quietly(connection, registry_key, name, 0)
                return
            *lines, pending = (pending + data).split(b"\n")
            if lines:
                name = lines[-1].decode().strip() or None
            continue
        _beat_quietly(connection, registry_key, name, ttl)
        next_beat = time.monotonic() + interval


def _beat_quietly(connection: Redis, registry_key: str, name: str | None, ttl: int) -> None:
    if name is None:
        return
    try:
        beat(connection, registry_key, name, ttl)
    except RedisError:
        pass  # Redis restarting: nothing to keep alive there now


if __name__ == "__main__":
    run(os.environ["SOFTEVO_HEARTBEAT_REDIS"], sys.argv[1], int(sys.argv[2]))
