"""The worker's heartbeat process (``worker.heartbeat``) outlives the SIGTERM and SIGINT sent to
the worker's whole process group (Ctrl-C, ``scancel``, a SLURM time limit), so that a worker
finishing its job on such a signal still has its job kept alive; it ends with the worker's
pipe."""

from __future__ import annotations

import signal
import time
from pathlib import Path

from softevo.worker.rq_worker import start_heartbeat


def ignored_signals(pid: int) -> set[int]:
    """The signals process ``pid`` ignores (Linux: the SigIgn mask of /proc/PID/status)."""
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith("SigIgn:"):
            mask = int(line.split()[1], 16)
            return {number for number in range(1, 65) if mask >> (number - 1) & 1}
    return set()


def test_the_heartbeat_ignores_the_group_signals_and_ends_with_the_worker_pipe():
    heartbeat = start_heartbeat("redis://127.0.0.1:1/0", "no-such-queue", 3)  # no name: no beat
    try:
        deadline = time.monotonic() + 60
        while not {signal.SIGTERM, signal.SIGINT} <= ignored_signals(heartbeat.pid):
            assert heartbeat.poll() is None and time.monotonic() < deadline, "heartbeat did not start"
            time.sleep(0.05)
        heartbeat.send_signal(signal.SIGTERM)
        heartbeat.send_signal(signal.SIGINT)
        time.sleep(0.5)
        assert heartbeat.poll() is None  # still there
        heartbeat.stdin.close()  # the worker is gone
        assert heartbeat.wait(10) == 0
    finally:
        if heartbeat.poll() is None:
            heartbeat.kill()
            heartbeat.wait(5)
