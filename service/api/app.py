"""The FastAPI application: ``create_app(settings)``.

The lifespan builds what the routes use (``Services``): the database engine (schema
upgraded), the executor (RQ when ``SOFTEVO_REDIS_URL`` is set, else local processes) and,
unless ``SOFTEVO_COORDINATOR=false``, the coordinator loop that drives every unfinished run
(``service.runs.driver``). Nothing is built at import time.

Errors are JSON ``{"detail": "<message>"}`` (422 adds ``errors``, the problems found).
"""

from __future__ import annotations

import asyncio
import logging
import threading
from collections.abc import AsyncIterator
from contextlib import asynccontextmanager
from typing import Any

from fastapi import APIRouter, FastAPI, HTTPException, Request
from fastapi.exceptions import RequestValidationError
from fastapi.responses import JSONResponse, RedirectResponse, Response
from sqlalchemy import Engine
from sqlalchemy.exc import DBAPIError, OperationalError
from sqlalchemy.exc import TimeoutError as PoolTimeout
from starlette.exceptions import HTTPException as StarletteHTTPException
from starlette.middleware.trustedhost import TrustedHostMiddleware
from starlette.routing import Match

from softevo import __version__
from softevo.errors import UserError
from softevo.service.api import docs_page
from softevo.service.api.dashboard import dashboard_router
from softevo.service.api.dashboard.pages import not_found
from softevo.service.api.expensive import Busy, ExpensiveReads
from softevo.service.api.frames import recorded_frames
from softevo.service.api.guards import BodyLimits, ConcurrencyLimit
from softevo.service.api.headers import SecurityHeaders
from softevo.service.api.read_cache import ReadCache
from softevo.service.api.routes import analyses, experiments, exports, health, individuals, phylogeny, runs
from softevo.service.api.routes import archive as archive_routes
from softevo.service.api.routes import plan as plan_routes
from softevo.service.api.routes import worlds as world_routes
from softevo.service.api.schemas import problem_line, request_problems
from softevo.service.reports.report import write_report
from softevo.service.runs.driver import CoordinatorLoop
from softevo.service.runs.executors import make_executor
from softevo.service.runs.locks import RedisLocks
from softevo.service.settings import Settings
from softevo.service.storage import open_database
from softevo.service.storage.advisory_locks import DatabaseLocks

log = logging.getLogger("softevo.api")


class Services:
    """What the app builds in its lifespan and the routes share."""

    def __init__(self, settings: Settings, engine: Engine) -> None:
        self.settings = settings
        self.engine = engine
        self.stop = threading.Event()
        self.executor: Any = None
        self.executor_kind = "none"
        self.loop: Any = None
        self._status_queue: Any = None
        self.reads = ExpensiveReads(
            settings.background_queue, settings.frames_cache_mb * 2**20, settings.background_per_client
        )
        self.report_failures: dict[int, Any] = {}  # experiment id -> its update time when it failed

    # -- building and closing ----------------------------------------------------------------

    def start(self) -> None:
        """Executor and coordinator loop (if this process coordinates)."""
        settings = self.settings
        if settings.redis_url:
            # rq and redis load only for a service configured with Redis
            from rq import Queue
            from rq.serializers import JSONSerializer

            from softevo.service.runs.rq_executor import connect

            self._status_queue = Queue(
                settings.queue, connection=connect(settings.redis_url), serializer=JSONSerializer
            )
            self.executor_kind = "rq"
        redis_away = not self.redis_reachable()
        if redis_away:  # one line now; the loop stays quiet until it is back
            log.warning("Redis cannot be reached (SOFTEVO_REDIS_URL): new experiments are refused (503) "
                        "and runs wait until it answers; this server goes on by itself then")
        if not settings.coordinator:
            return
        self.executor = self._make_executor()
        if settings.redis_url:
            locks = RedisLocks(settings.redis_url, settings.database_namespace())
        else:
            locks = DatabaseLocks(self.engine)  # two serve on one database: one drives a run
        self.loop = CoordinatorLoop(self.engine, self.executor, locks, stop=self.stop)
        if redis_away:
            self.loop.away = "Redis"
        self.loop.start()

    def _make_executor(self):
        settings = self.settings
        if settings.redis_url:
            from softevo.service.runs.rq_executor import RQExecutor  # only with Redis, as above

            return RQExecutor(
                settings.redis_url,
                queue=settings.queue,
                genomes_per_job=settings.genomes_per_job,
                job_timeout=settings.job_timeout,
                retries=settings.job_retries,
                result_ttl=settings.result_ttl,
                stop=self.stop,
                across_runs=settings.jobs_across_runs,
                max_result_bytes=settings.max_result_bytes,
            )
        self.executor_kind = "local"
        return make_executor(settings.workers, settings.genomes_per_job)

    def close(self) -> None:
        self.stop.set()
        if self.loop is not None:
            self.loop.stop()
        if self.executor is not None:
            self.executor.close()
        self.reads.close()
        self.engine.dispose()

    # -- used by the routes ------------------------------------------------------------------

    def executor_status(self) -> tuple[int, int, bool]:
        """(workers, queued jobs, reachable) of the executor."""
        if self._status_queue is not None:
            from rq import Worker  # only with Redis, as in start()
            from rq.worker_registration import clean_worker_registry

            try:
                clean_worker_registry(self._status_queue)
                return Worker.count(queue=self._status_queue), self._status_queue.count, True
            except Exception:
                return 0, 0, False
        if self.executor is not None:
            return int(self.executor.workers), 0, True
        return 0, 0, True

    def redis_reachable(self) -> bool:
        """Whether the Redis the runs' jobs go through answers (True without one)."""
        if self._status_queue is None:
            return True
        try:
            return bool(self._status_queue.connection.ping())
        except Exception:  # noqa: BLE001 - any failure to answer is "unreachable"
            return False

    def cancel(self, run_id: int) -> None:
        if self.loop is not None:
            self.loop.request_cancel(run_id)

    async def record_motion(
        self, task, every: int, max_frames: int, client: str = ""
    ) -> tuple[bytes, dict[str, str]]:
        """(body, headers) of ``task``'s recorded frames (``service.api.frames.recorded_frames``
        in the background process), cached by individual, world and recording settings;
        ``X-Cache`` says whether the answer was in the cache (``hit``) or computed (``miss``)."""
        key = ("frames", task.id, task.environment, task.evaluation.youngs_modulus, every, max_frames)
        hit = self.reads.cached(key) is not None
        body, headers = await self.reads.compute(
            key, recorded_frames, task, every, max_frames,
            timeout=self.settings.frames_timeout, client=client,
        )  # fmt: skip
        return body, {**headers, "X-Cache": "hit" if hit else "miss"}

    async def write_report(self, experiment_id: int, out_dir, client: str = "") -> Any:
        """``service.reports.report.write_report`` in the background process; concurrent requests
        for one experiment share one writing."""
        key = ("report", experiment_id)
        return await self.reads.compute(
            key, write_report, self.settings.db, experiment_id, str(out_dir),
            cache=False, timeout=self.settings.report_timeout, client=client,
        )  # fmt: skip


# -- errors ------------------------------------------------------------------------------------


def _error(status: int, message: str, headers: dict | None = None, **extra) -> JSONResponse:
    return JSONResponse({"detail": message, **extra}, status_code=status, headers=headers)


async def _validation_error(request: Request, exc: RequestValidationError) -> Response:
    errors = request_problems(exc.errors())
    if _dashboard_page(request):  # /dashboard/runs/abc: a page that says so, not JSON
        return not_found(request, f"There is no page {request.url.path} ({problem_line(errors)}).")
    return _error(422, problem_line(errors), errors=errors)


def _dashboard_page(request: Request) -> bool:
    """Whether ``request`` asks for a dashboard page (HTML), not its JSON helpers or assets."""
    path = request.url.path
    return path.startswith("/dashboard/") and not path.startswith(("/dashboard/api/", "/dashboard/static/"))


async def _http_error(request: Request, exc: StarletteHTTPException) -> JSONResponse:
    headers = dict(getattr(exc, "headers", None) or {})
    if exc.status_code == 405:
        headers["Allow"] = ", ".join(_allowed_methods(request))
        return _error(405, f"method {request.method} not allowed here", headers)
    return _error(exc.status_code, str(exc.detail), headers or None)


def _allowed_methods(request: Request) -> list[str]:
    """Every method some route serves at this path (Starlette's own 405 names only the first
    matching route's)."""
    methods: set[str] = set()
    for route in request.app.router.routes:
        match, _ = route.matches(request.scope)
        if match != Match.NONE:
            methods |= set(getattr(route, "methods", None) or ())
    return sorted(methods)


async def _pool_timeout(request: Request, exc: PoolTimeout) -> JSONResponse:
    log.warning("no database connection free for %s: %s", request.url.path, exc)
    return _error(
        503, "the server is busy: no database connection free; try again shortly", {"Retry-After": "1"}
    )


async def _busy(request: Request, exc: Busy) -> JSONResponse:
    return _error(429, str(exc), {"Retry-After": str(exc.retry_after)})


async def _user_error(request: Request, exc: UserError) -> JSONResponse:
    return _error(422, str(exc), errors=[])


async def _database_error(request: Request, exc: DBAPIError) -> JSONResponse:
    log.error("database error on %s: %s", request.url.path, exc)
    if isinstance(exc, OperationalError) or exc.connection_invalidated:
        return _error(503, "the database is unreachable; try again shortly")
    return _error(500, "database error")


def install_error_handlers(app: FastAPI) -> None:
    app.add_exception_handler(RequestValidationError, _validation_error)
    app.add_exception_handler(StarletteHTTPException, _http_error)
    app.add_exception_handler(HTTPException, _http_error)
    app.add_exception_handler(UserError, _user_error)
    app.add_exception_handler(Busy, _busy)
    app.add_exception_handler(PoolTimeout, _pool_timeout)
    app.add_exception_handler(DBAPIError, _database_error)


# -- the app -----------------------------------------------------------------------------------


def create_app(settings: Settings | None = None, read_only: bool = False) -> FastAPI:
    """The API for ``settings`` (default: from the environment); ``read_only``: the read
    routes alone (``softevo dashboard``: a write there is 405, token or not).

    Raises UserError when no token is set and ``settings.host`` is not a loopback address.
    """
    settings = settings or Settings.load()
    settings.check_safe()

    @asynccontextmanager
    async def lifespan(app: FastAPI) -> AsyncIterator[None]:
        services = Services(settings, open_database(settings.db))
        app.state.services = services
        services.start()
        try:
            yield
        finally:
            await asyncio.to_thread(services.close)

    app = FastAPI(
        title="softevo",
        summary="Evolve soft voxel robots on land and in water: experiments, runs, lineages.",
        version=__version__,
        lifespan=lifespan,
        docs_url=None,  # docs_page: vendored Swagger UI, no CDN; no ReDoc (it loads from a CDN)
        redoc_url=None,
    )
    app.state.settings = settings
    install_error_handlers(app)
    for module in (health, experiments, analyses, exports, runs, individuals, phylogeny, archive_routes):
        app.include_router(_reads_of(module.router) if read_only else module.router)
    app.include_router(world_routes.router)  # the world registry, read-only
    app.include_router(plan_routes.router)  # POST, but it stores nothing: read-only servers too
    app.include_router(dashboard_router())  # /dashboard pages and assets
    app.include_router(docs_page.router)  # /docs
    app.add_api_route("/", _front_door, methods=["GET", "HEAD"], include_in_schema=False)
    app.add_middleware(BodyLimits, max_bytes=settings.max_body_bytes, max_depth=settings.max_json_depth)
    app.add_middleware(ConcurrencyLimit, limit=settings.max_concurrent_requests)
    app.add_middleware(ReadCache, seconds=settings.read_cache_seconds)  # hits wait for nothing
    app.add_middleware(SecurityHeaders)  # nosniff, CSP and frame-ancestors on cached answers too
    if settings.token_value is None:  # loopback only: refuse DNS-rebinding names (docs/security.md)
        app.add_middleware(TrustedHostMiddleware, allowed_hosts=settings.trusted_hosts())
    return app


def _front_door(request: Request) -> RedirectResponse:
    """``/``: the dashboard (the API is at ``/docs``, ``/openapi.json``)."""
    root = request.scope.get("root_path", "").rstrip("/")
    return RedirectResponse(f"{root}/dashboard/", status_code=307)


def _reads_of(router: APIRouter) -> APIRouter:
    """A router of ``router``'s read routes (GET, HEAD) alone; ``router`` is left as it is."""
    reads = APIRouter()
    reads.routes.extend(r for r in router.routes if not set(getattr(r, "methods", ())) - {"GET", "HEAD"})
    return reads
