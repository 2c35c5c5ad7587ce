"""Limits of the REST API and the CLI (``service.runs.limits``, ``service.api.guards``,
``service.api.expensive``), over real HTTP on loopback (``softevo serve``, coordinator off)
on a database holding a real tiny run:

- expensive reads: recorded frames are cached (the same answer again, ``X-Cache: hit``),
  concurrent requests for one robot share one simulation, and once
  ``SOFTEVO_BACKGROUND_QUEUE`` simulations are computing or waiting one more is 429 with
  ``Retry-After``; ``SOFTEVO_READ_TOKEN`` guards them;
- bodies: over ``SOFTEVO_MAX_BODY_BYTES`` 413, nested deeper than ``SOFTEVO_MAX_JSON_DEPTH``
  or holding NaN / Infinity / 1e999 422, a 30^3 workspace 422, each answered at once;
- repeated reads are answered from memory (``SOFTEVO_READ_CACHE_SECONDS``) until a write;
- the CLI: a 30^3 scene, a 20^3 scene of 10^6 steps and a 30^3 workspace are one error line
  and exit status 2, before anything is simulated.
"""

from __future__ import annotations

import asyncio
import json
import time
from concurrent.futures import ThreadPoolExecutor
from datetime import UTC, datetime

import httpx
import pytest

from softevo.service.api.frames import decode_frames
from softevo.service.api.guards import json_depth
from softevo.service.api.routes.experiments import _stale
from tests.service import tinyrun
from tests.service.rq_support import Processes, auth, service_env
from tests.support import softevo

READ_TOKEN = "read-token-456-789012"
QUEUE = 2  # SOFTEVO_BACKGROUND_QUEUE of the test server


@pytest.fixture(scope="module")
def served(tmp_path_factory):
    """(base URL, ids of the individuals of the tiny run's last population)."""
    tmp_path = tmp_path_factory.mktemp("limits")
    url, run_id = tinyrun.stored(tmp_path, "limits")
    env = service_env(
        url,
        None,
        SOFTEVO_COORDINATOR="false",
        SOFTEVO_READ_TOKEN=READ_TOKEN,
        SOFTEVO_BACKGROUND_QUEUE=str(QUEUE),
    )
    group = Processes(tmp_path, env)
    _, base = group.serve()
    front = httpx.get(f"{base}/runs/{run_id}/front", params={"generation": 0}).json()
    lineage = httpx.get(f"{base}/runs/{run_id}/generations").json()
    assert lineage
    ids = sorted({m["id"] for m in front["individuals"]})
    yield base, ids
    group.stop_all()


def read_auth() -> dict[str, str]:
    return {"Authorization": f"Bearer {READ_TOKEN}"}


def _frames_at_once(base: str, requests: list[tuple[int, int]]) -> list[httpx.Response]:
    """The frames requests sent at once; in a thread of its own, since another test's
    browser may have left an event loop running in this one."""
    with ThreadPoolExecutor(1) as pool:
        return pool.submit(asyncio.run, _gather_frames(base, requests)).result()


async def _gather_frames(base: str, requests: list[tuple[int, int]]) -> list[httpx.Response]:
    async with httpx.AsyncClient(base_url=base, timeout=120, headers=read_auth()) as client:
        calls = [
            client.get(f"/individuals/{i}/frames", params={"every": every, "max_frames": 20})
            for i, every in requests
        ]
        return await asyncio.gather(*calls)


def test_frames_are_cached_shared_and_refused_when_the_queue_is_full(served):
    base, ids = served
    individual = ids[0]
    url = f"{base}/individuals/{individual}/frames"
    assert httpx.get(url, params={"max_frames": 20}).status_code == 401  # SOFTEVO_READ_TOKEN
    # three concurrent requests for one robot: one simulation, none refused (queue of 2)
    same = _frames_at_once(base, [(individual, 40)] * 3)
    assert [r.status_code for r in same] == [200] * 3
    assert len({r.content for r in same}) == 1
    assert [r.headers["x-cache"] for r in same] == ["miss"] * 3
    again = httpx.get(url, params={"every": 40, "max_frames": 20}, headers=read_auth(), timeout=60)
    assert again.headers["x-cache"] == "hit" and again.content == same[0].content
    assert decode_frames(again.content)["positions"].shape[0] == 20
    # other recording settings are another key: eight distinct simulations at once
    started = time.monotonic()
    mixed = _frames_at_once(base, [(individual, 50 + k) for k in range(8)])
    codes = sorted(r.status_code for r in mixed)
    assert codes.count(200) >= QUEUE and codes.count(429) >= 1, codes
    assert set(codes) <= {200, 429}
    for refused in (r for r in mixed if r.status_code == 429):
        assert int(refused.headers["retry-after"]) >= 1
        assert "busy" in refused.json()["detail"]
    assert time.monotonic() - started < 60  # refused at once, not queued behind the others


STIFFNESS = b'{"name": "x", "treatments": [{"environment": "land", "stiffness_mpa": %s}]}'


@pytest.mark.parametrize(
    ("body", "status", "needle"),
    [
        (b"[" * 100_000 + b"]" * 100_000, 422, "nested deeper than 32"),
        (STIFFNESS % b"NaN", 422, "NaN"),
        (STIFFNESS % b"Infinity", 422, "Infinity"),
        (STIFFNESS % b"1e999", 422, "1e999"),
        (b'{"name": "' + b"x" * 1_100_000 + b'"}', 413, "SOFTEVO_MAX_BODY_BYTES"),
    ],
    ids=["deep", "nan", "infinity", "overflow", "huge"],
)  # fmt: skip
def test_bodies_at_the_edges_are_refused_at_once(served, body, status, needle):
    base, _ = served
    headers = {**auth(), "Content-Type": "application/json"}
    started = time.monotonic()
    response = httpx.post(f"{base}/experiments", content=body, headers=headers, timeout=30)
    assert response.status_code == status, response.text[:500]
    assert needle in response.json()["detail"]
    assert time.monotonic() - started < 10
    assert httpx.get(f"{base}/health").status_code == 200  # the server is unharmed


def test_a_huge_workspace_is_refused(served):
    base, _ = served
    treatment = {"environment": "land", "stiffness_mpa": 1.0, "workspace": [30, 30, 30]}
    body = {"name": "big", "treatments": [treatment]}
    response = httpx.post(f"{base}/experiments", json=body, headers=auth())
    assert response.status_code == 422
    assert "27000 voxels" in response.json()["detail"] and "SOFTEVO_MAX_VOXELS" in response.json()["detail"]
    experiments = httpx.get(f"{base}/experiments").json()
    assert [e["name"] for e in experiments] == ["test"]  # nothing was created


@pytest.mark.parametrize(
    ("body", "detail"),
    [
        ({"treatments": [{"environment": "lnd", "stiffness_mpa": 1}]},
         "body.treatments.0.environment: must be one of land, water"),
        ({"name": "x", "treatments": [{"environment": "land", "stiffness_mpa": 1, "switch_at": 2}]},
         "switch_at needs a transition environment (got land)"),
        ({}, "body.name: Field required (and 1 more problem(s))"),
    ],
    ids=["wrong-before-missing", "no-cli-flag", "missing"],
)  # fmt: skip
def test_a_422_leads_with_the_value_given_and_names_fields(served, body, detail):
    """Issue 49.13: every 422 led with ``body.name: Field required`` (a value given wrongly
    comes first now), said ``Value error, ``, and a treatment's error named ``--switch-at``."""
    base, _ = served
    response = httpx.post(f"{base}/experiments", json=body, headers=auth())
    assert response.status_code == 422
    assert response.json()["detail"].startswith(detail), response.json()
    assert "--" not in response.json()["detail"] and "Value error" not in response.json()["detail"]


def test_repeated_reads_are_answered_from_memory_until_a_write(served):
    base, _ = served
    url = f"{base}/experiments"
    small = {"name": "write", "treatments": [{"environment": "land", "stiffness_mpa": 1.0}]}
    assert httpx.post(url, json=small, headers=auth()).status_code == 201  # a write
    first, second = httpx.get(url), httpx.get(url)
    assert "x-read-cache" not in first.headers and second.headers["x-read-cache"] == "hit"
    assert second.json() == first.json()
    assert httpx.post(f"{base}/runs/1/cancel", headers=auth()).status_code == 409  # refused
    assert httpx.get(url).headers["x-read-cache"] == "hit"  # a refused write changed nothing
    assert httpx.post(url, json=small, headers=auth()).status_code == 201  # a write
    assert "x-read-cache" not in httpx.get(url).headers  # the cache was emptied
    assert "x-read-cache" not in httpx.get(f"{base}/health").headers  # never cached


def test_json_depth():
    assert [json_depth(v) for v in (1, [], [[1]], {"a": [{"b": 2}]})] == [0, 1, 2, 3]


def test_a_live_experiment_report_is_rewritten_at_most_once_per_interval(tmp_path):
    html = tmp_path / "report.html"
    assert _stale(html, None, live=True, interval=60)  # never written
    html.write_text("<html></html>")
    newer = datetime.fromtimestamp(html.stat().st_mtime + 5, UTC)
    assert not _stale(html, newer, live=True, interval=60)  # written < 60 s ago: kept
    assert _stale(html, newer, live=True, interval=0)
    assert _stale(html, newer, live=False, interval=60)  # finished: the final report at once
    older = datetime.fromtimestamp(html.stat().st_mtime - 5, UTC)
    assert not _stale(html, older, live=False, interval=0)  # nothing new since


def _cube(n: int, **extra) -> dict:
    return {"body": [[[1] * n for _ in range(n)] for _ in range(n)], **extra}


@pytest.mark.parametrize(
    ("scene", "needle"),
    [
        (_cube(30), "27000 voxels, more than the limit of 8000 (SOFTEVO_MAX_VOXELS)"),
        (_cube(20, duration={"seconds": 200.0}), "voxel-steps, more than the limit of 2e+09"),
    ],
    ids=["30^3", "20^3 x 10^6 steps"],
)
def test_the_cli_refuses_scenes_over_the_limits(tmp_path, capsys, scene, needle):
    path = tmp_path / "scene.json"
    path.write_text(json.dumps(scene))
    started = time.monotonic()
    code, out, err = softevo(capsys, "simulate", str(path))
    assert code == 2 and out == ""
    assert err.count("\n") == 1 and err.startswith("error: ") and needle in err, err
    assert time.monotonic() - started < 30


def test_the_cli_refuses_a_huge_workspace(tmp_path, capsys):
    db = f"sqlite:///{tmp_path / 'x.db'}"
    args = ["run", "--env", "land", "--stiffness", "1", "--workspace", "30,30,30", "--db", db]
    code, _, err = softevo(capsys, *args)
    assert code == 2 and err.count("\n") == 1 and "SOFTEVO_MAX_VOXELS" in err, err


def test_a_body_that_is_not_json_says_so_in_words(served):
    """Issue 59.4: it answered ``body.20: JSON decode error``."""
    base, _ = served
    headers = {**auth(), "Content-Type": "application/json"}
    response = httpx.post(f"{base}/experiments", content=b'{"name": "x", "treatments": [', headers=headers)
    assert response.status_code in (400, 422), response.text
    detail = response.json()["detail"]
    assert detail.startswith("the body is not valid JSON at character "), detail
    assert "body." not in detail and "decode error" not in detail


def test_runs_and_a_run_give_best_per_world_alike(served):
    """Issue 59.4: ``/runs`` said ``best_by_world`` (a dict), ``/runs/{id}`` ``best_per_world``
    (a list): one name and shape now, the old key kept (docs/contracts.md)."""
    base, _ = served
    listed = httpx.get(f"{base}/runs").json()
    assert listed
    for summary in listed:
        one = httpx.get(f"{base}/runs/{summary['id']}").json()
        assert [b["environment"] for b in summary["best_per_world"]] == [b["environment"] for b in
                                                                         one["best_per_world"]]
        assert [b["distance"] for b in summary["best_per_world"]] == pytest.approx(
            [b["distance"] for b in one["best_per_world"]])
        old = {b["environment"]: b["distance"] for b in summary["best_per_world"]}
        assert summary["best_by_world"] == old
