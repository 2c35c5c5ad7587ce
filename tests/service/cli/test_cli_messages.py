"""Every mistake reads ``error: <message>`` (one line, exit 2), click's usage messages as
softevo's own; ``softevo --version``; a server port in use is a mistake, not uvicorn's
``ERROR:`` line."""

from __future__ import annotations

import socket

from softevo import __version__
from softevo.service.storage import open_database
from tests.support import softevo


def test_version(capsys):
    code, out, _ = softevo(capsys, "--version")
    assert code == 0 and out == f"softevo {__version__}\n"


def test_usage_errors_read_as_softevo_errors(capsys):
    assert softevo(capsys, "bogus") == (2, "", "error: no such command 'bogus'\n")
    code, _, err = softevo(capsys, "run")
    assert code == 2 and err == "error: missing option '--env'\n"


def test_no_arguments_shows_the_help_and_no_empty_error(capsys):
    code, out, err = softevo(capsys)
    assert code == 2 and "Usage" in out and "error" not in err  # was: a bare "error: " line


def test_a_port_in_use_is_one_line_and_exit_2(capsys, tmp_path):
    url = f"sqlite:///{tmp_path / 'x.db'}"
    open_database(url).dispose()
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        port = taken.getsockname()[1]
        for command in ("dashboard", "serve"):
            code, _, err = softevo(capsys, command, "--db", url, "--port", str(port))
            assert code == 2 and err.count("\n") == 1, (command, err)
            assert err.startswith(f"error: cannot listen on 127.0.0.1:{port}: "), err


def test_calling_main_again_does_not_add_the_commands_again(capsys):
    """Each ``main()`` once re-added every command: after 300 calls in one test process typer
    held 5,700 of them and each call took 14 s to find its command."""
    from softevo.service.cli import app

    softevo(capsys, "--version")
    counts = (len(app.registered_commands), len(app.registered_groups))
    for _ in range(3):
        softevo(capsys, "bogus")
    assert (len(app.registered_commands), len(app.registered_groups)) == counts
    assert counts[0] > 5


def test_the_progress_bar_numbers_generations_as_rest_does():
    """Issue 59.4: the bar said "gen 6/6 stored" where REST says ``generation: 5``: a
    generation is an index from 0 everywhere, a count says "of" (docs/contracts.md)."""
    from softevo.service.cli.progress import generation_text

    assert generation_text(3, 5, 6) == "run 3 generation 5 stored (6 of 6)"
    assert generation_text(1, 0, 6) == "run 1 generation 0 stored (1 of 6)"
