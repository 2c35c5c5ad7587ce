"""Settings of the service, from ``SOFTEVO_*`` environment variables: the one reader of them.

One pydantic-settings class read by ``softevo serve`` (API + coordinator), ``softevo worker``,
``softevo dashboard`` and the commands that open a database or check a limit. Every field is
an environment variable named ``SOFTEVO_`` + the field name in capitals (``db`` ->
``SOFTEVO_DB``); an empty variable counts as unset. Each field says what it means, who reads
it and, where it is not a plain value, how its default reads: ``settings_table()`` writes the
table of docs/cluster.md ("Settings") from them (``python -m softevo.service.settings``).

The ``max_*`` and background fields bound what one request or command may cost
(``service.runs.limits``): an expensive read (recorded frames, the report) runs in one background
process, at most once at a time per key, its answer cached; when ``background_queue`` of them
are already computing or waiting, a new one is refused with 429 and ``Retry-After``.

With no token the write endpoints are open, so the server refuses to start on any address
but the loopback one (``check_safe``), serves only requests naming a loopback host
(``trusted_hosts``) and takes writes with a JSON body or an ``X-Requested-With`` header only.
Tokens have at least 16 characters (``MIN_TOKEN_LENGTH``).
"""

from __future__ import annotations

import hashlib
import ipaddress
from typing import Any

from pydantic import Field, SecretStr, ValidationError, field_validator
from pydantic_settings import BaseSettings, SettingsConfigDict

from softevo.errors import UserError

LOOPBACK_NAMES = ("localhost", "localhost.localdomain", "ip6-localhost")
LOOPBACK_HOSTS = ("127.0.0.1", "::1", "[::1]", *LOOPBACK_NAMES)  # Host headers served without a token
MIN_TOKEN_LENGTH = 16
GENOMES_PER_TASK = 4  # genomes per RQ job or pool task: queue overhead against balance (dispatch)


def _field(default: Any, used_by: str, meaning: str, default_text: str = "", **bounds: Any) -> Any:
    """A setting: its default, who reads it, what it means and how the docs say its default
    (``default_text``; else the value, or "unset" for None)."""
    extra = {"used_by": used_by, "default_text": default_text}
    return Field(default, description=meaning, json_schema_extra=extra, **bounds)


class Settings(BaseSettings):
    """Service settings; see the module doc for the environment variables."""

    model_config = SettingsConfigDict(env_prefix="SOFTEVO_", extra="ignore")

    db: str = _field(
        "sqlite:///softevo.db", "serve, CLI",
        "SQLAlchemy URL (`postgresql+psycopg://user:pw@host/db` or `sqlite:///file.db`)",
    )
    redis_url: str | None = _field(None, "serve, worker", "Redis URL; unset: `serve` evaluates locally")
    token: SecretStr | None = _field(None, "serve", "bearer token of the write endpoints")
    host: str = _field("127.0.0.1", "serve, dashboard", "address to listen on")
    port: int = _field(8000, "serve, dashboard", "port to listen on", ge=1, le=65535)
    queue: str = _field(
        "softevo", "serve, worker",
        "RQ queue name (one per cluster)",
        pattern=r"^[A-Za-z0-9_.-]+$",
    )
    workers: int | None = _field(
        None, "serve",
        "local evaluation processes when Redis is unset",
        "all cores", ge=0,
    )
    genomes_per_job: int = _field(
        GENOMES_PER_TASK, "serve", "genomes per RQ job (queue overhead against balance)", ge=1
    )
    jobs_across_runs: bool = _field(
        False, "serve",
        "`true`: a job may hold genomes of many runs (GPU workers)",
    )
    engine: str = _field(
        "numba", "worker",
        '`numba`, `cuda` (docs/gpu.md) or `sleep` (no physics: "How many workers one coordinator feeds")',
        pattern=r"^(numba|cuda|sleep)$",
    )
    device: str | None = _field(
        None, "worker",
        "CUDA device (`cuda:0`, `cuda:1`, ...); the sleep engine's speed-up `x<factor>`",
        "cuda:0 with cuda",
    )
    job_timeout: int = _field(3600, "serve", "seconds a job may run before it fails", ge=1)
    job_retries: int = _field(3, "serve", "re-dispatches of a failed or abandoned job", ge=1)
    result_ttl: int = _field(600, "serve", "seconds Redis keeps a job's result", ge=10)
    heartbeat_ttl: int = _field(30, "worker", "a job whose worker is silent this long is re-dispatched", ge=3)
    coordinator: bool = _field(True, "serve", "`false`: serve the API only, drive no runs")
    reports: str = _field("reports", "serve", "directory of the experiment reports")
    read_token: SecretStr | None = _field(
        None, "serve",
        "bearer token of the expensive reads (frames, report); the write token works too",
        "unset (open)",
    )
    background_queue: int = _field(
        4, "serve",
        "simulations and reports computing or waiting at once; one more is 429 with `Retry-After`",
        ge=1, le=1000,
    )
    background_per_client: int = _field(
        2, "serve",
        "of those, started by one client address; more: 429",
        ge=1, le=1000,
    )
    frames_timeout: float = _field(
        300.0, "serve",
        "seconds of one frames simulation; then 504, its slot freed",
        gt=0, le=86400,
    )
    report_timeout: float = _field(
        900.0, "serve",
        "seconds of writing one report; then 504, its slot freed",
        gt=0, le=86400,
    )
    frames_cache_mb: int = _field(
        128, "serve",
        "memory for recorded frames (least recently used dropped first)",
        ge=0,
    )
    report_interval: float = _field(
        60.0, "serve",
        "seconds between rewrites of a live experiment's report",
        ge=0,
    )
    max_body_bytes: int = _field(1_000_000, "serve", "largest request body; larger: 413", ge=1024)
    max_json_depth: int = _field(
        32, "serve",
        "deepest nesting of a JSON body; deeper (or NaN, Infinity, 1e999): 422",
        ge=4, le=1000,
    )
    max_voxels: int = _field(
        8000, "serve, CLI",
        "voxels of a workspace (`--workspace`, REST) or a scene body (`simulate`)",
        ge=1,
    )
    max_voxel_steps: float = _field(2e9, "CLI", "voxels x steps of one `softevo simulate`", gt=0)
    max_runs_per_request: int = _field(1000, "serve", "runs one experiment may create", ge=1)
    max_request_voxel_steps: float = _field(
        5e16, "serve",
        "voxel-steps one experiment may ask, an upper bound: every evaluation at the guard on "
        "seconds (the paper grid at paper scale: 2.2e16)",
        gt=0,
    )
    max_server_voxel_steps: float = _field(
        5e17, "serve",
        "voxel-steps of the unfinished runs and a new one together",
        gt=0,
    )
    max_result_bytes: int = _field(
        1_000_000, "serve",
        "JSON of one RQ job's results; larger: rejected and re-queued",
        ge=1024,
    )
    max_concurrent_requests: int = _field(
        32, "serve",
        "requests in the routes at once; the others wait their turn (at most 40: the thread pool)",
        ge=1, le=40,
    )
    read_cache_seconds: float = _field(
        1.0, "serve",
        "a `GET` answered 200 is reused this long for the same URL (writes through the server empty the "
        "cache; not `/health`, frames, report); `0`: off",
        ge=0, le=60,
    )

    @classmethod
    def load(cls, **overrides: Any) -> Settings:
        """The settings from the environment, ``overrides`` that are not None winning (a
        command's options, each named ``--field-name``); a UserError naming the option the
        user typed, or else the variable, for a bad value."""
        given = {key: value for key, value in overrides.items() if value is not None}
        try:
            return cls(**given)
        except ValidationError as exc:
            raise UserError(setting_problem(exc.errors()[0], given)) from None

    @field_validator("redis_url", "token", "read_token", "workers", "device", mode="before")
    @classmethod
    def _empty_is_unset(cls, value):
        return None if value == "" else value

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
        """Raise UserError if the server would accept writes from the network unauthenticated,
        or a token is too short to guess hard (fewer than ``MIN_TOKEN_LENGTH`` characters).
        Only the commands that serve read the tokens and check them: a worker, or ``softevo
        run``, starts whatever ``SOFTEVO_TOKEN`` holds (issue 59.4)."""
        for name, value in (("token", self.token_value), ("read_token", self.read_token_value)):
            if value is not None and len(value) < MIN_TOKEN_LENGTH:
                raise UserError(
                    f"setting {name} (SOFTEVO_{name.upper()}): a token needs at least {MIN_TOKEN_LENGTH} "
                    "characters; make one with `openssl rand -hex 32`"
                )
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


def variable(name: str) -> str:
    """The environment variable of setting ``name`` (``redis_url`` -> ``SOFTEVO_REDIS_URL``),
    for a command that hands a setting on to processes it starts (``softevo slurm-workers``)."""
    if name not in Settings.model_fields:
        raise KeyError(f"no setting {name!r}")
    return f"SOFTEVO_{name.upper()}"


SECRETS = ("token", "read_token")  # never echoed in a message


def setting_problem(problem: dict[str, Any], given: dict[str, Any]) -> str:
    """One line for a setting pydantic refused: ``--port: ...`` when the user typed the option
    (a key of ``given``), else ``setting port (SOFTEVO_PORT): ...``; the library's "Value
    error, " left out, and the value given shown unless it is a secret."""
    name = ".".join(str(part) for part in problem["loc"])
    message = str(problem["msg"]).removeprefix("Value error, ")
    message = message[:1].lower() + message[1:]
    if name not in SECRETS and "input" in problem:
        message += f" (got {problem['input']!r})"
    where = f"--{name.replace('_', '-')}" if name in given else f"setting {name} (SOFTEVO_{name.upper()})"
    return f"{where}: {message}"


def settings_table() -> str:
    """The Markdown table of every setting (docs/cluster.md, "Settings")."""
    lines = ["| variable | used by | meaning | default |", "| --- | --- | --- | --- |"]
    for name, info in Settings.model_fields.items():
        extra = info.json_schema_extra or {}
        default = extra.get("default_text") or ("unset" if info.default is None else _plain(info.default))
        lines.append(f"| `{variable(name)}` | {extra['used_by']} | {info.description} | {default} |")
    return "\n".join(lines) + "\n"


def _plain(value: Any) -> str:
    if isinstance(value, bool):
        return f"`{str(value).lower()}`"
    if isinstance(value, float) and value >= 1e6:
        return f"`{value:.0e}`".replace("e+", "e")
    return f"`{value}`"


if __name__ == "__main__":
    print(settings_table(), end="")
