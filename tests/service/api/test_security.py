"""Issue 30's findings replayed against real servers on loopback (docs/security.md): each test
failed before its fix and asserts the fixed behaviour. Item 1 (workers refuse foreign jobs)
is ``test_rq_foreign_jobs.py``."""

from __future__ import annotations

import base64
import dataclasses
import hashlib
import http.server
import json
import os
import re
import subprocess
import sys
import threading
import uuid
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import httpx
import pytest
from redis import Redis
from rq import Callback, Queue
from rq.job import JobStatus
from rq.registry import StartedJobRegistry
from rq.serializers import JSONSerializer
from rq.webhook import Webhook

from softevo.service.runs.rq_executor import RQExecutor
from softevo.service.runs.submit import create
from softevo.service.storage import open_database
from softevo.worker.rq_worker import JOB_FUNCTION
from tests.service import tinyrun
from tests.service.rq_support import Processes, auth, free_port, redis_for_test, service_env, wait_for

CALLED: list[str] = []  # what ``mark`` saw: a callback that ran


def mark(job, *args, **kwargs) -> None:
    """A failure callback that records that it ran (it must never)."""
    CALLED.append(job.id)


class Recorder(http.server.BaseHTTPRequestHandler):
    """A webhook receiver on loopback: records every request it gets."""

    seen: list[str] = []

    def do_POST(self) -> None:  # noqa: N802 - http.server's name
        Recorder.seen.append(self.path)
        self.send_response(200)
        self.end_headers()

    do_GET = do_PUT = do_POST  # noqa: N815

    def log_message(self, *args) -> None:
        pass


@pytest.fixture(scope="module")
def redis_url():
    with redis_for_test() as url:
        yield url


# -- item 1, the coordinator's side: RQ maintenance imports nothing named in Redis --------------


@pytest.mark.redis
def test_the_coordinators_cleanup_calls_no_callback_and_sends_no_webhook(redis_url):
    name = f"test-{uuid.uuid4().hex[:8]}"
    connection = Redis.from_url(redis_url)
    receiver = http.server.HTTPServer(("127.0.0.1", 0), Recorder)
    threading.Thread(target=receiver.serve_forever, daemon=True).start()
    url = f"http://127.0.0.1:{receiver.server_port}/hook"
    queue = Queue(name, connection=connection, serializer=JSONSerializer)
    job = queue.enqueue(
        JOB_FUNCTION,
        args=[[]],
        on_failure=Callback(f"{__name__}.mark"),
        webhooks=[Webhook(url, "failed")],
    )
    job.set_status(JobStatus.STARTED)  # a worker took it and died: abandoned, expired
    connection.zadd(StartedJobRegistry(queue=queue).key, {f"{job.id}:dead-execution": 1})
    executor = RQExecutor(redis_url, queue=name, maintenance_seconds=0)
    try:
        executor._maintain()
    finally:
        executor.close()
        receiver.shutdown()
    assert connection.hget(f"rq:job:{job.id}", "status") == b"failed"  # cleaned up as before
    assert CALLED == [] and Recorder.seen == []


# -- items 3 and 4: one door for writes ------------------------------------------------------

EXPERIMENT = {"name": "intruder", "treatments": [{"environment": "land", "stiffness_mpa": 1.0}]}
EVIL = {"Origin": "http://evil.example", "Referer": "http://evil.example/page.html"}


def wait_up(process, base: str, group: Processes) -> None:
    def up():
        if process.poll() is not None:
            pytest.fail(f"the server exited:\n{group.logs()}")
        return httpx.get(f"{base}/health", timeout=2).status_code in (200, 503)

    wait_for(up, 90, f"{base} to answer /health", every=0.25)


@pytest.fixture(scope="module")
def open_servers(tmp_path_factory):
    """``softevo serve`` and ``softevo dashboard`` without a token, coordinator off, on one
    database with a pending run: (serve's URL, dashboard's URL, run id, database URL)."""
    tmp_path = tmp_path_factory.mktemp("open")
    url, run_id = tinyrun.stored(tmp_path, "open", finished=False)
    group = Processes(tmp_path, service_env(url, None, SOFTEVO_TOKEN="", SOFTEVO_COORDINATOR="false"))
    _, base = group.serve()
    port = free_port()
    dashboard = group.start("dashboard", "--db", url, "--port", str(port), log=f"dashboard-{port}")
    board = f"http://127.0.0.1:{port}"
    wait_up(dashboard, board, group)
    yield base, board, run_id, url
    group.stop_all()


def test_the_dashboard_serves_no_write(open_servers, tmp_path):
    _, board, run_id, _ = open_servers
    before = httpx.get(f"{board}/experiments").json()
    created = httpx.post(f"{board}/experiments", json=EXPERIMENT)
    assert created.status_code == 405, created.text
    assert httpx.post(f"{board}/runs/{run_id}/cancel", json={}).status_code in (404, 405)
    assert httpx.get(f"{board}/experiments").json() == before
    assert httpx.get(f"{board}/runs/{run_id}").json()["status"] == "pending"
    assert httpx.get(f"{board}/dashboard/").status_code == 200  # the pages and reads still work
    paths = httpx.get(f"{board}/openapi.json").json()["paths"]
    writes = {(path, m) for path, ops in paths.items() for m in ops if m != "get"}
    assert writes <= {("/plan", "post")}  # a plan is computed from its body; it stores nothing
    assert httpx.get(f"{board}/experiments").json() == before


def test_without_a_token_a_rebinding_host_is_refused(open_servers):
    base, board, run_id, _ = open_servers
    for server in (base, board):
        refused = httpx.get(f"{server}/runs/{run_id}", headers={"Host": "rebind.attacker.example"})
        assert refused.status_code == 400, refused.text
        assert "rebind" not in refused.text
        for host in ("127.0.0.1", "localhost"):
            port = server.rsplit(":", 1)[1]
            assert httpx.get(f"{server}/runs/{run_id}", headers={"Host": f"{host}:{port}"}).status_code == 200


def test_without_a_token_a_cross_site_simple_post_cannot_cancel(open_servers):
    base, _, run_id, _ = open_servers
    simple = [
        httpx.post(f"{base}/runs/{run_id}/cancel", headers=EVIL),  # body-less, as a form or fetch sends
        httpx.post(
            f"{base}/runs/{run_id}/cancel", headers={**EVIL, "Content-Type": "text/plain"}, content="{}"
        ),
        httpx.post(
            f"{base}/experiments",
            headers={**EVIL, "Content-Type": "text/plain"},
            content=json.dumps(EXPERIMENT),
        ),
    ]
    for response in simple:
        assert response.status_code in (403, 422), response.text
    assert simple[0].status_code == 403 and "X-Requested-With" in simple[0].json()["detail"]
    assert httpx.get(f"{base}/runs/{run_id}").json()["status"] == "pending"
    assert all(e["name"] != "intruder" for e in httpx.get(f"{base}/experiments").json())
    # what this machine's own scripts send still works: a JSON body, or the header
    assert httpx.post(f"{base}/runs/{run_id}/cancel", headers={"X-Requested-With": "curl"}).status_code == 200
    assert httpx.get(f"{base}/runs/{run_id}").json()["status"] == "cancelled"


@pytest.mark.parametrize("variable", ["SOFTEVO_TOKEN", "SOFTEVO_READ_TOKEN"])
def test_a_short_token_is_refused_in_one_line(variable, tmp_path):
    env = {**os.environ, variable: "x", "SOFTEVO_DB": f"sqlite:///{tmp_path / 'x.db'}"}
    done = subprocess.run(
        [sys.executable, "-m", "softevo.service.cli", "serve", "--port", str(free_port())],
        env=env, capture_output=True, text=True, timeout=120,
    )  # fmt: skip
    assert done.returncode == 2, done.stderr
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and variable in lines[0] and "16 characters" in lines[0], done.stderr
    assert "x" not in lines[0].split(":")[-1].split()  # the token itself is never printed


# -- item 5: reports ---------------------------------------------------------------------------

MATH_NAME = r"soft $\frac{$ robot"  # matplotlib's math text raised on this (ParseSyntaxException)


@pytest.fixture(scope="module")
def report_server(tmp_path_factory):
    """``softevo serve`` (no coordinator) on a finished tiny run whose treatment name holds
    math text: (base URL, experiment id, reports directory, processes)."""
    tmp_path = tmp_path_factory.mktemp("report")
    url = f"sqlite:///{tmp_path / 'report.db'}"
    engine = open_database(url)
    experiment_id, (run_id,) = create(engine, "dollars", [dataclasses.replace(tinyrun.TINY, name=MATH_NAME)])
    tinyrun.run_to_end(engine, run_id)
    engine.dispose()
    reports = tmp_path / "reports"
    group = Processes(
        tmp_path, service_env(url, None, SOFTEVO_COORDINATOR="false", SOFTEVO_REPORTS=str(reports))
    )
    _, base = group.serve()
    yield base, experiment_id, reports, group
    group.stop_all()


def test_a_dollar_in_a_treatment_name_leaves_the_report_whole(report_server):
    base, experiment_id, _, _ = report_server
    response = httpx.get(f"{base}/experiments/{experiment_id}/report", headers=auth(), timeout=600)
    assert response.status_code == 200, response.text
    assert "soft $\\frac{$ robot" in response.text  # the name as typed


def test_a_failed_report_is_one_generic_500_not_retried(report_server, tmp_path):
    base, _, reports, group = report_server
    engine = open_database(group.env["SOFTEVO_DB"])
    experiment_id, (run_id,) = create(engine, "broken", [tinyrun.TINY])
    tinyrun.run_to_end(engine, run_id)
    engine.dispose()
    (reports / f"experiment-{experiment_id}" / "report.html").mkdir(parents=True)  # cannot be written
    url = f"{base}/experiments/{experiment_id}/report"
    answers = [httpx.get(url, headers=auth(), timeout=600) for _ in range(3)]
    assert [a.status_code for a in answers] == [500] * 3, answers[0].text
    detail = answers[0].json()["detail"]
    assert {a.json()["detail"] for a in answers} == {detail}
    assert "Error" not in detail and "experiment-" not in detail and "exists" not in detail.lower()
    assert group.logs().count(f"report of experiment {experiment_id} failed") == 1  # written once


# -- item 7: headers and edges -----------------------------------------------------------------


def test_html_pages_forbid_framing_and_foreign_scripts(report_server):
    base, experiment_id, _, _ = report_server
    pages = {
        "dashboard": httpx.get(f"{base}/dashboard/"),
        "docs": httpx.get(f"{base}/docs"),
        "report": httpx.get(f"{base}/experiments/{experiment_id}/report", headers=auth(), timeout=600),
    }
    for name, page in pages.items():
        assert page.status_code == 200 and page.headers["content-type"].startswith("text/html"), name
        policy = page.headers["content-security-policy"]
        assert "frame-ancestors 'none'" in policy and "default-src" in policy, name
        assert page.headers["x-content-type-options"] == "nosniff", name
        assert page.headers["x-frame-options"] == "DENY", name
        assert "http" not in policy  # no other origin may serve scripts, styles or data
    assert "script-src" not in pages["report"].headers["content-security-policy"]  # default 'none'
    for path in ("/health", "/experiments", "/openapi.json"):
        assert httpx.get(f"{base}{path}").headers["x-content-type-options"] == "nosniff"


def test_the_api_docs_load_nothing_from_a_cdn(report_server):
    base, _, _, _ = report_server
    docs = httpx.get(f"{base}/docs")
    assert "cdn." not in docs.text and "https://" not in docs.text
    sources = re.findall(r'(?:src|href)="([^"]+)"', docs.text)
    assert any(s.endswith("swagger-ui-bundle.js") for s in sources)
    for source in sources:
        assert source.startswith("/"), source
        assert httpx.get(f"{base}{source}").status_code == 200, source
    inline = re.findall(r"<script>(.*?)</script>", docs.text, re.DOTALL)
    digest = base64.b64encode(hashlib.sha256(inline[0].encode()).digest()).decode()
    assert f"'sha256-{digest}'" in docs.headers["content-security-policy"]
    assert httpx.get(f"{base}/redoc").status_code == 404  # ReDoc would load from a CDN


def test_an_endless_scene_is_one_line_not_a_traceback(tmp_path):
    scene = tmp_path / "endless.json"
    scene.write_text(json.dumps({"body": [[[1]]], "duration": {"cycles": 1e300}}))
    done = subprocess.run(
        [sys.executable, "-m", "softevo.service.cli", "simulate", str(scene)],
        capture_output=True, text=True, timeout=300,
    )  # fmt: skip
    assert done.returncode == 2 and "Traceback" not in done.stderr, done.stderr[-2000:]
    assert done.stderr.strip().count("\n") == 0 and "SOFTEVO_MAX_VOXEL_STEPS" in done.stderr


# -- item 6: the expensive reads and the read cache -------------------------------------------


@pytest.fixture(scope="module")
def limits_server(tmp_path_factory):
    """``softevo serve`` on a finished tiny run with a long read cache, two background slots,
    one per client and a frames time-out shorter than the background process takes to start:
    (base URL, individual ids, serve's process)."""
    tmp_path = tmp_path_factory.mktemp("slots")
    url, run_id = tinyrun.stored(tmp_path, "slots")
    env = service_env(
        url, None, SOFTEVO_COORDINATOR="false", SOFTEVO_READ_CACHE_SECONDS="30",
        SOFTEVO_BACKGROUND_QUEUE="2", SOFTEVO_BACKGROUND_PER_CLIENT="1", SOFTEVO_FRAMES_TIMEOUT="0.2",
    )  # fmt: skip
    group = Processes(tmp_path, env)
    process, base = group.serve()
    front = httpx.get(f"{base}/runs/{run_id}/front", params={"generation": 0}).json()
    yield base, sorted({m["id"] for m in front["individuals"]}), process
    group.stop_all()


def frames_url(base: str, individual_id: int, every: int = 10) -> str:
    """Frames of one individual; each ``every`` is a read of its own (its own slot)."""
    return f"{base}/individuals/{individual_id}/frames?every={every}&max_frames=2000"


def simulating_children(pid: int) -> list[int]:
    """Background simulation processes of ``pid`` (multiprocessing's spawned children)."""
    found = []
    for entry in Path("/proc").iterdir():
        try:
            stat = (entry / "stat").read_text().rsplit(")", 1)[1].split()
            cmdline = (entry / "cmdline").read_bytes()
        except (OSError, IndexError):
            continue
        if int(stat[1]) == pid and b"spawn_main" in cmdline:
            found.append(int(entry.name))
    return found


def test_a_rejected_write_leaves_the_read_cache_alone(limits_server):
    base, _, _ = limits_server
    httpx.get(f"{base}/experiments")
    assert httpx.get(f"{base}/experiments").headers.get("x-read-cache") == "hit"
    refused = httpx.post(f"{base}/experiments", json=EXPERIMENT)  # no token
    assert refused.status_code == 401
    assert httpx.get(f"{base}/experiments").headers.get("x-read-cache") == "hit"
    assert httpx.post(f"{base}/experiments", json={"name": "x"}, headers=auth()).status_code == 422
    assert httpx.get(f"{base}/experiments").headers.get("x-read-cache") == "hit"


def test_a_timed_out_simulation_frees_its_slot_and_its_process(limits_server):
    base, ids, process = limits_server
    first = httpx.get(frames_url(base, ids[0]), timeout=120)
    assert first.status_code == 504, first.text
    second = httpx.get(frames_url(base, ids[0], every=11), timeout=120)  # one slot per client: free again
    assert second.status_code == 504, second.text
    wait_for(lambda: not simulating_children(process.pid), 10, "the timed-out simulation to end")


def test_one_client_cannot_take_every_slot(limits_server):
    base, ids, _ = limits_server
    other = httpx.Client(transport=httpx.HTTPTransport(local_address="127.0.0.2"), timeout=120)
    barrier = threading.Barrier(3, timeout=60)

    def get(client, every):
        barrier.wait()
        return client.get(frames_url(base, ids[0], every))

    with httpx.Client(timeout=120) as mine, other, ThreadPoolExecutor(3) as pool:
        calls = [
            pool.submit(get, mine, 20),
            pool.submit(get, mine, 21),
            pool.submit(get, other, 22),
        ]
        mine_a, mine_b, theirs = (call.result() for call in calls)
    assert sorted([mine_a.status_code, mine_b.status_code]) == [429, 504]  # one slot for 127.0.0.1
    assert theirs.status_code == 504  # admitted: 127.0.0.2 has a slot of its own


# -- item 2: work has a budget ------------------------------------------------------------------

ONE_TREATMENT_COST = 1.19e11  # voxel-steps of the default land treatment at 0.1 MPa
# the finding's body: 200 treatments of population 10,000, 1e6 generations, 20^3, 10,000 cycles
HUGE = {"environment": "land", "stiffness_mpa": 10.0, "population": 10_000, "generations": 1_000_000,
        "workspace": [20, 20, 20], "cycles": 10_000}  # fmt: skip


@pytest.fixture(scope="module")
def budget_server(tmp_path_factory):
    """``softevo serve`` (coordinator off) on an empty database whose server budget holds one
    default treatment but not two: its base URL."""
    tmp_path = tmp_path_factory.mktemp("budget")
    url = f"sqlite:///{tmp_path / 'budget.db'}"
    open_database(url).dispose()
    env = service_env(url, None, SOFTEVO_COORDINATOR="false",
                      SOFTEVO_MAX_SERVER_VOXEL_STEPS=str(1.5 * ONE_TREATMENT_COST))  # fmt: skip
    group = Processes(tmp_path, env)
    _, base = group.serve()
    yield base
    group.stop_all()


def test_the_findings_body_is_refused_by_its_runs(budget_server):
    treatments = [{**HUGE, "name": f"t{k}", "repetitions": 1000} for k in range(200)]
    body = {"name": "years", "treatments": treatments}
    refused = httpx.post(f"{budget_server}/experiments", json=body, headers=auth(), timeout=60)
    assert refused.status_code == 422, refused.text
    detail = refused.json()["detail"]
    assert "200000 runs" in detail and "SOFTEVO_MAX_RUNS_PER_REQUEST" in detail, detail
    assert all(e["name"] != "years" for e in httpx.get(f"{budget_server}/experiments").json())


def test_an_experiment_over_the_request_budget_is_refused_with_its_cost(budget_server):
    body = {"name": "one-huge", "treatments": [HUGE]}
    refused = httpx.post(f"{budget_server}/experiments", json=body, headers=auth())
    assert refused.status_code == 422, refused.text
    detail = refused.json()["detail"]
    # 10,000 x 1e6 generations x 8000 voxels x 20,000,000 steps (the scene's max_steps)
    assert "1.6e+21 voxel-steps" in detail and "SOFTEVO_MAX_REQUEST_VOXEL_STEPS" in detail, detail


def test_the_server_budget_counts_the_unfinished_runs(budget_server):
    body = {"name": "one", "treatments": [{"environment": "land", "stiffness_mpa": 0.1}]}
    first = httpx.post(f"{budget_server}/experiments", json=body, headers=auth())
    assert first.status_code == 201, first.text
    second = httpx.post(f"{budget_server}/experiments", json=body, headers=auth())
    assert second.status_code == 422, second.text
    assert "SOFTEVO_MAX_SERVER_VOXEL_STEPS" in second.json()["detail"]
    (run_id,) = first.json()["runs"]
    assert httpx.post(f"{budget_server}/runs/{run_id}/cancel", headers=auth()).status_code == 200
    third = httpx.post(f"{budget_server}/experiments", json=body, headers=auth())
    assert third.status_code == 201, third.text  # a cancelled run is off the books


def test_the_cli_applies_the_same_budget(tmp_path):
    args = ["run", "--env", "land", "--stiffness", "10", "--population", "10000", "--generations",
            "1000000", "--workspace", "20,20,20", "--db", f"sqlite:///{tmp_path / 'cli.db'}"]  # fmt: skip
    done = subprocess.run([sys.executable, "-m", "softevo.service.cli", *args],
                          capture_output=True, text=True, timeout=300)  # fmt: skip
    assert done.returncode == 2 and "Traceback" not in done.stderr, done.stderr[-2000:]
    assert "SOFTEVO_MAX_REQUEST_VOXEL_STEPS" in done.stderr and "voxel-steps" in done.stderr


@pytest.mark.parametrize("preset", ["paper", "gradual"])
@pytest.mark.parametrize("model", [None, "voxelyze-2"])
def test_the_presets_fit_the_default_budget_at_every_scale(preset, model):
    from softevo.evolution.treatments import SCALES, preset_grid
    from softevo.service.runs.limits import check_experiment, experiment_cost
    from softevo.service.settings import Settings

    settings = Settings.model_construct()  # the defaults, whatever the environment says
    for scale in SCALES:
        treatments = preset_grid(preset, scale, model=model)
        assert check_experiment(treatments, settings=settings) == experiment_cost(treatments)


@pytest.fixture(scope="module")
def paged_server(tmp_path_factory):
    """``softevo serve`` (coordinator off) on a database holding one experiment of 300 runs:
    (base URL, the experiment's id, its run ids)."""
    tmp_path = tmp_path_factory.mktemp("paged")
    url = f"sqlite:///{tmp_path / 'paged.db'}"
    engine = open_database(url)
    treatment = dataclasses.replace(tinyrun.TINY, repetitions=300)
    experiment_id, run_ids = create(engine, "many", [treatment])
    engine.dispose()
    group = Processes(tmp_path, service_env(url, None, SOFTEVO_COORDINATOR="false"))
    _, base = group.serve()
    yield base, experiment_id, run_ids
    group.stop_all()


def test_an_experiments_runs_are_listed_a_page_at_a_time(paged_server):
    base, experiment_id, run_ids = paged_server
    (listed,) = httpx.get(f"{base}/experiments").json()
    assert listed["runs_total"] == 300 and len(listed["runs"]) == 100  # the default page
    assert listed["progress"]["generations_total"] == 300 * tinyrun.TINY.generations  # over all runs
    page = httpx.get(f"{base}/experiments/{experiment_id}", params={"runs_limit": 50, "runs_offset": 280})
    page = page.json()
    assert [run["id"] for run in page["runs"]] == run_ids[280:] and page["runs_total"] == 300
    (counts,) = httpx.get(f"{base}/experiments", params={"runs_limit": 0}).json()
    assert counts["runs"] == [] and counts["status"] == "pending"


def test_a_listing_holds_a_bounded_number_of_runs(paged_server):
    base, _, _ = paged_server
    for params in ({"limit": 101}, {"runs_limit": 201}, {"limit": 1000, "runs_limit": 1000}):
        assert httpx.get(f"{base}/experiments", params=params).status_code == 422, params
    (listed,) = httpx.get(f"{base}/experiments", params={"limit": 100, "runs_limit": 200}).json()
    assert len(listed["runs"]) == 200
    one = httpx.get(f"{base}/experiments/{listed['id']}", params={"runs_limit": 1000}).json()
    assert len(one["runs"]) == 300


# -- item 2: cancel stops the generation in flight --------------------------------------------

SLOW = {"environment": "land", "stiffness_mpa": 1.0, "population": 8, "generations": 2,
        "workspace": [6, 6, 6], "cycles": 2000}  # fmt: skip  # a generation: a minute on one core


def busy_seconds(pid: int) -> float:
    """CPU seconds (user + system) of process ``pid`` so far; 0 once it has ended."""
    try:
        fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    except OSError:
        return 0.0
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def test_cancel_ends_the_evaluations_in_flight(tmp_path):
    url = f"sqlite:///{tmp_path / 'cancel.db'}"
    open_database(url).dispose()
    env = service_env(url, None, SOFTEVO_WORKERS="1", SOFTEVO_GENOMES_PER_JOB="1")
    group = Processes(tmp_path, env)
    try:
        process, base = group.serve()
        body = {"name": "slow", "treatments": [SLOW]}
        created = httpx.post(f"{base}/experiments", json=body, headers=auth())
        (run_id,) = created.json()["runs"]
        evaluators: list[int] = []

        def evaluating() -> bool:  # the pool process has simulated for a second
            evaluators[:] = simulating_children(process.pid)
            return any(busy_seconds(pid) > 1.0 for pid in evaluators)

        wait_for(evaluating, 120, "the run's first evaluation to run")
        cancelled = httpx.post(f"{base}/runs/{run_id}/cancel", headers=auth())
        assert cancelled.status_code == 200, cancelled.text
        wait_for(lambda: not any(Path(f"/proc/{pid}").exists() for pid in evaluators), 15,
                 "the evaluator process to end")  # fmt: skip
        run = httpx.get(f"{base}/runs/{run_id}").json()
        assert run["status"] == "cancelled" and run["generation"] == -1, run  # nothing stored
    finally:
        group.stop_all()


def test_concurrent_experiments_cannot_both_pass_the_budget(db_url, tmp_path):
    """Issue 49.15 (security review): requests fired together each read the unfinished work
    before any inserted, so all of them passed a server budget that holds one; the check and
    the insert are one now (``service.storage.experiments.lock_new_experiments``), on SQLite and
    PostgreSQL alike."""
    import asyncio

    from sqlalchemy import func, select

    from softevo.service.storage.models import ExperimentRow

    engine = open_database(db_url)
    env = service_env(db_url, None, SOFTEVO_COORDINATOR="false",
                      SOFTEVO_MAX_SERVER_VOXEL_STEPS=str(1.5 * ONE_TREATMENT_COST))  # fmt: skip
    group = Processes(tmp_path, env)
    try:
        _, base = group.serve()
        body = {"name": "together", "treatments": [{"environment": "land", "stiffness_mpa": 0.1}]}

        async def fire(count: int) -> list[httpx.Response]:
            async with httpx.AsyncClient(base_url=base, headers=auth(), timeout=120) as client:
                return await asyncio.gather(*(client.post("/experiments", json=body) for _ in range(count)))

        with ThreadPoolExecutor(1) as pool:  # a loop of its own (a browser test may hold this one's)
            answers = pool.submit(asyncio.run, fire(12)).result()
        codes = sorted(answer.status_code for answer in answers)
        assert codes == [201] + [422] * 11, [a.text[:200] for a in answers]
        refused = [a.json()["detail"] for a in answers if a.status_code == 422]
        assert all("SOFTEVO_MAX_SERVER_VOXEL_STEPS" in detail for detail in refused), refused
        with engine.connect() as conn:
            assert conn.execute(select(func.count()).select_from(ExperimentRow.__table__)).scalar() == 1
    finally:
        group.stop_all()
        engine.dispose()
