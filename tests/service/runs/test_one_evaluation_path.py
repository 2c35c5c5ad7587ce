"""One evaluation path: ``softevo.evolve`` (in memory) and ``softevo run`` (stored, worker
processes) ask, evaluate through the workers' job function and tell alike, so with the same
seed they keep the same survivors with the same distances and descriptors at every
generation, across a switch of worlds too (issue 48)."""

from __future__ import annotations

from pathlib import Path

import pytest
from sqlalchemy import create_engine, select

import softevo
from softevo.service.storage.models import EvaluationRow, IndividualRow, PopulationMemberRow
from tests.support import softevo_process

ROOT = Path(__file__).resolve().parents[3]
SETTINGS = {"population": 4, "generations": 4, "workspace": (4, 4, 4), "cycles": 1, "seed": 3, "switch_at": 2}


def stored_members(url: str) -> dict[int, list[tuple[int, float, float | None]]]:
    """{generation: [(local id, distance, symmetry) of each member, by id]}: the member's
    latest evaluation at or before the generation."""
    engine = create_engine(url)
    members, individuals, evaluations = (
        PopulationMemberRow.__table__, IndividualRow.__table__, EvaluationRow.__table__)
    query = (
        select(members.c.generation, individuals.c.local_id, evaluations.c.generation,
               evaluations.c.distance, evaluations.c.symmetry)
        .join(individuals, individuals.c.id == members.c.individual_id)
        .join(evaluations, (evaluations.c.individual_id == members.c.individual_id)
              & (evaluations.c.generation <= members.c.generation))
        .order_by(evaluations.c.generation)
    )
    latest: dict[tuple[int, int], tuple[float, float | None]] = {}
    with engine.connect() as conn:
        for generation, local_id, _, distance, symmetry in conn.execute(query):  # later ones win
            latest[int(generation), int(local_id)] = (float(distance), symmetry)
    engine.dispose()
    found: dict[int, list] = {}
    for (generation, local_id), (distance, symmetry) in latest.items():
        found.setdefault(generation, []).append((local_id, distance, symmetry))
    return {g: sorted(rows) for g, rows in found.items()}


@pytest.mark.slow
def test_evolve_and_run_keep_the_same_survivors_and_distances_at_every_generation(tmp_path):
    url = f"sqlite:///{tmp_path / 'run.db'}"
    args = ["--population", "4", "--generations", "4", "--workspace", "4,4,4", "--cycles", "1", "--seed", "3",
            "--switch-at", "2"]
    done = softevo_process("run", "--env", "land-water", "--stiffness", "1", *args, "--db", url,
                           "--workers", "2", cwd=ROOT)
    assert done.returncode == 0, done.stderr
    stored = stored_members(url)

    local = softevo.evolve("land-water", 1.0, **SETTINGS)
    assert [row["generation"] for row in local.history] == sorted(stored) == [0, 1, 2, 3]
    assert [row["environment"] for row in local.history] == ["land", "land", "water", "water"]
    for row in local.history:
        assert [(i, d) for i, d, _ in stored[row["generation"]]] == row["members"]
    assert max(d for _, d in local.history[-1]["members"]) > 0  # something moved
    # the same descriptors: the workers' evaluation computes them in both
    final = {ind.id: (ind.descriptors or {}).get("symmetry") for ind in local.evolution.population}
    assert any(value is not None for value in final.values())
    assert {i: s for i, _, s in stored[3]} == pytest.approx(final)


def test_evolve_returns_the_best_robot_of_each_world_with_a_scene_that_reproduces_it():
    local = softevo.evolve("land-water", 1.0, population=3, generations=3, workspace=(3, 3, 3), cycles=1,
                           seed=1, switch_at=1)
    assert local.best().world == "water" == local.history[-1]["environment"]
    for world in ("land", "water"):
        best = local.best(world)
        assert best.world == world and best.scene["environment"]["kind"] == world
        result = softevo.simulate(best.scene)
        assert result.stable
        assert result.distance == pytest.approx(best.distance, rel=1e-9, abs=1e-12)
    with pytest.raises(KeyError, match="worlds seen: land, water"):
        local.best("void")
