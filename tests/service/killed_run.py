"""Run in a subprocess by test_resume: advance run 1 and SIGKILL this process at a chosen point.

python -m tests.service.killed_run DB_URL after-commit GENERATION
python -m tests.service.killed_run DB_URL during-write GENERATION
"""

from __future__ import annotations

import os
import signal
import sys

from softevo.service.runs.coordinator import Coordinator
from softevo.service.runs.executors import InlineExecutor
from softevo.service.storage import generations, open_database
from softevo.service.storage.models import PopulationMemberRow


def _die() -> None:
    os.kill(os.getpid(), signal.SIGKILL)


def main(url: str, mode: str, generation: int) -> None:
    engine = open_database(url)

    def after_commit(report) -> None:
        if report.generation == generation:
            _die()

    real_insert = generations.insert_ignore

    def insert_then_die(conn, table, rows):
        real_insert(conn, table, rows)
        if table is PopulationMemberRow.__table__ and rows and rows[0]["generation"] == generation:
            _die()  # individuals, evaluations and members written, not committed

    if mode == "during-write":
        generations.insert_ignore = insert_then_die
    listener = after_commit if mode == "after-commit" else None
    Coordinator(engine, InlineExecutor(), on_generation=listener).run([1])


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2], int(sys.argv[3]))
