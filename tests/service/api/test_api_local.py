"""``softevo serve`` without Redis (the embedded default: local evaluation) over real HTTP:
experiments submitted over the API run to the end, a cancelled run stays cancelled while
the others go on, and a server without a token only listens on loopback."""

from __future__ import annotations

import subprocess
import sys

import httpx
import pytest

from tests.service.rq_support import REPO, Processes, auth, service_env, wait_for

pytestmark = pytest.mark.slow


def treatment(**changes) -> dict:
    base = {
        "environment": "water",
        "stiffness_mpa": 1.0,
        "population": 4,
        "generations": 3,
        "workspace": [3, 3, 3],
        "cycles": 2,
    }
    return {**base, **changes}


def test_runs_finish_and_a_cancelled_run_stays_cancelled(tmp_path):
    env = service_env(f"sqlite:///{tmp_path / 'local.db'}", None, SOFTEVO_WORKERS="1")
    group = Processes(tmp_path, env)
    try:
        _, base = group.serve()
        health = httpx.get(f"{base}/health").json()
        assert (health["executor"], health["workers"], health["coordinator"]) == ("local", 1, True)
        body = {
            "name": "local",
            "treatments": [
                treatment(name="short"),
                treatment(name="long", generations=400, repetitions=2),
            ],
        }
        created = httpx.post(f"{base}/experiments", json=body, headers=auth())
        assert created.status_code == 201, created.text
        short, long_a, long_b = created.json()["runs"]

        def generation(run_id):
            return httpx.get(f"{base}/runs/{run_id}").json()["generation"]

        wait_for(lambda: generation(long_a) >= 1, 120, "the long runs to start")
        cancelled = httpx.post(f"{base}/runs/{long_a}/cancel", headers=auth())
        assert cancelled.status_code == 200 and cancelled.json()["status"] == "cancelled"
        wait_for(
            lambda: httpx.get(f"{base}/runs/{short}").json()["status"] == "finished",
            120,
            "the short run to finish",
        )
        stopped_at = generation(long_a)
        wait_for(lambda: generation(long_b) >= stopped_at + 3, 120, "the other run to go on")
        run = httpx.get(f"{base}/runs/{long_a}").json()
        assert run["status"] == "cancelled" and run["generation"] <= stopped_at + 1
        again = httpx.post(f"{base}/runs/{long_a}/cancel", headers=auth())
        assert again.status_code == 200  # cancelling twice changes nothing
        finished = httpx.post(f"{base}/runs/{short}/cancel", headers=auth())
        assert finished.status_code == 409 and "finished" in finished.json()["detail"]
        listed = httpx.get(f"{base}/runs", params={"status": "cancelled"}).json()
        assert [r["id"] for r in listed] == [long_a]
        experiment = httpx.get(f"{base}/experiments/{created.json()['id']}").json()
        assert experiment["status"] == "running"
        assert [r["status"] for r in experiment["runs"]] == ["finished", "cancelled", "running"]
        httpx.post(f"{base}/runs/{long_b}/cancel", headers=auth())
    finally:
        group.stop_all()


def test_no_token_means_loopback_only(tmp_path):
    env = {
        "SOFTEVO_DB": f"sqlite:///{tmp_path / 'x.db'}",
        "SOFTEVO_HOST": "0.0.0.0",
        "SOFTEVO_TOKEN": "",
        "PATH": "/usr/bin:/bin",
    }
    done = subprocess.run(
        [sys.executable, "-m", "softevo.service.cli", "serve"],
        cwd=REPO,
        env=env,
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert done.returncode == 2
    assert "refusing to serve on 0.0.0.0" in done.stderr and "SOFTEVO_TOKEN" in done.stderr
