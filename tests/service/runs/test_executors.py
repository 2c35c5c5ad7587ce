"""The ``Executor`` interface is whole: every executor has each of its members (defaults
from ``BlockingExecutor`` where an executor has nothing to add), an in-process executor's
``submit`` / ``wait`` give what ``evaluate`` gives, and service/runs calls the interface
directly, never probing an executor with ``hasattr`` / ``getattr``."""

from __future__ import annotations

import ast
import inspect
from pathlib import Path

import pytest

from softevo.service.runs import executors
from softevo.service.runs.executors import BlockingExecutor, Executor, InlineExecutor, LocalExecutor
from softevo.service.runs.rq_executor import RQExecutor
from tests.service.runs.test_rq_executor import tasks, without_seconds

RUNS = Path(executors.__file__).parent
MEMBERS = [name for name in dir(Executor) if not name.startswith("_")] + list(Executor.__annotations__)


def test_the_interface_names_what_the_coordinator_uses():
    assert {"evaluate", "submit", "wait", "drop_runs", "keep_runs", "close", "workers", "pipelined"} <= set(
        MEMBERS
    )


@pytest.mark.parametrize("kind", [BlockingExecutor, InlineExecutor, LocalExecutor, RQExecutor])
def test_every_executor_has_the_whole_interface(kind):
    missing = [name for name in MEMBERS if not hasattr(kind, name)]
    assert missing == []


def test_an_inline_executor_submits_and_waits_as_it_evaluates():
    executor = InlineExecutor()
    work = tasks(3)
    assert not executor.pipelined
    ticket = executor.submit(work)
    assert executor.wait([ticket], timeout=0) == [ticket]
    assert without_seconds(ticket.results) == without_seconds(executor.evaluate(work))
    executor.drop_runs([1])  # nothing in flight: the next call evaluates as before
    assert [r["id"] for r in executor.evaluate(work)] == [0, 1, 2]
    executor.keep_runs([1])
    executor.close()


def probes(path: Path) -> list[str]:
    """``hasattr`` / ``getattr`` calls in ``path`` whose object names an executor."""
    found = []
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        called = node.func.id if isinstance(node, ast.Call) and isinstance(node.func, ast.Name) else None
        if called in {"hasattr", "getattr"}:
            target = ast.unparse(node.args[0]) if node.args else ""
            if "executor" in target.lower():
                found.append(f"{path.name}:{node.lineno}: {ast.unparse(node)}")
    return found


def test_service_runs_never_probes_an_executor():
    assert sorted(RUNS.glob("*.py"))
    assert [probe for path in sorted(RUNS.glob("*.py")) for probe in probes(path)] == []


def test_the_probe_finder_sees_a_probe(tmp_path):
    source = tmp_path / "probe.py"
    source.write_text(inspect.cleandoc('''
        def f(self):
            return getattr(self.executor, "drop_runs", None), hasattr(executor, "wait"), getattr(self, "x")
    '''))
    assert len(probes(source)) == 2
