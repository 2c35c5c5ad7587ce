"""``softevo slurm-workers`` without a SLURM (``worker.slurm``): the batch script it writes
(one worker per array task, started with ``exec`` so that SLURM's drain signal reaches it, a
name per task and restart, no Redis URL in it) and its one-line mistakes. The script on a real
SLURM: tests/service/slurm/."""

from __future__ import annotations

import subprocess

import pytest

from softevo.worker.slurm import WorkerArray, batch_script
from tests.support import softevo

URL = "redis://:secret-password@login01:6379/0"


def sbatch_options(script: str) -> list[str]:
    return [line.removeprefix("#SBATCH ") for line in script.splitlines() if line.startswith("#SBATCH ")]


def test_the_script_asks_for_an_array_the_drain_signal_and_requeue(capsys, monkeypatch):
    monkeypatch.setenv("SOFTEVO_REDIS_URL", URL)
    code, script, err = softevo(
        capsys, "slurm-workers", "--array", "8", "--time", "1-12", "--drain", "120", "--threads", "2",
        "--partition", "short", "--queue", "big", "--sbatch=--account=abc", "--print",
    )  # fmt: skip
    assert code == 0, err
    assert sbatch_options(script) == [
        "--job-name=softevo-workers",
        "--array=0-7",
        "--ntasks=1",
        "--cpus-per-task=2",
        "--signal=B:TERM@120",
        "--requeue",
        "--output=softevo-worker-%A_%a.log",
        "--time=1-12",
        "--partition=short",
        "--account=abc",
    ]
    assert "secret-password" not in script and "login01" not in script
    last = script.splitlines()[-1]
    assert last.startswith("exec ") and " worker --queue big --threads 2 --name " in last
    subprocess.run(["bash", "-n"], input=script, text=True, check=True)  # valid shell


@pytest.mark.parametrize(("restarts", "name"), [(None, "slurm-41_3"), ("2", "slurm-41_3-r2")])
def test_each_task_and_restart_has_a_worker_name_of_its_own(restarts, name):
    script = batch_script(WorkerArray(workers=4, python="echo"))
    env = {"SLURM_ARRAY_JOB_ID": "41", "SLURM_ARRAY_TASK_ID": "3", "PATH": "/usr/bin:/bin"}
    if restarts:
        env["SLURM_RESTART_COUNT"] = restarts
    done = subprocess.run(["bash"], input=script, env=env, capture_output=True, text=True, check=True)
    assert done.stdout.split()[-2:] == ["--name", name]


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--array", "0"], "error: --array must be >= 1 worker (got 0)"),
        (["--array", "2", "--time", "2h"], "error: --time '2h' is not a SLURM time"),
        (["--array", "2", "--drain", "0"], "error: --drain must be >= 1 second (got 0)"),
        (["--array", "2", "--sbatch", "account=abc"], "error: --sbatch 'account=abc': give one sbatch"),
    ],
)
def test_mistakes_are_one_line(capsys, args, message):
    code, _, err = softevo(capsys, "slurm-workers", *args, "--print")
    assert code == 2 and err.startswith(message) and err.count("\n") == 1, err


def test_no_redis_url_or_no_sbatch_is_one_line(capsys, monkeypatch, tmp_path):
    monkeypatch.delenv("SOFTEVO_REDIS_URL", raising=False)
    code, _, err = softevo(capsys, "slurm-workers", "--array", "2")
    assert code == 2 and err == (
        "error: softevo slurm-workers needs a Redis URL: set SOFTEVO_REDIS_URL or --redis-url\n"
    )
    monkeypatch.setenv("PATH", str(tmp_path))  # no sbatch on it
    code, _, err = softevo(capsys, "slurm-workers", "--array", "2", "--redis-url", URL)
    assert code == 2 and err.startswith("error: sbatch not found: run this on a SLURM login node"), err
