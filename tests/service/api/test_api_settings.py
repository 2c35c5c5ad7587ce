"""Settings of the service: environment variables, loopback-only without a token."""

from __future__ import annotations

import pytest

from softevo.errors import UserError
from softevo.service.settings import Settings


@pytest.mark.parametrize("host", ["127.0.0.1", "127.0.0.2", "::1", "localhost"])
def test_without_a_token_loopback_is_allowed(host):
    Settings(host=host, token=None).check_safe()


@pytest.mark.parametrize("host", ["0.0.0.0", "::", "192.168.1.10", "example.org"])
def test_without_a_token_other_addresses_are_refused(host):
    with pytest.raises(UserError, match="SOFTEVO_TOKEN"):
        Settings(host=host, token=None).check_safe()
    Settings(host=host, token="secret-16-characters").check_safe()


def test_environment_variables(monkeypatch):
    monkeypatch.setenv("SOFTEVO_DB", "postgresql+psycopg://u:pw@db/softevo")
    monkeypatch.setenv("SOFTEVO_REDIS_URL", "")  # empty counts as unset
    monkeypatch.setenv("SOFTEVO_TOKEN", "s3cr3t-token-0123456")
    monkeypatch.setenv("SOFTEVO_PORT", "9000")
    settings = Settings()
    assert settings.db.startswith("postgresql+psycopg://") and settings.redis_url is None
    assert settings.token_value == "s3cr3t-token-0123456" and "s3cr3t" not in repr(settings)
    assert (settings.host, settings.port) == ("127.0.0.1", 9000)


def test_database_namespace_ignores_the_password():
    a = Settings(db="postgresql+psycopg://u:one@db/softevo").database_namespace()
    b = Settings(db="postgresql+psycopg://u:two@db/softevo").database_namespace()
    c = Settings(db="postgresql+psycopg://u:one@db/other").database_namespace()
    assert a == b != c
