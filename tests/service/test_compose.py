"""docker-compose.yml and the Dockerfile against the CLI and the settings class (no Docker
engine here: the files are parsed, not run)."""

from __future__ import annotations

import re
from pathlib import Path

import pytest
import typer
import yaml
from sqlalchemy.engine import make_url

from softevo.service.settings import Settings

REPO = Path(__file__).resolve().parents[2]
SETTINGS_VARIABLES = {f"SOFTEVO_{name.upper()}": name for name in Settings.model_fields}
INTERPOLATION = re.compile(r"\$\{(\w+)(?::?([-?])([^}]*))?\}")
REQUIRED = {"SOFTEVO_TOKEN": "t0ken-0123456789ab", "SOFTEVO_REDIS_PASSWORD": "r3dis"}  # no defaults


@pytest.fixture(scope="module")
def compose() -> dict:
    return yaml.safe_load((REPO / "docker-compose.yml").read_text())


def interpolate(value: str, environment: dict[str, str]) -> str:
    """Compose's ``${VAR}``, ``${VAR:-default}`` and ``${VAR:?error}`` (``$$`` is a ``$``)."""

    def replace(match: re.Match) -> str:
        name, kind, rest = match.groups()
        if name in environment:
            return environment[name]
        if kind == "?":
            raise KeyError(f"{name}: {rest}")
        return rest or ""

    return INTERPOLATION.sub(replace, str(value)).replace("$$", "$")


def environment_of(service: dict, variables: dict[str, str] | None = None) -> dict[str, str]:
    env = service.get("environment", {})
    if isinstance(env, list):
        env = dict(item.split("=", 1) for item in env)
    return {key: interpolate(value, variables or {}) for key, value in env.items()}


def cli_commands() -> set[str]:
    from softevo.service import cli

    cli._register()
    return set(typer.main.get_command(cli.app).commands)


def test_services_and_their_commands(compose):
    services = compose["services"]
    assert set(services) == {"redis", "postgres", "api", "worker"}
    assert services["api"]["command"] == ["softevo", "serve"]
    assert services["worker"]["command"] == ["softevo", "worker"]
    assert {"serve", "worker"} <= cli_commands()
    assert services["api"]["image"] == services["worker"]["image"]
    assert services["api"]["build"] == services["worker"]["build"] == "."
    assert "ports" not in services["worker"]  # scaled with --scale worker=N
    assert "container_name" not in services["worker"]
    assert set(services["api"]["depends_on"]) == {"redis", "postgres"}
    assert set(services["worker"]["depends_on"]) >= {"redis"}


def test_environment_variables_are_settings(compose):
    for name in ("api", "worker"):
        env = environment_of(compose["services"][name], REQUIRED)
        unknown = set(env) - set(SETTINGS_VARIABLES)
        assert not unknown, f"{name}: {unknown} are not fields of service.settings.Settings"


def test_api_settings_are_valid_and_safe(compose):
    api = compose["services"]["api"]
    with pytest.raises(KeyError, match="SOFTEVO_TOKEN"):
        environment_of(api, {"SOFTEVO_REDIS_PASSWORD": "r3dis"})  # no API without a token
    env = environment_of(api, REQUIRED)
    settings = Settings(**{SETTINGS_VARIABLES[key]: value for key, value in env.items()})
    settings.check_safe()  # a token is set, so 0.0.0.0 is allowed
    assert settings.host == "0.0.0.0" and settings.token_value == "t0ken-0123456789ab"
    database = make_url(settings.db)
    assert database.drivername == "postgresql+psycopg" and database.host == "postgres"
    assert database.database == compose["services"]["postgres"]["environment"]["POSTGRES_DB"]
    assert settings.redis_url.startswith("redis://") and "@redis:6379" in settings.redis_url
    published = [str(port).rsplit(":", 1)[-1] for port in api["ports"]]
    assert str(settings.port) in published


def test_workers_need_the_redis_url_alone(compose):
    env = environment_of(compose["services"]["worker"], REQUIRED)
    api = environment_of(compose["services"]["api"], REQUIRED)
    assert "SOFTEVO_DB" not in env  # a worker never touches SQL
    assert env["SOFTEVO_REDIS_URL"] == api["SOFTEVO_REDIS_URL"]
    assert env.get("SOFTEVO_QUEUE", "softevo") == api.get("SOFTEVO_QUEUE", "softevo")
    password = compose["services"]["redis"]["command"]
    assert interpolate(password[-1], REQUIRED) == "r3dis"
    assert env["SOFTEVO_REDIS_URL"] == "redis://:r3dis@redis:6379/0"


def test_redis_needs_a_password_and_listens_on_loopback(compose):
    """No fallback password (issue 30: anyone who writes to Redis tells the workers what to
    do), and Redis is published on 127.0.0.1 unless SOFTEVO_REDIS_PUBLISH says otherwise."""
    redis = compose["services"]["redis"]
    only_token = {"SOFTEVO_TOKEN": "t0ken-0123456789ab"}
    for value in [*redis["command"], *redis["environment"].values()]:
        if "SOFTEVO_REDIS_PASSWORD" in str(value):
            with pytest.raises(KeyError, match="SOFTEVO_REDIS_PASSWORD"):
                interpolate(value, only_token)
    for name in ("api", "worker"):
        with pytest.raises(KeyError, match="SOFTEVO_REDIS_PASSWORD"):
            environment_of(compose["services"][name], only_token)
    assert "softevo" not in interpolate(redis["command"][-1], REQUIRED)
    assert redis["environment"]["REDISCLI_AUTH"].startswith("${SOFTEVO_REDIS_PASSWORD:?")
    published = [interpolate(port, REQUIRED) for port in redis["ports"]]
    assert published == ["127.0.0.1:6379:6379"]
    text = (REPO / "docker-compose.yml").read_text()
    assert "SOFTEVO_REDIS_PASSWORD:-" not in text and "0.0.0.0:6379" not in text


def test_dockerfile_installs_the_package_with_postgres(compose):
    dockerfile = (REPO / "Dockerfile").read_text()
    assert re.search(r'pip install "?\.\[postgres\]"?', dockerfile)
    for package in ("softevo", "sim", "evolution", "service", "worker", "migrations"):
        assert f"COPY {package} " in dockerfile
    assert 'CMD ["softevo", "serve"]' in dockerfile
    assert "warm()" in dockerfile  # numba's cache is filled at build time
