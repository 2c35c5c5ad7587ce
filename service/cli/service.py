"""``softevo serve`` (REST API + coordinator), ``softevo worker`` (RQ worker) and
``softevo slurm-workers`` (workers as a SLURM job array).

Both read their settings from ``SOFTEVO_*`` environment variables (``service.settings``);
the options below override them for one invocation.
"""

from __future__ import annotations

from typing import Annotated

import typer

from softevo.errors import UserError
from softevo.service.cli.options import device_option, engine_option, redis_url_option
from softevo.service.settings import Settings, variable
from softevo.worker.slurm import DRAIN, OUTPUT


def serve(
    host: Annotated[str | None, typer.Option("--host", help="default $SOFTEVO_HOST or 127.0.0.1")] = None,
    port: Annotated[int | None, typer.Option("--port", help="default $SOFTEVO_PORT or 8000")] = None,
    db: Annotated[str | None, typer.Option("--db", help="SQLAlchemy URL (default $SOFTEVO_DB)")] = None,
    redis_url: redis_url_option("default $SOFTEVO_REDIS_URL; unset: local processes") = None,
    no_coordinator: Annotated[
        bool, typer.Option("--no-coordinator", help="serve the API only; drive no runs")
    ] = False,
    log_level: Annotated[str, typer.Option("--log-level")] = "info",
) -> None:
    """Serve the REST API (OpenAPI at /docs) and drive every unfinished run.

    Write endpoints need 'Authorization: Bearer $SOFTEVO_TOKEN'; without a token the server
    only listens on loopback.
    """
    import logging

    import uvicorn

    from softevo.service.api.app import create_app
    from softevo.service.cli.dashboard import check_database, check_port

    settings = Settings.load(
        host=host, port=port, db=db, redis_url=redis_url, coordinator=False if no_coordinator else None
    )
    settings.check_safe()
    check_database(settings.db)
    check_port(settings.host, settings.port)
    logging.basicConfig(level=log_level.upper(), format="%(asctime)s %(name)s %(message)s")
    uvicorn.run(create_app(settings), host=settings.host, port=settings.port, log_level=log_level)


def worker(
    redis_url: redis_url_option("default $SOFTEVO_REDIS_URL") = None,
    queue: Annotated[str | None, typer.Option("--queue", help="default $SOFTEVO_QUEUE")] = None,
    name: Annotated[str | None, typer.Option("--name", help="default <host>-<pid>")] = None,
    threads: Annotated[int, typer.Option("--threads", help="numba threads per batch")] = 1,
    heartbeat_ttl: Annotated[
        int | None,
        typer.Option("--heartbeat-ttl", help="seconds; default $SOFTEVO_HEARTBEAT_TTL or 30"),
    ] = None,
    burst: Annotated[
        bool, typer.Option("--burst", help="quit once the queue is drained (empty, nothing running)")
    ] = False,
    idle: Annotated[
        int | None,
        typer.Option("--idle", help="with --burst: seconds drained before quitting; default 5"),
    ] = None,
    connect_timeout: Annotated[
        float | None,
        typer.Option("--connect-timeout", help="seconds to wait for Redis at the start; default 5"),
    ] = None,
    engine: engine_option("default $SOFTEVO_ENGINE or numba") = None,
    device: device_option("default $SOFTEVO_DEVICE") = None,
) -> None:
    """Evaluate genomes for a coordinator: an RQ worker on the Redis of $SOFTEVO_REDIS_URL.

    Needs only the Redis URL (no database). Run one per core; with ``--engine cuda --device
    cuda:0``, one per GPU, fed large jobs (docs/cluster.md, "GPU workers").
    """
    import os

    from softevo.worker.evaluate import DEVICE_ENV, ENGINE_ENV
    from softevo.worker.rq_worker import run_worker

    settings = Settings.load(
        redis_url=redis_url, queue=queue, heartbeat_ttl=heartbeat_ttl, engine=engine, device=device
    )
    # the evaluations of this process and its job processes read them (evaluate.engine_options)
    os.environ[ENGINE_ENV] = settings.engine
    if settings.device is not None:
        os.environ[DEVICE_ENV] = settings.device
    if not settings.redis_url:
        raise UserError("softevo worker needs a Redis URL: set SOFTEVO_REDIS_URL or --redis-url")
    if threads < 1:
        raise UserError(f"--threads must be >= 1 (got {threads})")
    if (idle is not None and idle < 1) or (connect_timeout is not None and connect_timeout <= 0):
        raise UserError(f"--idle must be >= 1 and --connect-timeout > 0 (got {idle}, {connect_timeout})")
    waits = {"idle": idle, "connect_timeout": connect_timeout}
    run_worker(
        settings.redis_url,
        queue=settings.queue,
        name=name,
        threads=threads,
        heartbeat_ttl=settings.heartbeat_ttl,
        burst=burst,
        **{key: value for key, value in waits.items() if value is not None},
    )


def slurm_workers(
    array: Annotated[int, typer.Option("--array", help="workers: array tasks of one worker each")],
    redis_url: redis_url_option("default $SOFTEVO_REDIS_URL; travels in the job's environment") = None,
    queue: Annotated[str | None, typer.Option("--queue", help="default $SOFTEVO_QUEUE")] = None,
    time: Annotated[
        str | None, typer.Option("--time", help="each worker's time limit (sbatch --time, 30:00, 1-12)")
    ] = None,
    drain: Annotated[
        int, typer.Option("--drain", help="seconds before the time limit that a worker stops taking jobs")
    ] = DRAIN,
    partition: Annotated[str | None, typer.Option("--partition", help="sbatch --partition")] = None,
    threads: Annotated[int, typer.Option("--threads", help="numba threads (and CPUs) per worker")] = 1,
    output: Annotated[str, typer.Option("--output", help="sbatch's log file pattern")] = OUTPUT,
    sbatch: Annotated[
        list[str] | None, typer.Option("--sbatch", help="one more sbatch option (--sbatch=--account=abc)")
    ] = None,
    show: Annotated[bool, typer.Option("--print", help="print the sbatch script; submit nothing")] = False,
) -> None:
    """Start workers as a SLURM job array (sbatch) against the coordinator's Redis.

    Prints the array's job id (scancel JOB_TASK stops one worker; its job goes back to the
    queue). Each worker drains on the SIGTERM that SLURM sends --drain seconds before the
    time limit (docs/cluster.md, "SLURM").
    """
    import os

    from softevo.worker.slurm import WorkerArray, batch_script, submit

    settings = Settings.load(redis_url=redis_url, queue=queue)
    script = batch_script(
        WorkerArray(
            workers=array,
            queue=settings.queue,
            threads=threads,
            time=time,
            drain=drain,
            partition=partition,
            output=output,
            sbatch=tuple(sbatch or ()),
        )
    )
    if show:
        typer.echo(script, nl=False)
        return
    if not settings.redis_url:
        raise UserError("softevo slurm-workers needs a Redis URL: set SOFTEVO_REDIS_URL or --redis-url")
    job = submit(script, {**os.environ, variable("redis_url"): settings.redis_url})
    typer.echo(job)
    typer.echo(f"submitted {array} worker(s) as SLURM job array {job} on queue {settings.queue}", err=True)


def register(app: typer.Typer) -> None:
    """Add ``serve``, ``worker`` and ``slurm-workers`` to ``app``."""
    for command in (serve, worker):
        app.command(name=command.__name__)(command)
    app.command(name="slurm-workers")(slurm_workers)
