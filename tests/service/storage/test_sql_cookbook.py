"""docs/sql.md: every cookbook query, extracted from the markdown and run verbatim on SQLite
and PostgreSQL against the hand-built phylogeny (tests/service/handbuilt.py), answers the
question it states; the exaptation summary (``service.storage.exaptation``) agrees with it."""

from __future__ import annotations

import re
from pathlib import Path

import pytest
from sqlalchemy import text

from softevo.service.storage.archive import run_archive
from softevo.service.storage.exaptation import exaptation
from tests.service import handbuilt

DOC = Path(__file__).resolve().parents[3] / "docs" / "sql.md"
BLOCK = re.compile(r"<!-- cookbook: (\w+) -->\s*```sql\n(.*?)```", re.S)
SWITCH = handbuilt.TREATMENT.switch_generation()
LAST = max(handbuilt.KEPT)


def cookbook() -> dict[str, str]:
    return {name: sql for name, sql in BLOCK.findall(DOC.read_text(encoding="utf-8"))}


def line_of(local: int) -> list[int]:
    """local ids from ``local`` back to its root, by the hand-built parents."""
    line = [local]
    while line[-1] in handbuilt.PARENTS:
        line.append(handbuilt.PARENTS[line[-1]])
    return line


def descendants(founder: int) -> set[int]:
    return {i for i in handbuilt.BORN if founder in line_of(i)}


@pytest.fixture
def built(engine):
    run_id = handbuilt.build(engine)
    ids = {local: handbuilt.db_id(engine, run_id, local) for local in handbuilt.BORN}
    local = {db: loc for loc, db in ids.items()}

    def query(name: str, **params):
        with engine.connect() as conn:
            return [tuple(row) for row in conn.execute(text(cookbook()[name]), params)]

    return engine, run_id, ids, local, query


def test_the_cookbook_has_every_example():
    assert set(cookbook()) == {
        "switch",
        "ancestors",
        "descendants",
        "surviving",
        "first_change",
        "dominant_founders",
        "archive",
    }


DEFAULT_GRID = {"low_x": 0.0, "high_x": 5.0, "cells_x": 6, "low_y": 0.0, "high_y": 1.0, "cells_y": 6}


def test_archive(built):
    """Every hand-built evaluation has frequency 2 and branching 0.1 (cell (2, 0)): the cell's
    elite is the world's farthest evaluation up to the generation (local id x 1 on land, x 2
    in water; 9 failed, but its distance stands)."""
    engine, run_id, ids, local, query = built
    for world, generation, best in (("land", 1, 6), ("water", 2, 9), ("water", 3, 12)):
        rows = query("archive", run_id=run_id, environment=world, generation=generation, **DEFAULT_GRID)
        assert [(row[0], row[1], local[row[2]], row[3]) for row in rows] == [
            (2, 0, best, handbuilt.distance(best, world))
        ]
        with engine.connect() as conn:
            archive = run_archive(conn, run_id, generation, world)
        assert [(e["cell"], e["individual"]) for e in archive["elites"]] == [([2, 0], ids[best])]


def test_switch(built):
    _, run_id, _, _, query = built
    assert query("switch", run_id=run_id) == [(SWITCH,)]


def test_ancestors(built):
    _, _, ids, local, query = built
    rows = query("ancestors", individual_id=ids[10])
    assert [local[r[1]] for r in rows] == line_of(10)
    assert [r[0] for r in rows] == list(range(len(line_of(10))))
    assert [r[3] for r in rows] == [handbuilt.BORN[i] for i in line_of(10)]
    assert rows[-1][2] is None


def test_descendants_of_the_founders(built):
    _, run_id, ids, local, query = built
    rows = query("descendants", run_id=run_id, switch_at=SWITCH)
    found: dict[int, set[int]] = {}
    for founder, individual, _depth, last in rows:
        found.setdefault(local[founder], set()).add(local[individual])
        kept = [g for g, members in handbuilt.KEPT.items() if local[individual] in members]
        assert last == (max(kept) if kept else None)
    assert found == {f: descendants(f) for f in handbuilt.KEPT[SWITCH - 1]}


def test_surviving_lineages(built):
    _, run_id, ids, local, query = built
    rows = query("surviving", run_id=run_id)
    assert {local[final]: (local[root], depth) for final, root, depth in rows} == {
        f: (line_of(f)[-1], len(line_of(f)) - 1) for f in handbuilt.KEPT[LAST]
    }


def test_first_trait_change(built):
    _, _, ids, _, query = built
    for final in handbuilt.KEPT[LAST]:
        line = list(reversed(line_of(final)))  # root first
        changed = [
            handbuilt.BORN[child]
            for parent, child in zip(line, line[1:], strict=False)
            if handbuilt.voxel_count(child) != handbuilt.voxel_count(parent)
        ]
        assert query("first_change", individual_id=ids[final]) == [(changed[0] if changed else None,)]


def test_dominant_founders_agree_with_the_exaptation_summary(built):
    engine, run_id, ids, local, query = built
    rows = query("dominant_founders", run_id=run_id, switch_at=SWITCH)
    final, front = handbuilt.KEPT[LAST], handbuilt.KEPT[LAST][0]  # the first kept is rank 0
    expected = {}
    for founder in handbuilt.KEPT[SWITCH - 1]:
        lines = [f for f in final if founder in line_of(f)]
        if lines:
            expected[founder] = (len(lines), sum(1 for f in lines if f == front))
    assert {local[f]: (n, on_front) for f, n, on_front in rows} == expected
    assert [r[2] for r in rows] == sorted((r[2] for r in rows), reverse=True)
    with engine.connect() as conn:
        summary = exaptation(conn, run_id)
    assert summary["founders_surviving"] == len(rows)
    assert {
        local[f["founder_id"]]: (f["lines"], f["front_lines"]) for f in summary["founder_lines"] if f["lines"]
    } == expected
    surviving = query("surviving", run_id=run_id)
    assert summary["roots"] == sorted({root for _, root, _ in surviving})
    assert summary["every_line_rooted"] and summary["final_population"] == len(surviving)
