"""Every database failure of the command line is one line on stderr and exit status 2
(issue 28, item 3), and a read-only command never creates a database (item 10)."""

from __future__ import annotations

import pytest

from tests.analysis.cli import softevo

REFUSED = "postgresql+psycopg://u:secret@127.0.0.1:1/x"


def _not_a_database(tmp_path) -> str:
    path = tmp_path / "notes.db"
    path.write_text("these are my notes, not a database\n")
    return f"sqlite:///{path}"


@pytest.mark.parametrize(
    ("url", "message"),
    [
        (lambda _: REFUSED, "cannot open database postgresql+psycopg://u:***@127.0.0.1:1/x: connection"),
        (_not_a_database, "file is not a database"),
        (lambda _: "mysql://u:p@127.0.0.1/x", "no driver for 'mysql'"),
        (lambda _: "foo://x", "no driver for 'foo'"),
    ],
    ids=["no-server", "not-a-database", "mysql", "unknown-dialect"],
)
@pytest.mark.parametrize(
    "command",
    [
        ["status"],
        ["export", "latest", "--out", "OUT"],
        ["dashboard", "--port", "1"],
        ["serve", "--port", "1"],
    ],
    ids=lambda command: command[0],
)
def test_database_failures_are_one_line_and_exit_2(capsys, tmp_path, url, message, command):
    command = [str(tmp_path / "out") if part == "OUT" else part for part in command]
    code, _, err = softevo(capsys, *command, "--db", url(tmp_path))
    assert code == 2
    assert err.count("\n") == 1 and err.startswith("error: ") and message in err
    assert "secret" not in err


def test_a_wrong_password_is_one_line(capsys):
    from tests.service.conftest import POSTGRES_URL

    if not POSTGRES_URL:
        pytest.skip("SOFTEVO_TEST_POSTGRES is not set")
    from sqlalchemy.engine import make_url

    wrong = make_url(POSTGRES_URL).set(password="not-the-password").render_as_string(hide_password=False)
    code, _, err = softevo(capsys, "status", "--db", wrong)
    assert code == 2 and err.count("\n") == 1 and "password authentication failed" in err
    assert "not-the-password" not in err
