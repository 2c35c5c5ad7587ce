"""The worker's heartbeat process (``worker.heartbeat``) outlives the SIGTERM and SIGINT sent to
all of the worker's processes (Ctrl-C, ``scancel``, a SLURM time limit), from its first
instruction on, so that a worker finishing its job on such a signal still has its job kept
alive, and a worker killed at once has its job handed back; it ends with the worker's pipe."""

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


def test_the_heartbeat_ignores_the_stop_signals_from_its_start_and_ends_with_the_worker_pipe():
    heartbeat = start_heartbeat("redis://127.0.0.1:1/0", "no-such-queue", 3)  # no name: no beat
    try:
        heartbeat.send_signal(signal.SIGTERM)  # at once: while it still imports (a SLURM
        heartbeat.send_signal(signal.SIGINT)  # worker cancelled in its first second)
        assert {signal.SIGTERM, signal.SIGINT} <= ignored_signals(heartbeat.pid)
        time.sleep(1.0)
        assert heartbeat.poll() is None  # still there
        assert signal.getsignal(signal.SIGTERM) is signal.SIG_DFL  # the worker's own: as before
        heartbeat.stdin.close()  # the worker is gone
        assert heartbeat.wait(30) == 0
    finally:
        if heartbeat.poll() is None:
            heartbeat.kill()
            heartbeat.wait(5)
