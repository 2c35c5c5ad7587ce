"""Phylogeny queries on the hand-built run (SQLite and, when available, PostgreSQL)."""

from __future__ import annotations

import pytest

from softevo.errors import UserError
from softevo.service.storage import phylogeny
from tests.service import handbuilt


@pytest.fixture
def run(engine):
    run_id = handbuilt.build(engine)
    ids = {local: handbuilt.db_id(engine, run_id, local) for local in handbuilt.BORN}
    return engine, run_id, ids


def test_ancestors_to_the_root(run):
    engine, _, ids = run
    frame = phylogeny.ancestors(engine, ids[10])
    assert list(frame["id"]) == [ids[10], ids[7], ids[4], ids[1]]
    assert list(frame["depth"]) == [0, 1, 2, 3]
    assert list(frame["generation_born"]) == [3, 2, 1, 0]
    assert frame["parent_id"].iloc[-1] is None or frame["parent_id"].isna().iloc[-1]
    assert list(frame["environment"]) == ["water", "water", "land", "land"]
    assert list(frame["distance"]) == [20.0, 14.0, 4.0, 1.0]


def test_ancestors_latest_evaluation(run):
    engine, _, ids = run
    frame = phylogeny.ancestors(engine, ids[4], which="latest")
    assert list(frame["environment"]) == ["water", "water"]
    assert list(frame["generation"]) == [2, 2]
    assert list(frame["distance"]) == [8.0, 2.0]


def test_ancestors_of_a_newcomer_and_of_nobody(run):
    engine, _, ids = run
    assert list(phylogeny.ancestors(engine, ids[12])["id"]) == [ids[12]]
    empty = phylogeny.ancestors(engine, 10**6)
    assert empty.empty and "distance" in empty.columns


def test_transition_lineages(run):
    engine, run_id, ids = run
    assert phylogeny.switch_generation(engine, run_id) == 2
    frame = phylogeny.transition_lineages(engine, run_id)
    lines = {founder: sorted(group["id"]) for founder, group in frame.groupby("founder_id")}
    assert lines == {
        ids[1]: sorted([ids[1], ids[4], ids[7], ids[10]]),
        ids[4]: sorted([ids[4], ids[7], ids[10]]),
        ids[5]: sorted([ids[5], ids[8], ids[11]]),
    }
    last = dict(zip(frame["id"], frame["last_generation"], strict=False))
    assert last[ids[10]] == 3 and last[ids[1]] == 1 and last[ids[5]] == 1


def test_transition_lineages_explicit_switch(run):
    engine, run_id, ids = run
    frame = phylogeny.transition_lineages(engine, run_id, switch_at=3)
    assert set(frame["founder_id"]) == {ids[4], ids[7], ids[8]}


def test_trait_changes_along_a_line(run):
    engine, _, ids = run
    voxels = phylogeny.trait_changes(engine, ids[10], "voxel_count")
    assert list(voxels["id"]) == [ids[7]]  # 4 kept 1's 10 voxels; 10 kept 7's 70
    assert list(voxels["previous"]) == [10] and list(voxels["value"]) == [70]
    assert phylogeny.first_trait_change(engine, ids[10], "voxel_count") == 2
    assert phylogeny.first_trait_change(engine, ids[10], "active_share") == 2
    assert phylogeny.first_trait_change(engine, ids[11], "active_share") is None
    assert phylogeny.first_trait_change(engine, ids[11], "voxel_count") == 1


def test_unknown_trait_is_a_user_error(run):
    engine, _, ids = run
    with pytest.raises(UserError, match="unknown trait"):
        phylogeny.trait_changes(engine, ids[10], "voxel_count; drop table runs")
