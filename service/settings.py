"""Settings of the distributed service, from ``SOFTEVO_*`` environment variables.

One pydantic-settings class read by ``softevo serve`` (API + coordinator) and ``softevo
worker``. Every field is an environment variable named ``SOFTEVO_`` + the field name in
capitals (``db`` -> ``SOFTEVO_DB``); an empty variable counts as unset.

========================  ======================================================  ==============
variable                  meaning                                                 default
========================  ======================================================  ==============
SOFTEVO_DB                SQLAlchemy URL of the database (coordinator only)        sqlite:///softevo.db
SOFTEVO_REDIS_URL         Redis URL; unset: the coordinator evaluates locally      unset
SOFTEVO_TOKEN             bearer token of the write endpoints                      unset
SOFTEVO_HOST              address ``softevo serve`` listens on                     127.0.0.1
SOFTEVO_PORT              port ``softevo serve`` listens on                        8000
SOFTEVO_QUEUE             RQ queue name shared by coordinator and workers          softevo
SOFTEVO_WORKERS           local evaluation processes when Redis is unset           all cores
SOFTEVO_GENOMES_PER_JOB   genomes per RQ job (queue overhead vs balance)           4
SOFTEVO_JOBS_ACROSS_RUNS  true: one job may hold many runs' genomes (GPU workers)    false
SOFTEVO_JOB_TIMEOUT       seconds an RQ job may run before it fails                3600
SOFTEVO_JOB_RETRIES       re-dispatches of a failed or abandoned RQ job            3
SOFTEVO_RESULT_TTL        seconds Redis keeps a job's result                       600
SOFTEVO_HEARTBEAT_TTL     a worker silent this long has its job re-dispatched      30
SOFTEVO_COORDINATOR       ``serve`` also drives runs (false: API only)             true
SOFTEVO_REPORTS           directory of experiment reports                          reports
SOFTEVO_READ_TOKEN        bearer token of the expensive reads (frames, report)     unset (open)
SOFTEVO_BACKGROUND_QUEUE  expensive reads computing or waiting at once; more: 429   4
SOFTEVO_BACKGROUND_PER_CLIENT  of those, started by one client address; more: 429  2
SOFTEVO_FRAMES_TIMEOUT    seconds of one frames simulation; then 504, slot freed   300
SOFTEVO_REPORT_TIMEOUT    seconds of writing one report; then 504, slot freed      900
SOFTEVO_FRAMES_CACHE_MB   memory kept for recorded frames (LRU)                    128
SOFTEVO_REPORT_INTERVAL   seconds between rebuilds of a live experiment's report   60
SOFTEVO_MAX_BODY_BYTES    largest request body; larger: 413                        1000000
SOFTEVO_MAX_JSON_DEPTH    deepest nesting of a JSON body; deeper: 422              32
SOFTEVO_MAX_VOXELS        voxels of a workspace or scene body, at most             8000
SOFTEVO_MAX_VOXEL_STEPS   voxels x steps of one ``softevo simulate``, at most      2000000000
SOFTEVO_MAX_RUNS_PER_REQUEST  runs one experiment may create, at most           1000
SOFTEVO_MAX_REQUEST_VOXEL_STEPS  voxel-steps one experiment may ask, at most     1e16
SOFTEVO_MAX_SERVER_VOXEL_STEPS  voxel-steps of the unfinished runs and a new one  1e17
SOFTEVO_MAX_RESULT_BYTES  JSON of one RQ job's results; larger: rejected, re-queued 1000000
SOFTEVO_MAX_CONCURRENT_REQUESTS  requests in the routes at once (others wait)      32
SOFTEVO_READ_CACHE_SECONDS  a GET's answer is reused this long (0: off)            1
========================  ======================================================  ==============

The last group bounds what one request or command may cost (``service.limits``): an
expensive read (recorded frames, the report) runs in one background process, at most once at
a time per key, its answer cached; when ``SOFTEVO_BACKGROUND_QUEUE`` of them are already
computing or waiting, a new one is refused with 429 and ``Retry-After``.

With no token the write endpoints are open, so the server refuses to start on any address
but the loopback one (``check_safe``), serves only requests naming a loopback host
(``trusted_hosts``) and takes writes with a JSON body or an ``X-Requested-With`` header only.
Tokens have at least 16 characters (``MIN_TOKEN_LENGTH``).
"""

from __future__ import annotations

import hashlib
import ipaddress

from pydantic import Field, SecretStr, field_validator
from pydantic_settings import BaseSettings, SettingsConfigDict

from softevo.errors import UserError

LOOPBACK_NAMES = ("localhost", "localhost.localdomain", "ip6-localhost")
LOOPBACK_HOSTS = ("127.0.0.1", "::1", "[::1]", *LOOPBACK_NAMES)  # Host headers served without a token
MIN_TOKEN_LENGTH = 16


class Settings(BaseSettings):
    """Service settings; see the module doc for the environment variables."""

    model_config = SettingsConfigDict(env_prefix="SOFTEVO_", extra="ignore")

    db: str = "sqlite:///softevo.db"
    redis_url: str | None = None
    token: SecretStr | None = None
    host: str = "127.0.0.1"
    port: int = Field(8000, ge=1, le=65535)
    queue: str = Field("softevo", pattern=r"^[A-Za-z0-9_.-]+$")
    workers: int | None = Field(None, ge=0)
    genomes_per_job: int = Field(4, ge=1)
    jobs_across_runs: bool = False  # GPU workers: one job holds all runs' genomes of a round
    job_timeout: int = Field(3600, ge=1)
    job_retries: int = Field(3, ge=1)
    result_ttl: int = Field(600, ge=10)
    heartbeat_ttl: int = Field(30, ge=3)
    coordinator: bool = True
    reports: str = "reports"
    read_token: SecretStr | None = None
    background_queue: int = Field(4, ge=1, le=1000)
    background_per_client: int = Field(2, ge=1, le=1000)  # of background_queue, per client address
    frames_timeout: float = Field(300.0, gt=0, le=86400)  # seconds of one frames simulation
    report_timeout: float = Field(900.0, gt=0, le=86400)  # seconds of writing one report
    frames_cache_mb: int = Field(128, ge=0)
    report_interval: float = Field(60.0, ge=0)
    max_body_bytes: int = Field(1_000_000, ge=1024)
    max_json_depth: int = Field(32, ge=4, le=1000)
    max_voxels: int = Field(8000, ge=1)
    max_voxel_steps: float = Field(2e9, gt=0)
    max_runs_per_request: int = Field(1000, ge=1)
    max_request_voxel_steps: float = Field(1e16, gt=0)  # the paper grid at paper scale: 3.3e15
    max_server_voxel_steps: float = Field(1e17, gt=0)
    max_result_bytes: int = Field(1_000_000, ge=1024)
    max_concurrent_requests: int = Field(32, ge=1, le=40)  # below the 40 threads, 50 connections
    read_cache_seconds: float = Field(1.0, ge=0, le=60)

    @field_validator("redis_url", "token", "read_token", "workers", mode="before")
    @classmethod
    def _empty_is_unset(cls, value):
        return None if value == "" else value

    @field_validator("token", "read_token")
    @classmethod
    def _long_enough(cls, value: SecretStr | None) -> SecretStr | None:
        if value is not None and len(value.get_secret_value()) < MIN_TOKEN_LENGTH:
            raise ValueError(
                f"a token needs at least {MIN_TOKEN_LENGTH} characters; make one with `openssl rand -hex 32`"
            )
        return value

    def trusted_hosts(self) -> list[str]:
        """Host header names served when no token is set: loopback names (and ``host``), so a
        DNS-rebinding page (``Host: rebind.attacker.example``) is refused."""
        return sorted({*LOOPBACK_HOSTS, self.host.lower()})

    @property
    def token_value(self) -> str | None:
        """The bearer token in clear (None when unset)."""
        return self.token.get_secret_value() if self.token else None

    @property
    def read_token_value(self) -> str | None:
        """The token of the expensive reads in clear (None: they are open)."""
        return self.read_token.get_secret_value() if self.read_token else None

    def is_loopback(self) -> bool:
        """Whether ``host`` only accepts connections from this machine."""
        if self.host.lower() in LOOPBACK_NAMES:
            return True
        try:
            return ipaddress.ip_address(self.host).is_loopback
        except ValueError:
            return False

    def check_safe(self) -> None:
        """Raise UserError if the server would accept writes from the network unauthenticated."""
        if self.token_value is None and not self.is_loopback():
            raise UserError(
                f"refusing to serve on {self.host}: set SOFTEVO_TOKEN (the write endpoints "
                "need a bearer token) or listen on 127.0.0.1"
            )

    def database_namespace(self) -> str:
        """A short stable name of the database (password left out) for Redis keys, so that
        coordinators of different databases sharing one Redis never share a lock."""
        from sqlalchemy.engine import make_url

        try:
            text = make_url(self.db).render_as_string(hide_password=True)
        except Exception:  # a malformed URL fails later, in make_engine, with a clear message
            text = self.db
        return hashlib.sha1(text.encode()).hexdigest()[:12]
