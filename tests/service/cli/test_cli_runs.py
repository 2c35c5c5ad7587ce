"""``softevo run | experiment | status | resume | export | lineage`` on the embedded default."""

from __future__ import annotations

import json

import pandas as pd
import pytest

from tests.support import softevo

TINY = [
    "--population",
    "3",
    "--generations",
    "3",
    "--workspace",
    "3,3,3",
    "--cycles",
    "1",
    "--workers",
    "0",
    "--quiet",
]


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--env", "moon", "--stiffness", "1"], "unknown environment 'moon'"),
        (["--env", "land", "--stiffness", "1", "--population", "-5"], "population must be"),
        (["--env", "land", "--stiffness", "20"], "stiffness must be within"),
        (["--env", "land", "--stiffness", "0.0001"], "stiffness must be within"),
        (["--env", "land", "--stiffness", "1", "--workspace", "3,3"], "--workspace"),
        (["--env", "land", "--stiffness", "1", "--switch-at", "2"], "transition"),
        (["--env", "land", "--stiffness", "1", "--db", "sqlite:////proc/no/x.db"], "cannot be"),
    ],
)
def test_bad_arguments_are_one_line_and_exit_2(capsys, tmp_path, args, message):
    if "--db" not in args:
        args = [*args, "--db", f"sqlite:///{tmp_path / 'x.db'}"]
    code, _, err = softevo(capsys, "run", *args)
    assert code == 2
    assert err.count("\n") == 1 and err.startswith("error: ") and message in err


def test_bad_experiment_arguments(capsys, tmp_path):
    db = f"sqlite:///{tmp_path / 'x.db'}"
    assert softevo(capsys, "experiment", "zoo", "--db", db)[0] == 2
    code, _, err = softevo(capsys, "experiment", "paper", "--scale", "huge", "--db", db)
    assert code == 2 and "unknown scale" in err


def test_run_status_lineage_export_end_to_end(capsys, tmp_path):
    db = f"sqlite:///{tmp_path / 'e2e.db'}"
    code, out, err = softevo(capsys, "run", "--env", "water-land", "--stiffness", "0.1", *TINY, "--db", db)
    assert code == 0, err
    assert "finished" in out
    code, out, _ = softevo(capsys, "status", "--db", db)
    assert code == 0 and "finished" in out and "3/3" in out
    code, out, _ = softevo(capsys, "export", "e1", "--out", str(tmp_path / "out"), "--db", db)
    assert code == 0
    individuals = pd.read_csv(tmp_path / "out" / "individuals.csv")
    child = individuals[individuals["parent_id"].notna()].iloc[-1]
    code, out, _ = softevo(capsys, "lineage", str(child["individual_id"]), "--json", "--db", db)
    records = json.loads(out)
    assert records[0]["id"] == child["individual_id"]
    assert records[1]["id"] == child["parent_id"] and records[-1]["parent_id"] is None
    code, out, _ = softevo(capsys, "resume", "--db", db, "--quiet")
    assert code == 0 and "nothing to do" in out
    assert softevo(capsys, "lineage", "999999", "--db", db)[0] == 2
    assert softevo(capsys, "status", "r42", "--db", db)[0] == 2


def test_resume_by_name_continues_a_cancelled_run(capsys, tmp_path):
    from softevo.evolution.run_status import RunStatus
    from softevo.service.storage import open_database
    from softevo.service.storage.runs import run_row, set_run_status
    from tests.service import tinyrun

    db = f"sqlite:///{tmp_path / 'cancelled.db'}"
    engine = open_database(db)
    run_id = tinyrun.new_run(engine)
    with engine.begin() as conn:
        set_run_status(conn, run_id, RunStatus.CANCELLED)
    assert "nothing to do" in softevo(capsys, "resume", "--db", db, "-q", "--workers", "0")[1]
    code, _, err = softevo(capsys, "resume", f"r{run_id}", "--db", db, "-q", "--workers", "0")
    assert code == 0, err
    with engine.connect() as conn:
        assert run_row(conn, run_id)["status"] == "finished"


def test_ctrl_c_exits_130_so_a_chained_report_does_not_run(tmp_path):
    """Ctrl-C (SIGINT to the terminal's process group) while ``softevo run`` evolves: exit
    130, so ``softevo run ... && softevo report ...`` stops (issue 49.12: it exited 0)."""
    import os
    import shutil
    import signal
    import subprocess
    import sys
    import time

    from sqlalchemy import create_engine, text

    db = tmp_path / "interrupted.db"
    exe = shutil.which("softevo")
    cmd = [exe] if exe else [sys.executable, "-m", "softevo.service.cli"]
    args = ["run", "--env", "land", "--stiffness", "1", "--population", "4", "--generations", "100000",
            "--workspace", "3,3,3", "--cycles", "1", "--workers", "0", "--quiet", "--db", f"sqlite:///{db}"]
    # its own process group with Ctrl-C's default action, as a terminal's job: a command started
    # in the background of a script (as .ci/run starts the tests) inherits SIGINT ignored, and a
    # Python started so keeps it ignored (as nohup would)
    proc = subprocess.Popen([*cmd, *args], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            start_new_session=True,
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    try:
        generation = -1
        while generation < 1 and proc.poll() is None:  # a generation stored: it is evolving
            time.sleep(0.5)
            if db.exists():
                engine = create_engine(f"sqlite:///{db}")
                try:
                    with engine.connect() as conn:
                        generation = conn.execute(text("SELECT max(generation) FROM runs")).scalar() or -1
                except Exception:  # the tables are being created
                    pass
                finally:
                    engine.dispose()
        assert proc.poll() is None, proc.communicate()
        os.killpg(proc.pid, signal.SIGINT)
        _, err = proc.communicate(timeout=120)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
    assert proc.returncode == 130, err
    assert "interrupted" in err and "softevo resume" in err and "Traceback" not in err, err


def test_a_run_whose_evaluations_all_fail_ends_failed_and_says_why(capsys, tmp_path):
    """Issue 49.1: every evaluation over the step budget (10 MPa: a short step; 10,000 cycles)
    ended "finished" with best 0.000 and exit 0; now the run fails after its first generation,
    the command exits 1 with the reason, and status and report say it."""
    db = f"sqlite:///{tmp_path / 'failing.db'}"
    args = ["--population", "4", "--generations", "5", "--workspace", "3,3,3", "--workers", "0", "--quiet"]
    code, out, err = softevo(capsys, "run", "--env", "land", "--stiffness", "10", "--cycles", "10000", *args,
                             "--db", db)
    assert code == 1, err
    assert "failed" in out and "1/5" in out, out  # stopped after generation 0
    import re

    pattern = r"run 1 failed: (\d+) of \1 evaluations of generation 0 failed \(a run fails at 95%\)"
    found = re.search(pattern, err)
    assert found and "step budget exceeded" in err, err  # every simulated one (passive bodies are not)
    reason = found.group(0)
    code, out, err = softevo(capsys, "status", "--db", db)
    assert code == 0 and "failed" in out and reason in err, (out, err)
    code, out, err = softevo(capsys, "report", "e1", "--out", str(tmp_path / "report"), "--no-animation",
                             "--quiet", "--db", db)
    assert code == 0, err
    assert f"warning: 1 of 1 run(s) failed: r1 (land S=10MPa): {reason.split('failed: ')[1]}" in err, err
    assert "1 of 1 run(s) failed" in (tmp_path / "report" / "report.md").read_text()


@pytest.mark.parametrize(
    ("option", "message"),
    [
        (["--cycles", "1000000"], "cycles must be within 1..10,000 (got 1,000,000)"),
        (["--generations", "1000000000"], "generations must be within 1..1,000,000 (got 1,000,000,000)"),
        (["--population", "20000"], "population must be within 2..10,000 (got 20,000)"),
        (["--workspace", "70,2,2"], "workspace must be 3 integers within 1..64 voxels (got 70,2,2)"),
        (["--max-seconds", "5000"], "max_seconds must be at most 3600 (got 5000)"),
    ],
)
def test_the_cli_takes_what_the_api_takes(capsys, tmp_path, option, message):
    """Issue 49.1: the CLI accepted 1e6 cycles and 1e9 generations (REST: 10,000, 1,000,000)."""
    db = tmp_path / "limits.db"
    code, out, err = softevo(capsys, "run", "--env", "land", "--stiffness", "1", *option, "--db", f"sqlite:///{db}")
    assert code == 2 and out == "" and err == f"error: {message}\n", err
    assert not db.exists()  # refused before anything was stored


def test_a_bare_number_says_what_it_was_taken_as(capsys, tmp_path):
    """Issue 49.5: ``1`` was silently a run in best and status, an individual in lineage, runs
    in export and an experiment in report; each now says which, and ``report r1`` (a run) is
    refused naming the run's experiment instead of being taken as experiment 1."""
    db = f"sqlite:///{tmp_path / 'ids.db'}"
    assert softevo(capsys, "run", "--env", "land", "--stiffness", "1", *TINY, "--db", db)[0] == 0
    for command, taken in (("best", "run 1; e1 names experiment 1"),
                           ("status", "run 1; e1 names experiment 1"),
                           ("lineage", "individual 1; r1 names run 1's best individual")):
        code, _, err = softevo(capsys, command, "1", "--db", db)
        assert code == 0 and err == f"note: 1 is taken as {taken}\n", (command, err)
    code, _, err = softevo(capsys, "export", "1", "--out", str(tmp_path / "out"), "--db", db)
    assert code == 0 and "note: 1 is taken as run 1" in err, err
    assert softevo(capsys, "best", "r1", "--db", db)[2] == ""  # a prefixed id needs no note
    code, _, err = softevo(capsys, "lineage", "999999", "--db", db)  # an error says it in its one line
    assert code == 2 and err == ("error: no individual 999999 (999999 is taken as individual 999999; "
                                 "r999999 names run 999999's best individual)\n"), err
    code, _, err = softevo(capsys, "report", "r1", "--out", str(tmp_path / "report"), "--db", db)
    assert code == 2 and err == "error: 'r1' names a run, not an experiment; run 1 is in experiment e1\n", err
