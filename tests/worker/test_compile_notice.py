"""The first run on a machine compiles the simulator's kernels (about 100 s on 2 cores): it
says so on stderr instead of sitting silent (issue 49.3)."""

from __future__ import annotations

import os
import signal
import subprocess
import sys

from softevo.worker.evaluate import COMPILING_NOTICE


def test_a_cold_cache_says_it_is_compiling(tmp_path):
    """``softevo run`` with an empty numba cache (``NUMBA_CACHE_DIR``) prints the notice
    while it compiles; the test stops the run (and its compiling subprocess) once it has."""
    command = [
        sys.executable, "-m", "softevo.service.cli", "run", "--env", "land", "--stiffness", "1",
        "--population", "2", "--generations", "1", "--workspace", "3,3,3", "--cycles", "1",
        "--db", f"sqlite:///{tmp_path / 'cold.db'}",
    ]  # fmt: skip
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "numba-cache")}
    process = subprocess.Popen(
        command, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True, env=env,
        start_new_session=True,  # its own process group: the compiling subprocess ends with it
    )  # fmt: skip
    seen = []
    try:
        for line in process.stderr:  # until the notice, else until the run ends
            seen.append(line)
            if COMPILING_NOTICE in line:
                break
    finally:
        os.killpg(process.pid, signal.SIGKILL)
        process.wait()
    assert any(COMPILING_NOTICE in line for line in seen), "".join(seen)


def test_cached_kernels_load_without_the_notice():
    """A second process finds the kernels in numba's cache (the first filled it, if it was
    cold): loading them says nothing, however long it takes on a busy machine."""
    code = "from softevo.worker.evaluate import ensure_compiled; ensure_compiled()"
    subprocess.run([sys.executable, "-c", code], check=True, capture_output=True, timeout=900)
    again = subprocess.run(
        [sys.executable, "-c", code], check=True, capture_output=True, text=True, timeout=900
    )
    assert COMPILING_NOTICE not in again.stderr
