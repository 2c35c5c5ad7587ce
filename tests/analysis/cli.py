"""Run the ``softevo`` command line in-process and capture its outcome."""

from __future__ import annotations

from softevo.service.cli import main


def softevo(capsys, *args: str) -> tuple[int, str, str]:
    """(exit code, stdout, stderr) of ``softevo ARGS``."""
    try:
        main(list(args))
        code = 0
    except SystemExit as exc:
        code = exc.code or 0
    captured = capsys.readouterr()
    return code, captured.out, captured.err
