"""Run the ``softevo`` command line in-process and capture its outcome."""

from __future__ import annotations

from softevo.service.cli import main


def exit_code(*args: str) -> int:
    """The exit status of ``softevo ARGS`` run in this process (its output goes where
    stdout and stderr go)."""
    try:
        main(list(args))
    except SystemExit as exc:
        return exc.code or 0
    return 0


def softevo(capsys, *args: str) -> tuple[int, str, str]:
    """(exit code, stdout, stderr) of ``softevo ARGS``."""
    code = exit_code(*args)
    captured = capsys.readouterr()
    return code, captured.out, captured.err
