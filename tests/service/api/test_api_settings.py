"""Settings of the service: environment variables, loopback-only without a token."""

from __future__ import annotations

import pytest

from softevo.errors import UserError
from softevo.service.settings import Settings
from tests.support import softevo


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


# -- issue 59.4: a new user's frictions ---------------------------------------------------------


def test_a_short_token_stops_only_the_commands_that_serve(monkeypatch, capsys):
    """A worker never reads SOFTEVO_TOKEN: a 12-character one refused its start (and every
    command's that loads the settings); ``serve`` still refuses it, in one line."""
    monkeypatch.setenv("SOFTEVO_TOKEN", "twelve-chars")
    monkeypatch.delenv("SOFTEVO_REDIS_URL", raising=False)
    assert Settings.load().token_value == "twelve-chars"
    code, _, err = softevo(capsys, "worker")
    assert code == 2 and "Redis URL" in err and "token" not in err, err
    with pytest.raises(UserError, match=r"setting token \(SOFTEVO_TOKEN\): a token needs at least 16"):
        Settings.load().check_safe()


def test_a_bad_option_names_the_flag_typed_and_a_variable_names_the_variable(monkeypatch, capsys):
    monkeypatch.delenv("SOFTEVO_PORT", raising=False)
    code, _, err = softevo(capsys, "serve", "--port", "99999")
    assert code == 2 and err.startswith("error: --port: input should be less than or equal to 65535"), err
    assert "SOFTEVO_PORT" not in err and "(got 99999)" in err and err.count("\n") == 1
    monkeypatch.setenv("SOFTEVO_PORT", "99999")
    code, _, err = softevo(capsys, "serve")
    assert code == 2 and err.startswith("error: setting port (SOFTEVO_PORT): input should be"), err


@pytest.mark.parametrize(
    "variable", [("SOFTEVO_WORKERS", "-1"), ("SOFTEVO_QUEUE", "a b"), ("SOFTEVO_ENGINE", "gpu")]
)
def test_no_setting_message_carries_the_librarys_value_error(monkeypatch, variable):
    monkeypatch.setenv(*variable)
    with pytest.raises(UserError) as caught:
        Settings.load()
    assert "Value error" not in str(caught.value) and variable[0] in str(caught.value)


def test_postgresql_without_its_driver_names_the_extra():
    """It said ``No module named 'psycopg'``; the README names the extra too."""
    import subprocess
    import sys
    from pathlib import Path

    code = ("import sys; sys.modules['psycopg'] = None\n"  # as if psycopg were not installed
            "from softevo.service.cli import main\n"
            "sys.argv = ['softevo', 'status', '--db', 'postgresql+psycopg://u:pw@127.0.0.1:1/x']\n"
            "main()")  # fmt: skip
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert done.returncode == 2, done.stderr
    assert done.stderr.count("\n") == 1 and "pip install 'softevo[postgres]'" in done.stderr, done.stderr
    readme = (Path(__file__).resolve().parents[3] / "README.md").read_text()
    assert "'.[postgres]'" in readme
