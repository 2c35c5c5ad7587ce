"""``softevo worker`` processes as a SLURM job array (``softevo slurm-workers``, docs/cluster.md).

One array task is one worker: ``#SBATCH --array=0-(N-1)``, one task of ``threads`` CPUs each,
and the task's batch script *is* the worker (``exec``), so the signals SLURM sends the batch
shell reach it:

- ``--signal=B:TERM@<drain>``: ``drain`` seconds before the time limit SLURM sends SIGTERM
  to the worker, which takes no new job and finishes the one it runs (RQ's warm shutdown),
  then exits. At the limit itself (and on ``scancel`` or preemption) SLURM sends SIGTERM to
  every process of the task, then SIGKILL ``KillWait`` seconds later: the worker finishes
  its job if it can (a simulation in progress is not interrupted), else it dies, its
  heartbeat stops, and the coordinator's registry cleanup puts the job back in the queue
  within the heartbeat's ttl. The heartbeat process ignores SIGTERM
  (``rq_worker.start_heartbeat``), so that a worker finishing its job never looks dead.
  Nothing is lost: evaluations are deterministic, so a job run again gives the same result.
- ``--requeue``: a worker preempted (``PreemptMode=REQUEUE``) or whose node failed is
  started again by SLURM; each start has a worker name of its own
  (``slurm-<job>_<task>``, ``-r<n>`` after the n-th restart), since RQ refuses a name that
  is still registered.

The Redis URL (and its password) never enters the script, which SLURM stores and shows to
the cluster's administrators (``scontrol write batch_script``): it travels in the job's
environment (``SOFTEVO_REDIS_URL``, exported to the job by ``sbatch --export=ALL``), like
every other ``SOFTEVO_*`` setting of the worker (queue, heartbeat, engine).
"""

from __future__ import annotations

import re
import shlex
import shutil
import subprocess
import sys
from dataclasses import dataclass, field

from softevo import __version__
from softevo.errors import UserError

DRAIN = 60  # seconds before the time limit that SLURM asks the workers to finish (--signal)
JOB_NAME = "softevo-workers"
OUTPUT = "softevo-worker-%A_%a.log"  # sbatch's pattern: array job id, task index
TIME = re.compile(r"\d+(-\d+)?(:\d+){0,2}")  # minutes, m:s, h:m:s, d-h, d-h:m, d-h:m:s


@dataclass(frozen=True)
class WorkerArray:
    """What ``batch_script`` writes: ``workers`` array tasks, each one ``softevo worker``."""

    workers: int
    queue: str = "softevo"
    threads: int = 1
    time: str | None = None  # sbatch's --time (the partition's default limit when None)
    drain: int = DRAIN
    partition: str | None = None
    output: str = OUTPUT
    job_name: str = JOB_NAME
    sbatch: tuple[str, ...] = field(default_factory=tuple)  # more #SBATCH options, verbatim
    python: str = sys.executable  # the interpreter whose softevo the workers run

    def check(self) -> None:
        """A UserError (one line) for settings sbatch would refuse or misread."""
        if self.workers < 1:
            raise UserError(f"--array must be >= 1 worker (got {self.workers})")
        if self.threads < 1:
            raise UserError(f"--threads must be >= 1 (got {self.threads})")
        if self.drain < 1:
            raise UserError(f"--drain must be >= 1 second (got {self.drain})")
        if self.time is not None and not TIME.fullmatch(self.time):
            raise UserError(
                f"--time {self.time!r} is not a SLURM time: minutes, mm:ss, hh:mm:ss, d-hh or d-hh:mm:ss"
            )
        for option in self.sbatch:
            if not option.startswith("--") or "\n" in option:
                raise UserError(f"--sbatch {option!r}: give one sbatch option, as in --sbatch=--account=abc")


def worker_name_expression() -> str:
    """The shell expression of a task's worker name: ``slurm-<job>_<task>`` (``-r<n>`` after
    SLURM's n-th restart of it)."""
    return "slurm-${SLURM_ARRAY_JOB_ID}_${SLURM_ARRAY_TASK_ID}${SLURM_RESTART_COUNT:+-r$SLURM_RESTART_COUNT}"


def batch_script(array: WorkerArray) -> str:
    """The sbatch script of ``array``: its #SBATCH header, then ``exec`` of the worker."""
    array.check()
    options = [
        f"--job-name={array.job_name}",
        f"--array=0-{array.workers - 1}",
        "--ntasks=1",
        f"--cpus-per-task={array.threads}",
        f"--signal=B:TERM@{array.drain}",
        "--requeue",
        f"--output={array.output}",
    ]
    if array.time is not None:
        options.append(f"--time={array.time}")
    if array.partition is not None:
        options.append(f"--partition={array.partition}")
    options += list(array.sbatch)
    worker = [shlex.quote(array.python), "-m", "softevo.service.cli", "worker"]
    worker += ["--queue", shlex.quote(array.queue), "--threads", str(array.threads)]
    lines = [
        "#!/bin/bash",
        f"# {array.workers} softevo worker(s) as a SLURM job array: `softevo slurm-workers` "
        f"(softevo {__version__}), docs/cluster.md",
        *(f"#SBATCH {option}" for option in options),
        "# SOFTEVO_REDIS_URL and the other SOFTEVO_* settings come from the job's environment.",
        f"# SIGTERM {array.drain} s before the time limit: no new job; the running one finishes.",
        f'exec {" ".join(worker)} --name "{worker_name_expression()}"',
    ]
    return "\n".join(lines) + "\n"


def submit(script: str, environment: dict[str, str]) -> str:
    """Submit ``script`` with sbatch, the job's environment ``environment``; return the job id.

    A UserError (one line) when sbatch is missing or refuses the job."""
    sbatch = shutil.which("sbatch")
    if sbatch is None:
        raise UserError("sbatch not found: run this on a SLURM login node (docs/cluster.md, SLURM)")
    done = subprocess.run(
        [sbatch, "--parsable", "--export=ALL"],
        input=script,
        env=environment,
        capture_output=True,
        text=True,
        check=False,
    )
    if done.returncode != 0:
        reason = " ".join((done.stderr or done.stdout).split()) or f"exit status {done.returncode}"
        raise UserError(f"sbatch refused the worker array: {reason}")
    return done.stdout.strip().split(";")[0]  # --parsable: "<id>" or "<id>;<cluster>"
