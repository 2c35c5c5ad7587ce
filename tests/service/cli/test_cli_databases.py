"""Every database failure of the command line is one line on stderr and exit status 2
(issue 28, item 3), and a read-only command never creates a database (item 10)."""

from __future__ import annotations

import pytest

from tests.support import softevo

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


READ_ONLY = [
    ["status"],
    ["status", "latest"],
    ["resume"],
    ["export", "latest", "--out", "OUT"],
    ["lineage", "1"],
    ["phylogeny", "1"],
    ["exaptation", "1"],
    ["show", "1", "--out", "OUT.gif"],
    ["export-vxa", "1", "--out", "OUT.vxa"],
    ["report", "latest", "--out", "OUT"],
    ["power", "latest"],
    ["dashboard", "--port", "1"],
]


@pytest.mark.parametrize("command", READ_ONLY, ids=lambda command: "-".join(command[:2]))
def test_read_only_commands_never_create_a_database(capsys, tmp_path, command):
    missing = tmp_path / "mistyped.db"
    command = [part.replace("OUT", str(tmp_path / "out")) for part in command]
    code, _, err = softevo(capsys, *command, "--db", f"sqlite:///{missing}")
    assert code == 2 and err == f"error: no database at {missing} (give --db URL or set SOFTEVO_DB)\n"
    assert sorted(tmp_path.iterdir()) == []


def test_reading_a_database_leaves_no_lock_beside_it(capsys, tmp_path):
    from softevo.service.storage import open_database

    path = tmp_path / "softevo.db"
    open_database(f"sqlite:///{path}").dispose()
    (tmp_path / "softevo.db.migrate.lock").unlink()
    code, out, _ = softevo(capsys, "status", "--db", f"sqlite:///{path}")
    assert code == 0 and "no runs yet" in out
    assert sorted(p.name for p in tmp_path.iterdir() if not p.name.endswith(("-wal", "-shm"))) == [
        "softevo.db"
    ]


def test_load_experiment_does_not_create_a_database(tmp_path):
    import softevo
    from softevo.errors import UserError

    with pytest.raises(UserError, match="no database at"):
        softevo.load_experiment(f"sqlite:///{tmp_path / 'none.db'}")
    assert sorted(tmp_path.iterdir()) == []
