"""Loopback helpers for whatever starts softevo's servers on this machine (the tests, the
benches, the docs' screenshot script): a free port, and the wait until a server answers."""

from __future__ import annotations

import socket
import subprocess
import time


def free_port() -> int:
    """A TCP port free on 127.0.0.1 now."""
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return sock.getsockname()[1]


def wait_healthy(base: str, process: subprocess.Popen, seconds: float) -> None:
    """Return once ``GET base/health`` answers 200; RuntimeError if ``process`` exits first
    (with what it wrote, where that was piped) or ``seconds`` pass."""
    import httpx

    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        if process.poll() is not None:
            piped = process.stdout or process.stderr
            output = piped.read() if piped is not None else ""
            raise RuntimeError(f"the server exited with {process.returncode}: {output}".strip())
        try:
            if httpx.get(f"{base}/health", timeout=2).status_code == 200:
                return
        except httpx.HTTPError:
            pass
        time.sleep(0.25)
    raise RuntimeError(f"the server at {base} did not answer /health in {seconds:g} s")
