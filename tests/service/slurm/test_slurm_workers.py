"""Workers as a SLURM job array on a real SLURM (one node on 127.0.0.1, started by
.ci/slurm-up), against a private Redis with a password and ``softevo serve`` (SQLite):

- docs/cluster.md's SLURM lines, run as written, one after another: ``softevo
  slurm-workers`` submits an array of two workers, ``squeue`` lists both, ``scancel JOB_1``
  stops one while it holds a job (it finishes that job and exits, or is killed and the job
  goes back to the queue), and the experiment completes with the results of an undisturbed
  in-process run, nothing left in the queue; ``scancel --batch --signal=TERM JOB_0`` (the
  signal SLURM sends before the time limit) drains the other, which exits with status 0.
- The batch script SLURM keeps holds no password (the URL travels in the job's environment),
  and asks for the drain signal before the time limit.

Skipped (failed under CI=true) where sbatch is missing or no SLURM node answers.
"""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
import time
from pathlib import Path

import httpx
import pytest
from redis import Redis
from rq import Queue
from rq.job import Job

from softevo.service.storage import open_database
from softevo.worker.evaluate import ensure_compiled
from tests.service import tinyrun
from tests.service.rq_support import REPO, Processes, RedisServer, job_held_by, service_env, wait_for
from tests.service.runs.test_rq_cluster import submit, undisturbed, wait_finished

pytestmark = [pytest.mark.slow, pytest.mark.redis]

# land -> water at generation 2; long enough that the cancelled worker's job is not the last
TREATMENT = {
    "name": "tiny land-water on slurm",
    "environment": "land-water",
    "switch_at": 2,
    "stiffness_mpa": 0.1,
    "population": 4,
    "generations": 6,
    "workspace": [4, 4, 4],
    "cycles": 12,
    "seed": 11,
}
PASSWORD = "slurm-test-password-0123456789abcdef"


def slurm_problem() -> str | None:
    """Why SLURM cannot run jobs here (None: it can)."""
    if shutil.which("sbatch") is None:
        return "sbatch is not installed (.ci/slurm-up installs and starts a one-node SLURM)"
    try:
        done = subprocess.run(["sinfo", "-h", "-o", "%T"], capture_output=True, text=True, timeout=20)
    except (OSError, subprocess.TimeoutExpired) as exc:
        return f"sinfo failed: {exc}"
    states = done.stdout.split()
    if done.returncode != 0 or not set(states) & {"idle", "mixed", "allocated"}:
        return f"no SLURM node is up (sinfo: {' '.join((done.stdout + done.stderr).split()) or 'nothing'})"
    return None


def documented_lines() -> list[str]:
    """The commands of docs/cluster.md's block that starts ``softevo slurm-workers``, in order,
    their comments left out."""
    text = (REPO / "docs" / "cluster.md").read_text(encoding="utf-8")
    (block,) = [b for b in re.findall(r"```bash\n(.*?)```", text, re.S) if "softevo slurm-workers" in b]
    lines = [re.sub(r"\s+#\s.*$", "", line).strip() for line in block.splitlines()]
    return [line for line in lines if line and not line.startswith("#")]


def shell(line: str, env: dict[str, str], cwd: Path) -> str:
    """Run one documented line with bash; its stdout (the test fails if it does)."""
    done = subprocess.run(
        ["bash", "-euo", "pipefail", "-c", line], env=env, cwd=cwd, capture_output=True, text=True, timeout=60
    )
    assert done.returncode == 0, f"{line!r} exited with {done.returncode}: {done.stderr}"
    return done.stdout


def array_tasks(job: str) -> set[str]:
    """The array's tasks SLURM still lists (``<job>_<task>``)."""
    done = subprocess.run(["squeue", "-h", "-r", "-j", job, "-o", "%i"], capture_output=True, text=True)
    return set(done.stdout.split()) if done.returncode == 0 else set()


def task_state(task: str) -> tuple[str, str]:
    """An ended array task's (JobState, ExitCode), as slurmctld keeps it for ``MinJobAge`` s."""
    shown = subprocess.run(["scontrol", "show", "job", task], capture_output=True, text=True).stdout
    fields = dict(re.findall(r"(JobState|ExitCode)=(\S+)", shown))
    return fields.get("JobState", "?"), fields.get("ExitCode", "?")


def test_documented_slurm_array_survives_scancel_of_a_worker_mid_job(tmp_path):
    problem = slurm_problem()
    if problem:
        pytest.skip(problem)
    lines = documented_lines()
    assert [line.split()[0] for line in lines] == ["job=$(softevo", "squeue", *["scancel"] * 3], lines
    assert lines[2:] == ['scancel "${job}_1"', 'scancel --batch --signal=TERM "${job}_0"', 'scancel "$job"']
    ensure_compiled()  # on a cold cache once, here, not by both workers at once inside SLURM
    reference = undisturbed(tmp_path, TREATMENT)
    started = time.monotonic()
    redis = RedisServer(password=PASSWORD)
    env = service_env(f"sqlite:///{tmp_path / 'softevo.db'}", redis.url)
    group = Processes(tmp_path, env)
    shell_env = {**group.env, "PATH": f"{Path(sys.executable).parent}{os.pathsep}{os.environ['PATH']}"}
    job = None
    try:
        _, base = group.serve()
        job = shell(f'{lines[0]}\necho "$job"', shell_env, tmp_path).strip()
        assert job.isdigit(), job
        shell_env["job"] = job
        stored = subprocess.run(
            ["scontrol", "write", "batch_script", job, "-"], capture_output=True, text=True, check=True
        ).stdout
        assert "#SBATCH --signal=B:TERM@60" in stored and "--array=0-1" in stored
        assert PASSWORD not in stored and "SOFTEVO_REDIS_URL" in stored

        def workers_up():
            return httpx.get(f"{base}/health", timeout=5).json()["workers"] == 2

        wait_for(workers_up, 120, "two SLURM workers on /health", every=0.5)
        listed = shell(lines[1], shell_env, tmp_path)
        assert f"{job}_0" in listed and f"{job}_1" in listed, listed

        run_id = submit(base, TREATMENT)
        worker = f"slurm-{job}_1"
        held = wait_for(
            lambda: job_held_by(redis.url, env["SOFTEVO_QUEUE"], worker),
            120,
            f"{worker} to hold a job",
            every=0.005,
        )
        shell(lines[2], shell_env, tmp_path)
        wait_for(lambda: f"{job}_1" not in array_tasks(job), 60, f"array task {job}_1 to end")
        assert f"{job}_0" in array_tasks(job)

        run = wait_finished(base, run_id, group)
        assert run["status"] == "finished" and run["generation"] == TREATMENT["generations"] - 1
        connection = Redis.from_url(redis.url)
        assert Job.fetch(held, connection=connection).get_status() == "finished"
        assert Queue(env["SOFTEVO_QUEUE"], connection=connection).count == 0
        engine = open_database(env["SOFTEVO_DB"])
        assert tinyrun.snapshot(engine, run_id) == reference
        engine.dispose()

        shell(lines[3], shell_env, tmp_path)  # drain the idle worker: it exits by itself
        wait_for(lambda: not array_tasks(job), 60, f"array task {job}_0 to drain and end")
        assert task_state(f"{job}_0") == ("COMPLETED", "0:0")
        assert task_state(f"{job}_1")[0] == "CANCELLED"
        for task in (0, 1):
            log = (tmp_path / f"softevo-worker-{job}_{task}.log").read_text()
            assert "warm shut down requested" in log, log[-2000:]
        shell(lines[4], shell_env, tmp_path)
        job = None
        print(f"SLURM array of 2 workers, one cancelled mid-job: {time.monotonic() - started:.1f} s")
    finally:
        if job is not None:
            subprocess.run(["scancel", job], check=False)
        group.stop_all()
        print(group.logs())
        for log in sorted(tmp_path.glob("softevo-worker-*.log")):
            print(f"--- {log.name}\n{log.read_text()[-3000:]}")
        redis.stop()


def test_a_job_sbatch_refuses_is_one_line(tmp_path):
    problem = slurm_problem()
    if problem:
        pytest.skip(problem)
    done = subprocess.run(
        [
            sys.executable,
            "-m",
            "softevo.service.cli",
            "slurm-workers",
            "--array",
            "2",
            "--partition",
            "nosuch",
        ],
        env={**os.environ, "SOFTEVO_REDIS_URL": "redis://127.0.0.1:6379/0"},
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert done.returncode == 2 and done.stdout == "", done
    assert done.stderr.startswith("error: sbatch refused the worker array: sbatch: error: ")
    assert "partition" in done.stderr and done.stderr.count("\n") == 1, done.stderr
