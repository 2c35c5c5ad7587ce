"""Storage at scale: bytes per stored row, the paper grid's database size, and the time of
the queries researchers run, on a store of one paper-sized run among 180 (docs/sql.md).

    python bench/storage_scale.py [--db URL] [--generations 9000] [--population 30]
                                  [--evolved 300] [--repeats 3]

1. Store. A new experiment of the paper's 12 treatments x 15 repetitions (``paper_grid``,
   generations scaled by ``--generations / 9000``, population ``--population``). Its run
   ``land-water S3`` #0 gets every generation in full: the first ``--evolved`` through
   the real algorithm (``coordinator.ask`` / ``tell`` with instant fake results, real
   genomes, mutation and lineages) and ``record_generation``; the rest synthesised in the
   same shapes (each child a parent's genome with one weight changed, one newcomer per
   generation, selection on fitness and age, the re-evaluation at the switch), again
   through ``record_generation``, a batch of generations per transaction, because the
   real algorithm's expression costs about 80 ms a generation on 2 cores (12 minutes
   for 9000). The 179 other runs (the index of 180 runs) get their generation summaries
   (copies of the full run's) and the final algorithm state, finished.
2. Size. Bytes per individual, evaluation, population member, generation summary and run
   (its algorithm state), tables with their indexes (SQLite: ``dbstat``; PostgreSQL:
   ``pg_total_relation_size``), and the paper grid's size extrapolated from them.
3. Queries. Median seconds of ``--repeats`` runs of each: the lineage of the final best,
   the run's tree as ``softevo phylogeny`` pages it and as the dashboard samples it,
   exaptation, the CSV export of the run, the run list and status of 180 runs, the
   report's data load (``load_experiment``).
4. Compression. What zlib (level 6, per value) and compact separators would save on the
   genome and phenotype JSON and the algorithm state.

Default database: a new SQLite file in a temporary folder (``--db sqlite:///FILE``,
``--db postgresql+psycopg://...`` for an empty database).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import statistics
import tempfile
import time
import zlib
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
from coordinator_overhead import InstantExecutor  # bench/: the instant results of the other benches
from sqlalchemy import Connection, Engine, func, select, text

from softevo.evolution.environments import PAPER, between
from softevo.evolution.selection import non_dominated_sort
from softevo.evolution.treatments import Treatment, paper_grid
from softevo.service.reports.data import load_experiment
from softevo.service.runs.coordinator import ask, load_run, tell
from softevo.service.runs.submit import create
from softevo.service.storage import open_database
from softevo.service.storage.exaptation import exaptation
from softevo.service.storage.experiments import list_experiments
from softevo.service.storage.export import export_runs
from softevo.service.storage.generations import (
    GenerationRecord,
    generations,
    insert_ignore,
    record_generation,
)
from softevo.service.storage.individuals import local_to_db_ids
from softevo.service.storage.models import (
    EvaluationRow,
    GenerationRow,
    IndividualRow,
    PopulationMemberRow,
    RunRow,
)
from softevo.service.storage.phylogeny import ancestors
from softevo.service.storage.run_tree import run_phylogeny, tree_sample
from softevo.service.storage.runs import list_runs

PAPER_LONGEST = 9000  # the paper's longest runs (S3 and the transitions), generations
FULL_RUN = (f"{between(*PAPER)} S3", 0)  # the run stored in full: a transition, for exaptation
BATCH = 100  # synthesised generations per transaction
PHYLOGENY_PAGE = 10_000  # what ``softevo phylogeny`` reads per query
ROW_KINDS = {  # table -> what one row is
    "individuals": "individual",
    "evaluations": "evaluation",
    "population_members": "population member",
    "generations": "generation summary",
    "runs": "run (algorithm state)",
}


# -- 1. the store --------------------------------------------------------------------------


def scaled_grid(generations: int, population: int) -> list[Treatment]:
    """The paper's grid with its generations scaled so its longest runs have ``generations``."""
    return [
        dataclasses.replace(
            t,
            population=population,
            generations=max(2, round(t.generations * generations / PAPER_LONGEST)),
        )
        for t in paper_grid("paper")
    ]


def build_store(engine: Engine, args) -> dict[str, Any]:
    """Create the experiment, store its full run and the index; return {experiment_id,
    run_id (the full run), run_ids, seconds}."""
    start = time.perf_counter()
    treatments = scaled_grid(args.generations, args.population)
    experiment_id, run_ids = create(engine, "storage-scale", treatments, preset="paper", scale="paper")
    with engine.connect() as conn:
        runs = list_runs(conn, experiment_id=experiment_id)
    full = next(r["id"] for r in runs if (r["treatment"], r["repetition"]) == FULL_RUN)
    state = store_full_run(engine, full, args)
    built = time.perf_counter() - start
    store_index(engine, full, [r for r in runs if r["id"] != full], treatments, state)
    return {
        "experiment_id": experiment_id,
        "run_id": full,
        "run_ids": run_ids,
        "full_seconds": built,
        "seconds": time.perf_counter() - start,
    }


def store_full_run(engine: Engine, run_id: int, args) -> dict[str, Any]:
    """Every generation of run ``run_id``: ``--evolved`` real ones, then synthesised ones.
    Returns the algorithm state stored after the last real generation."""
    run = load_run(engine, run_id)
    executor = InstantExecutor()
    newcomers: list[dict[str, Any]] = []
    record = None
    while not run.done and run.next_generation < args.evolved:
        record = tell(run, executor.evaluate(ask(run)), 0.0)
        with engine.begin() as conn:
            record_generation(conn, record)
        newcomers += [i for i in record.individuals if i["parent_local_id"] is None]
        run.next_generation += 1
    if run.done:
        return record.state
    synthetic = Synthesised(run, record, newcomers, seed=args.seed)
    while not run.done:
        with engine.begin() as conn:
            for _ in range(min(BATCH, run.generations - run.next_generation)):
                record_generation(conn, synthetic.next_record(run.next_generation))
                run.next_generation += 1
    return record.state


class Synthesised:
    """Generations in the shapes the algorithm stores, without expressing genomes: each
    generation ``population - 1`` children (a parent of a 2-tournament, its genome with one
    weight changed, its fitness plus noise, its age) and one newcomer (a real random
    genome); the population kept is the best ``population`` by (Pareto rank on fitness and
    age, fitness). At the environment switch every survivor is evaluated again."""

    def __init__(self, run, last: GenerationRecord, newcomers: list[dict], seed: int) -> None:
        self.treatment = run.treatment
        self.size = run.treatment.population
        self.rng = np.random.default_rng(seed)
        self.newcomers = newcomers
        self.state = last.state
        self.run_id = run.run_id
        born = {i.id: i for i in run.algorithm.population}
        self.population = [self._member(born[m["local_id"]], run) for m in last.members]
        self.next_id = max(i["local_id"] for i in self.population) + 1

    def _member(self, individual, run) -> dict[str, Any]:
        encoding = run.algorithm.config.encoding
        return {
            "local_id": individual.id,
            "genome": individual.genome.to_dict(),
            "phenotype": individual.phenotype(encoding).summary(),
            "age": individual.age,
            "distance": float(individual.objectives["distance"]),
            "active_share": float(individual.objectives["active_share"]),
            "voxel_count": int(individual.objectives["voxel_count"]),
            "descriptors": individual.descriptors,
        }

    def next_record(self, generation: int) -> GenerationRecord:
        environment = self.treatment.environment_at(generation)
        switched = environment != self.treatment.environment_at(generation - 1)
        for member in self.population:
            member["age"] += 1
            if switched:
                member["distance"] = float(self.rng.random())
        born = [self._child(generation) for _ in range(self.size - 1)] + [self._newcomer(generation)]
        evaluated = born + (self.population if switched else [])
        self.population = self._select(self.population + born)
        record = GenerationRecord(self.run_id, generation, state=self.state)
        record.individuals = [_individual_row(i, generation) for i in born]
        record.evaluations = [self._evaluation_row(i, generation, environment) for i in evaluated]
        ranks = _front_ranks(self.population)
        record.members = [
            {"local_id": i["local_id"], "front_rank": rank, "age": i["age"]}
            for i, rank in zip(self.population, ranks, strict=True)
        ]
        record.summary = self._summary(environment, len(evaluated), ranks)
        record.finished = generation + 1 >= self.treatment.generations
        return record

    def _child(self, generation: int) -> dict[str, Any]:
        a, b = self.rng.choice(len(self.population), 2, replace=False)
        parent = max(self.population[a], self.population[b], key=lambda i: i["distance"])
        child = dict(parent, local_id=self._new_id(), parent_local_id=parent["local_id"])
        child["genome"] = changed_weight(parent["genome"], self.rng)
        child["phenotype"] = dict(parent["phenotype"], hash=f"{self.rng.bytes(20).hex()}")
        child["distance"] = max(0.0, parent["distance"] + float(self.rng.normal(0, 0.02)))
        return child

    def _newcomer(self, generation: int) -> dict[str, Any]:
        real = self.newcomers[generation % len(self.newcomers)]
        template = self.population[0]
        return dict(
            template,
            local_id=self._new_id(),
            parent_local_id=None,
            genome=real["genome"],
            phenotype=real["phenotype"],
            age=0,
            distance=float(self.rng.random()) * 0.5,
        )

    def _new_id(self) -> int:
        self.next_id += 1
        return self.next_id - 1

    def _select(self, candidates: list[dict]) -> list[dict]:
        F = np.array([[-c["distance"], c["age"]] for c in candidates], dtype=float)
        ranks = non_dominated_sort(F)
        order = sorted(range(len(candidates)), key=lambda k: (ranks[k], -candidates[k]["distance"]))
        return [candidates[k] for k in order[: self.size]]

    def _evaluation_row(self, individual: dict, generation: int, environment: str) -> dict[str, Any]:
        descriptors = individual["descriptors"] or {}
        return {
            "local_id": individual["local_id"],
            "generation": generation,
            "age": individual["age"],
            "environment": environment,
            "stiffness": self.treatment.stiffness_pa,
            "distance": individual["distance"],
            "active_share": individual["active_share"],
            "voxel_count": individual["voxel_count"],
            **{
                name: descriptors.get(name)
                for name in ("frequency", "symmetry", "branching", "shape_entropy")
            },
            "descriptors": individual["descriptors"],
            "stable": True,
            "error": None,
            "seconds": 0.0,
        }

    def _summary(self, environment: str, evaluations: int, ranks: list[int]) -> dict[str, Any]:
        distances = [i["distance"] for i in self.population]
        return {
            "environment": environment,
            "evaluations": evaluations,
            "evaluation_seconds": 0.0,
            "best_distance": max(distances),
            "mean_distance": float(np.mean(distances)),
            "front_size": ranks.count(0),
            "failed": 0,
            "reused": 0,
            "empty_bodies": 0,
            "mean_voxel_count": float(np.mean([i["voxel_count"] for i in self.population])),
            "mean_active_share": float(np.mean([i["active_share"] for i in self.population])),
            "best_local_id": self.population[int(np.argmax(distances))]["local_id"],
        }


def _individual_row(individual: dict, generation: int) -> dict[str, Any]:
    return {
        "local_id": individual["local_id"],
        "parent_local_id": individual["parent_local_id"],
        "generation_born": generation,
        "genome": individual["genome"],
        "phenotype": individual["phenotype"],
    }


def _front_ranks(population: list[dict]) -> list[int]:
    F = np.array([[-i["distance"], i["active_share"], i["voxel_count"]] for i in population], dtype=float)
    return [int(rank) for rank in non_dominated_sort(F)]


def changed_weight(genome: dict[str, Any], rng: np.random.Generator) -> dict[str, Any]:
    """A copy of genome JSON ``genome`` with one link weight of one network changed."""
    networks = [name for name, net in genome.items() if isinstance(net, dict) and net.get("links")]
    if not networks:
        return genome
    name = networks[int(rng.integers(len(networks)))]
    links = [list(link) for link in genome[name]["links"]]
    k = int(rng.integers(len(links)))
    links[k][-1] = float(links[k][-1]) + float(rng.normal(0, 0.5))
    return {**genome, name: {**genome[name], "links": links}}


def store_index(engine: Engine, full: int, others: list[dict], treatments: list[Treatment], state) -> None:
    """The other runs, finished: the full run's generation summaries (as many as each run
    has, in its own environments) and its final algorithm state."""
    by_name = {t.name: t for t in treatments}
    with engine.connect() as conn:
        summaries = generations(conn, full)
    for run in others:
        treatment = by_name[run["treatment"]]
        rows = [
            {**_summary_of(s), "environment": treatment.environment_at(s["generation"])}
            for s in summaries[: treatment.generations]
        ]
        *earlier, last = rows
        with engine.begin() as conn:
            for start in range(0, len(earlier), 5000):
                insert_ignore(
                    conn,
                    GenerationRow.__table__,
                    [
                        {"run_id": run["id"], **r, "stats": r.pop("extra")}
                        for r in earlier[start : start + 5000]
                    ],
                )
            summary = {
                **last.pop("extra"),
                **{k: v for k, v in last.items() if k not in ("generation", "created_at")},
            }
            record_generation(
                conn,
                GenerationRecord(run["id"], last["generation"], summary=summary, state=state, finished=True),
            )


def _summary_of(stored: dict[str, Any]) -> dict[str, Any]:
    """A stored generation summary as the columns to insert again (``stats`` as ``extra``)."""
    keys = ("generation", "evaluations", "best_distance", "mean_distance", "front_size", "evaluation_seconds")
    return {
        **{k: stored[k] for k in keys},
        "created_at": stored["created_at"],
        "extra": dict(stored["stats"]),
    }


# -- 2. sizes --------------------------------------------------------------------------------


def table_bytes(conn: Connection) -> dict[str, int]:
    """Bytes of each table of ``ROW_KINDS`` with its indexes."""
    if conn.dialect.name == "postgresql":
        return {
            table: int(conn.execute(text("SELECT pg_total_relation_size(:t)"), {"t": table}).scalar())
            for table in ROW_KINDS
        }
    rows = conn.execute(
        text(
            "SELECT m.tbl_name AS owner, SUM(s.pgsize) AS size FROM dbstat AS s "
            "JOIN sqlite_master AS m ON m.name = s.name GROUP BY m.tbl_name"
        )
    )
    sizes = {row.owner: int(row.size) for row in rows}
    return {table: sizes.get(table, 0) for table in ROW_KINDS}


def row_counts(conn: Connection, run_id: int) -> dict[str, int]:
    """Rows per table of ``ROW_KINDS``, and the full run's own."""
    tables = {"individuals": IndividualRow, "evaluations": EvaluationRow,
              "population_members": PopulationMemberRow, "generations": GenerationRow}  # fmt: skip
    counts = {name: conn.execute(select(func.count()).select_from(model.__table__)).scalar_one()
              for name, model in tables.items()}  # fmt: skip
    counts["runs"] = conn.execute(select(func.count()).select_from(RunRow.__table__)).scalar_one()
    for name, model in tables.items():
        table = model.__table__
        counts[f"run:{name}"] = conn.execute(
            select(func.count()).select_from(table).where(table.c.run_id == run_id)
        ).scalar_one()
    return counts


def database_bytes(conn: Connection) -> int:
    """The whole database's bytes (SQLite: pages in use; PostgreSQL: ``pg_database_size``)."""
    if conn.dialect.name == "postgresql":
        return int(conn.execute(text("SELECT pg_database_size(current_database())")).scalar())
    pages = (
        conn.execute(text("PRAGMA page_count")).scalar()
        - conn.execute(text("PRAGMA freelist_count")).scalar()
    )
    return int(pages * conn.execute(text("PRAGMA page_size")).scalar())


def grid_generations() -> tuple[int, int]:
    """(runs, generations over all runs) of the paper grid."""
    grid = paper_grid("paper")
    return sum(t.repetitions for t in grid), sum(t.repetitions * t.generations for t in grid)


def sizes(engine: Engine, run_id: int) -> dict[str, Any]:
    """Bytes per row kind and the paper grid's extrapolated size (see ``print_sizes``)."""
    with engine.connect() as conn:
        if conn.dialect.name == "postgresql":
            conn.execute(text("ANALYZE"))
        tables, counts, total = table_bytes(conn), row_counts(conn, run_id), database_bytes(conn)
    per_row = {t: tables[t] / counts[t] if counts[t] else 0.0 for t in ROW_KINDS}
    run_generations = counts["run:generations"]
    runs, all_generations = grid_generations()
    grid = runs * per_row["runs"]
    for table in ("individuals", "evaluations", "population_members", "generations"):
        grid += per_row[table] * counts[f"run:{table}"] / run_generations * all_generations
    return {"tables": tables, "counts": counts, "per_row": per_row, "database": total,
            "grid_bytes": grid, "grid_runs": runs, "grid_generations": all_generations,
            "run_generations": run_generations}  # fmt: skip


# -- 3. queries ------------------------------------------------------------------------------


def timed(function: Callable[[], Any], repeats: int) -> tuple[float, Any]:
    """(median seconds over ``repeats`` calls, the last call's result)."""
    seconds, result = [], None
    for _ in range(repeats):
        start = time.perf_counter()
        result = function()
        seconds.append(time.perf_counter() - start)
    return statistics.median(seconds), result


def queries(
    engine: Engine, store: dict[str, Any], repeats: int, folder: Path
) -> list[tuple[str, float, str]]:
    """(name, median seconds, what came back) of each researcher's query."""
    run_id, experiment_id = store["run_id"], store["experiment_id"]
    with engine.connect() as conn:
        last = generations(conn, run_id)[-1]
        best = local_to_db_ids(conn, run_id, [last["stats"]["best_local_id"]])[last["stats"]["best_local_id"]]
    checks = {
        "lineage of the final best": (lambda: ancestors(engine, best), lambda r: f"{len(r)} ancestors"),
        "run tree, all pages (softevo phylogeny)": (
            lambda: _all_pages(engine, run_id),
            lambda r: f"{r} nodes",
        ),
        "run tree sample (dashboard)": (
            lambda: _on(engine, lambda conn: tree_sample(conn, run_id)),
            lambda r: f"{len(r['nodes'])} nodes",
        ),
        "exaptation": (
            lambda: _on(engine, lambda conn: exaptation(conn, run_id)),
            lambda r: (
                f"{r['founders_surviving']} of {r['founders']} founders survive, {r['lines_total']} lines"
            ),
        ),
        "export CSV of the run": (
            lambda: export_runs(engine, [run_id], folder / "export"),
            lambda r: f"{sum(p.stat().st_size for p in r) / 1e6:.0f} MB",
        ),
        "run list (180 runs)": (
            lambda: _on(engine, lambda conn: list_runs(conn, experiment_id=experiment_id)),
            lambda r: f"{len(r)} runs",
        ),
        "experiment status": (
            lambda: _on(engine, lambda conn: list_experiments(conn, experiment_id)),
            lambda r: f"{r[0]['runs_total']} runs",
        ),
        "report data load (load_experiment)": (
            lambda: load_experiment(engine, experiment_id),
            lambda r: f"{len(r.generations)} summaries, {len(r.evaluations)} evaluations",
        ),
    }
    results = []
    for name, (function, shown) in checks.items():
        seconds, result = timed(function, repeats)
        results.append((name, seconds, shown(result)))
        print(f"  {name:42s} {seconds:8.3f} s  {shown(result)}", flush=True)
    return results


def _on(engine: Engine, function: Callable[[Connection], Any]) -> Any:
    with engine.connect() as conn:
        return function(conn)


def _all_pages(engine: Engine, run_id: int) -> int:
    """Read the run's tree page by page as ``softevo phylogeny`` does; the nodes read."""
    rows, total, offset = 0, None, 0
    with engine.connect() as conn:
        while total is None or offset < total:
            total, page = run_phylogeny(conn, run_id, None, limit=PHYLOGENY_PAGE, offset=offset)
            rows += len(page)
            offset += PHYLOGENY_PAGE
    return rows


# -- 4. compression --------------------------------------------------------------------------


def compression(engine: Engine, run_id: int, sample: int = 5000) -> dict[str, dict[str, float]]:
    """Mean bytes per value of the genome, phenotype and algorithm state JSON as stored, with
    compact separators, and zlib-compressed (level 6) of each: over ``sample`` individuals
    spread through the run."""
    individuals, runs = IndividualRow.__table__, RunRow.__table__
    with engine.connect() as conn:
        count = conn.execute(select(func.count()).where(individuals.c.run_id == run_id)).scalar_one()
        step = max(1, count // sample)
        rows = conn.execute(
            select(individuals.c.genome, individuals.c.phenotype)
            .where(individuals.c.run_id == run_id, individuals.c.id % step == 0)
        ).all()  # fmt: skip
        state = conn.execute(select(runs.c.algorithm_state).where(runs.c.id == run_id)).scalar_one()
    values = {"genome": [r.genome for r in rows], "phenotype": [r.phenotype for r in rows], "state": [state]}
    return {name: _encodings(items) for name, items in values.items()}


def _encodings(items: list[Any]) -> dict[str, float]:
    stored = [json.dumps(item).encode() for item in items]  # what SQLAlchemy's JSON type writes
    compact = [json.dumps(item, separators=(",", ":")).encode() for item in items]
    mean = lambda values: float(np.mean([len(v) for v in values]))  # noqa: E731
    return {
        "stored": mean(stored),
        "compact": mean(compact),
        "zlib": mean([zlib.compress(v, 6) for v in stored]),
        "compact+zlib": mean([zlib.compress(v, 6) for v in compact]),
    }


# -- output ----------------------------------------------------------------------------------


def print_sizes(size: dict[str, Any]) -> None:
    print("\nbytes per row (table and its indexes / rows; whole database "
          f"{size['database'] / 1e6:.1f} MB)")  # fmt: skip
    print(f"  {'row':24s} {'rows':>10s} {'table MB':>10s} {'bytes/row':>10s} {'per generation':>15s}")
    for table, kind in ROW_KINDS.items():
        rows, run_rows = size["counts"][table], size["counts"].get(f"run:{table}")
        per_generation = f"{run_rows / size['run_generations']:.2f}" if run_rows is not None else "-"
        print(f"  {kind:24s} {rows:10d} {size['tables'][table] / 1e6:10.2f} "
              f"{size['per_row'][table]:10.0f} {per_generation:>15s}")  # fmt: skip
    print(f"\npaper grid: {size['grid_runs']} runs, {size['grid_generations']} generations: "
          f"about {size['grid_bytes'] / 1e9:.1f} GB")  # fmt: skip


def print_compression(saved: dict[str, dict[str, float]]) -> None:
    print("\nJSON bytes per value (mean): as stored, compact separators, zlib level 6")
    print(f"  {'column':12s} {'stored':>9s} {'compact':>9s} {'zlib':>9s} {'compact+zlib':>13s} {'ratio':>7s}")
    for name, row in saved.items():
        print(f"  {name:12s} {row['stored']:9.0f} {row['compact']:9.0f} {row['zlib']:9.0f} "
              f"{row['compact+zlib']:13.0f} {row['stored'] / row['zlib']:6.2f}x")  # fmt: skip


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--db", help="database URL (default: a new SQLite file in a temporary folder)")
    parser.add_argument(
        "--generations", type=int, default=PAPER_LONGEST, help="generations of the longest runs"
    )
    parser.add_argument("--population", type=int, default=30)
    parser.add_argument("--evolved", type=int, default=300, help="generations through the real algorithm")
    parser.add_argument("--repeats", type=int, default=3, help="timings per query (the median is shown)")
    parser.add_argument("--seed", type=int, default=0, help="seed of the synthesised generations")
    args = parser.parse_args()
    folder = Path(tempfile.mkdtemp(prefix="softevo-storage-"))
    engine = open_database(args.db or f"sqlite:///{folder / 'storage.db'}")
    print(f"database {engine.url.render_as_string(hide_password=True)}; "
          f"{os.cpu_count()} cores, load average {os.getloadavg()[0]:.2f}")  # fmt: skip
    store = build_store(engine, args)
    print(f"stored: run {store['run_id']} in full ({args.population} x {args.generations}, "
          f"{min(args.evolved, args.generations)} evolved) in {store['full_seconds']:.0f} s, "
          f"with the index of {len(store['run_ids'])} runs in {store['seconds']:.0f} s")  # fmt: skip
    print_sizes(sizes(engine, store["run_id"]))
    print(f"\nqueries (median of {args.repeats}; load average {os.getloadavg()[0]:.2f})")
    queries(engine, store, args.repeats, folder)
    print_compression(compression(engine, store["run_id"]))
    engine.dispose()


if __name__ == "__main__":
    main()
