"""Helpers every test package shares: the ``softevo`` command line run in this process (fast)
or as a user runs it (a fresh interpreter); a free loopback port and the wait for a server
(``service.api.loopback``)."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

from softevo.service.api.loopback import free_port, wait_healthy  # noqa: F401  (the tests' own)
from softevo.service.cli import main


def exit_code(*args: str) -> int:
    """The exit status of ``softevo ARGS`` run in this process (its output goes where
    stdout and stderr go; any stray exception fails the test)."""
    try:
        main(list(args))
    except SystemExit as exc:
        return exc.code if isinstance(exc.code, int) else int(exc.code is not None)
    return 0


def softevo(capsys, *args: str) -> tuple[int, str, str]:
    """(exit code, stdout, stderr) of ``softevo ARGS`` in this process."""
    capsys.readouterr()
    code = exit_code(*args)
    captured = capsys.readouterr()
    return code, captured.out, captured.err


def softevo_ok(capsys, *args: str) -> str:
    """``softevo ARGS`` in this process, which must succeed: its standard output."""
    code, out, err = softevo(capsys, *args)
    assert code == 0, err
    return out


def softevo_process(
    *args: str, env: dict | None = None, cwd: Path | None = None, timeout: float = 300
) -> subprocess.CompletedProcess:
    """``softevo ARGS`` as a user runs it: the installed console command (else the module)
    in a fresh interpreter, with ``env`` added to this environment."""
    exe = shutil.which("softevo")
    cmd = [exe] if exe else [sys.executable, "-m", "softevo.service.cli"]
    return subprocess.run(
        [*cmd, *args], capture_output=True, text=True, timeout=timeout, cwd=cwd,
        env={**os.environ, **(env or {})},
    )  # fmt: skip


