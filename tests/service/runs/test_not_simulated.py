"""A real tiny land -> water run: no individual is simulated twice in one world, survivors
only again at the switch, and each generation's stats count the evaluations it reused."""

from __future__ import annotations

from collections import Counter

from sqlalchemy import select

from softevo.service.runs.executors import InlineExecutor
from softevo.service.storage import open_database
from softevo.service.storage.models import EvaluationRow, GenerationRow
from tests.service import tinyrun


class RecordingExecutor(InlineExecutor):
    """The inline executor, noting every task it simulates."""

    def __init__(self) -> None:
        super().__init__()
        self.tasks: list[tuple[int, int, str]] = []

    def evaluate(self, tasks):
        self.tasks += [(t["id"], t["generation"], t["environment"]) for t in tasks]
        return super().evaluate(tasks)


def test_survivors_are_simulated_again_only_in_a_new_world(tmp_path):
    engine = open_database(f"sqlite:///{tmp_path / 'runs.db'}")
    run_id = tinyrun.new_run(engine)  # land -> water at generation 3, 5 generations
    executor = RecordingExecutor()
    tinyrun.run_to_end(engine, run_id, executor)
    simulated = Counter((local, env) for local, _, env in executor.tasks)
    assert max(simulated.values()) == 1  # never twice in one world
    snap = tinyrun.snapshot(engine, run_id)
    for generation in range(1, 5):
        survivors = {m[1] for m in snap["members"] if m[0] == generation - 1}
        handed_out = {local for local, g, _ in executor.tasks if g == generation}
        if generation == 3:  # the switch: every survivor again, now in water
            assert survivors <= handed_out
        else:
            assert not survivors & handed_out
    with engine.connect() as conn:
        rows = conn.execute(
            select(GenerationRow.generation, GenerationRow.evaluations, GenerationRow.stats).where(
                GenerationRow.run_id == run_id
            )
        ).all()
        stored = Counter(
            conn.execute(select(EvaluationRow.generation).where(EvaluationRow.run_id == run_id)).scalars()
        )
    per_generation = Counter(g for _, g, _ in executor.tasks)
    assert len(rows) == 5
    for generation, evaluations, stats in rows:
        assert evaluations == per_generation[generation]
        not_simulated = stats["reused"] + stats["empty_bodies"] + stats["passive_bodies"]
        assert evaluations + not_simulated == stored[generation]
    engine.dispose()
