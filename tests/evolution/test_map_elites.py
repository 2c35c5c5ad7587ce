"""MAP-Elites (``evolution.algorithm.MAP_ELITES``): its insertion rule is pyribs' own
``GridArchive``'s and ``evolution.archive.elites``' on the same inputs; a run's archive after
each generation is the replay of its evaluations (``archive.current``), whatever its worlds;
the same seed gives the same archive, and a run continued from its JSON state equals one that
never stopped; the treatment options that make its grid give one clear line when wrong."""

from __future__ import annotations

import math

import numpy as np
import pytest
from ribs.archives import GridArchive

import softevo
from softevo.errors import UserError
from softevo.evolution import Evolution, algorithm, archive, options, traits
from softevo.evolution.archive import EPSILON, Candidate, Grid, current, elites, grid_of
from softevo.evolution.operators import Candidates, archive_survival, uniform_mutants
from softevo.evolution.runner import ask_generation, tell_generation
from softevo.evolution.schedule import Schedule
from softevo.evolution.selection import PAPER_OBJECTIVES
from softevo.evolution.treatments import Treatment
from tests.evolution.test_afpo import config, evaluations

GRID = Grid(("frequency", "branching"), ((0.0, 5.0), (0.0, 1.0)), (6, 6))
GRIDS = [
    GRID,
    Grid(("voxel_count",), ((1.0, 64.0),), (7,)),
    Grid(("a", "b", "c"), ((-1.0, 1.0), (0.0, 0.3), (2.0, 2.5)), (3, 1, 5)),
]


def random_candidates(grid: Grid, n: int, seed: int) -> list[Candidate]:
    """Candidates crowding few cells: distances from a handful of values (ties), measures
    often outside the bounds, on a cell edge, or missing, and a few distances not finite."""
    rng = np.random.default_rng(seed)
    out = []
    for k in range(n):
        values = {}
        for name, (low, high), count in zip(grid.measures, grid.bounds, grid.cells, strict=True):
            kind = rng.integers(6)
            width = high - low
            if kind == 0:  # exactly on an edge between cells
                values[name] = low + width * rng.integers(count + 1) / count
            elif kind == 1:  # beyond the bounds, on either side
                beyond = rng.uniform(0, 3 * width)
                values[name] = float(rng.choice([low - beyond, high + beyond]))
            else:
                values[name] = float(rng.uniform(low, high))
        if rng.random() < 0.05:
            values[grid.measures[0]] = None if rng.random() < 0.5 else math.nan
        distance = float(rng.integers(4)) * 0.5
        if rng.random() < 0.03:
            distance = math.nan
        out.append(Candidate(k, distance, values, generation=k // 10))
    return out


def pyribs_archive(grid: Grid, candidates: list[Candidate]) -> dict[int, tuple[int, float]]:
    """{flat index: (individual, distance)} of a pyribs ``GridArchive`` fed the candidates in
    order, one ``add_single`` each (skipping those ``elites`` skips: pyribs refuses NaN)."""
    ribs = GridArchive(solution_dim=1, dims=grid.cells, ranges=grid.bounds, epsilon=EPSILON)
    for c in candidates:
        values = [c.measures[name] for name in grid.measures]
        if not math.isfinite(c.distance) or any(v is None or not math.isfinite(v) for v in values):
            continue
        ribs.add_single([c.individual], c.distance, values)
    data = ribs.data()
    return {int(index): (int(solution[0]), float(objective))
            for index, solution, objective in zip(data["index"], data["solution"], data["objective"],
                                                  strict=True)}


@pytest.mark.parametrize("seed", range(6))
@pytest.mark.parametrize("grid", GRIDS, ids=lambda g: "x".join(map(str, g.cells)))
def test_the_insertion_rule_is_pyribs_own(grid, seed):
    candidates = random_candidates(grid, 300, seed)
    ours = elites(grid, candidates)
    theirs = pyribs_archive(grid, candidates)
    assert {grid.index(cell): (e.individual, e.distance) for cell, e in ours.items()} == theirs
    # the cell rule alone: pyribs' index of every finite point is ours
    ribs = GridArchive(solution_dim=1, dims=grid.cells, ranges=grid.bounds, epsilon=EPSILON)
    for c in candidates:
        cell = grid.cell_of(c.measures)
        if cell is not None:
            assert grid.index(cell) == int(ribs.index_of_single([c.measures[n] for n in grid.measures]))
    # and the survival the algorithm runs keeps exactly the elites' rows
    measures = np.array([[np.nan if c.measures[n] is None else c.measures[n] for n in grid.measures]
                         for c in candidates])
    F = np.array([[-c.distance] for c in candidates])
    rows = Candidates(F, PAPER_OBJECTIVES[:1], np.zeros(len(candidates), int), np.ones(len(candidates), bool),
                      measures, grid)
    kept = archive_survival(rows, 4, np.random.default_rng(0))
    assert kept.tolist() == sorted(e.individual for e in ours.values())


def test_ties_keep_the_earlier_and_far_values_take_the_edge_cells():
    far = [Candidate(0, 1.0, {"frequency": -1e12, "branching": 0.5}),
           Candidate(1, 1.0, {"frequency": -7.0, "branching": 0.5}),  # same cell, a tie
           Candidate(2, 2.0, {"frequency": 1e12, "branching": 1e9}),
           Candidate(3, 2.0, {"frequency": 5.0, "branching": 1.0})]  # the top edge: a tie again
    kept = elites(GRID, far)
    assert {cell: e.individual for cell, e in kept.items()} == {(0, 3): 0, (5, 5): 2}
    rows = Candidates(np.array([[-c.distance] for c in far]), PAPER_OBJECTIVES[:1], np.zeros(4, int),
                      np.ones(4, bool), np.array([[c.measures[n] for n in GRID.measures] for c in far]), GRID)
    assert archive_survival(rows, 4, np.random.default_rng(0)).tolist() == [0, 2]


def test_uniform_mutants_draw_parents_with_the_runs_generator():
    algo = Evolution(config(mode="map-elites", grid=GRID, seed=4, population_size=5))
    algo.tell(evaluations(algo, algo.ask()))
    parents = list(algo.population)
    expected = np.random.Generator(type(algo.rng.bit_generator)())
    expected.bit_generator.state = algo.rng.bit_generator.state
    picks = expected.integers(len(parents), size=5)
    children = uniform_mutants(algo, parents)
    assert [child.parent_id for child in children] == [parents[k].id for k in picks]
    assert len(uniform_mutants(algo, [])) == 5  # an empty archive: newcomers
    assert all(child.parent_id is None for child in uniform_mutants(algo, []))


def run_generations(algo: Evolution, schedule: Schedule, generations: range):
    """Run ``algo`` through ``generations``; return every evaluation as a ``Candidate`` (in the
    order the generation evaluated them), each generation's world and its population's ids."""
    candidates, worlds, populations = [], {}, {}
    for generation in generations:
        asked = ask_generation(algo, schedule, generation)
        evaluated = list(algo.pending)
        tell_generation(algo, asked, evaluations(algo, asked))
        for ind in evaluated:
            values = ind.trait_values(algo.config.encoding)
            candidates.append(Candidate(ind.id, ind.objectives["distance"], values, generation))
        worlds[generation] = algo.environment
        populations[generation] = sorted(ind.id for ind in algo.population)
    return candidates, worlds, populations


SCHEDULES = {
    "land": Schedule.static("land"),
    "land-water": Schedule([("land", 0), ("water", 2)]),
    "gradual": Schedule([("land", 0), ("water", 2)], spans=[0, 2]),
}


@pytest.mark.parametrize("name", list(SCHEDULES))
def test_the_population_is_the_replay_of_the_evaluations(name):
    algo = Evolution(config(mode="map-elites", grid=GRID, seed=7, population_size=5))
    candidates, worlds, populations = run_generations(algo, SCHEDULES[name], range(6))
    filled = []
    for generation, population in populations.items():
        replay = elites(GRID, current(candidates, worlds, generation))
        assert population == sorted(e.individual for e in replay.values())
        filled.append(len(replay))
    assert max(filled) > 5  # more elites than the batch: the archive is the population
    if name != "land":
        assert len(set(worlds.values())) > 1


def archive_of(seed: int, schedule: Schedule = SCHEDULES["land"]) -> list[tuple]:
    algo = Evolution(config(mode="map-elites", grid=GRID, seed=seed, population_size=5))
    candidates, worlds, _ = run_generations(algo, schedule, range(4))
    replay = elites(GRID, current(candidates, worlds, 3))
    return sorted((cell, e.individual, e.distance) for cell, e in replay.items())


def test_the_same_seed_gives_the_same_archive():
    assert archive_of(3) == archive_of(3)
    assert archive_of(3) != archive_of(4)


def test_a_run_continued_from_its_state_equals_one_that_never_stopped():
    schedule = SCHEDULES["gradual"]
    whole = Evolution(config(mode="map-elites", grid=GRID, seed=9, population_size=5))
    run_generations(whole, schedule, range(5))
    first = Evolution(config(mode="map-elites", grid=GRID, seed=9, population_size=5))
    run_generations(first, schedule, range(2))
    state = first.state_to_json()
    assert '"grid"' in state
    resumed = Evolution.from_state_json(state)
    assert resumed.config == first.config and resumed.config.grid == GRID
    run_generations(resumed, schedule, range(2, 5))
    assert resumed.state_to_dict() == whole.state_to_dict()


def test_map_elites_is_one_registration_with_an_archive():
    record = algorithm.get("map-elites")
    assert record.archive and record.variations == (uniform_mutants,) and record.survival is archive_survival
    assert [a.name for a in algorithm.ALGORITHMS.records() if a.archive] == ["map-elites"]
    with pytest.raises(ValueError, match="needs a grid"):
        config(mode="map-elites")
    with pytest.raises(ValueError, match="takes no grid"):
        config(mode="afpo", grid=GRID)
    other = config(mode="afpo")
    assert "grid" not in other.to_dict()  # the stored state of other algorithms is as before


def test_trait_bounds():
    assert traits.get("frequency").bounds == (0.0, 5.0)
    assert traits.get("branching").bounds == traits.get("symmetry").bounds == (0.0, 1.0)
    assert traits.get("shape_entropy").bounds == (0.0, math.log2(10))
    assert traits.get("voxel_count").bounds is None and traits.get("distance").bounds is None
    height = traits.Trait("height_me", "height (voxels)", lambda p: float(p.body.any((0, 1)).sum()),
                          bounds=(0.0, 8.0))
    traits.register(height)
    try:
        treatment = Treatment("land", 1.0, algorithm="map-elites", measures=("height_me", "voxel_count"),
                              cells=(4, 3), workspace=(4, 4, 4))
        assert grid_of(treatment) == Grid(("height_me", "voxel_count"), ((0.0, 8.0), (1.0, 64.0)), (4, 3))
        algo = Evolution(treatment.evolution_config(0))
        algo.tell(evaluations(algo, algo.ask()))
        for ind in algo.population:  # the registered trait is measured before selection
            assert ind.trait_values(algo.config.encoding, ("height_me",))["height_me"] is not None
    finally:
        traits.unregister("height_me")
    with pytest.raises(ValueError, match="bounds must be two finite numbers"):
        traits.register(traits.Trait("wide_me", "w", lambda p: 1.0, bounds=(1.0, 1.0)))


def test_the_grid_options():
    treatment = Treatment("land", 1.0, algorithm="map-elites", measures=("frequency", "shape_entropy"),
                          cells=(5, 4), measure_bounds=(0, 8, 0.5, 2.5))
    assert treatment.grid() == Grid(("frequency", "shape_entropy"), ((0.0, 8.0), (0.5, 2.5)), (5, 4))
    assert treatment.evolution_config(1).grid == treatment.grid()
    settings = treatment.to_settings()
    assert settings["measures"] == ["frequency", "shape_entropy"] and settings["cells"] == [5, 4]
    assert settings["measure_bounds"] == [0, 8, 0.5, 2.5]
    assert Treatment.from_settings(settings) == treatment
    # settings stored before the options existed read as the defaults
    old = {k: v for k, v in Treatment("land", 1.0).to_settings().items()
           if k not in ("measures", "cells", "measure_bounds")}
    assert Treatment.from_settings(old).cells == (6, 6) and Treatment.from_settings(old).grid() is None
    assert Treatment("land", 1.0, algorithm="map-elites").grid() == GRID
    assert options.option("measure_bounds").parse("0,8,0,1") == (0.0, 8.0, 0.0, 1.0)
    assert archive.MAX_CELLS == 10_000


@pytest.mark.parametrize(("changes", "message"), [
    ({"measures": ("frequency", "nope")}, "measures: nope is no registered trait; choose among distance"),
    ({"cells": (6,)}, "cells: one count per measure (2: frequency, branching; got 1)"),
    ({"cells": (6, 0)}, "cells must be at most 6 integers within 1..10,000 (got 6,0)"),
    ({"measures": ("distance", "branching")}, "measure distance has no bounds of its own"),
    ({"measure_bounds": (0, 1, 2)}, "measure_bounds: low,high for each of the 2 measures (4 numbers"),
    ({"measure_bounds": (0, 1, 2, 2)}, "measure_bounds of branching must be finite with low < high"),
    ({"cells": (200, 200)}, "cells: at most 10,000 in all (got 200x200 = 40,000)"),
    ({"measures": ("branching", "branching")}, "measures: each trait once"),
    ({"algorithm": "afpo", "cells": (3, 3)}, "cells: only an algorithm with an archive takes a grid"),
])
def test_a_wrong_grid_is_one_line(changes, message):
    with pytest.raises(UserError) as caught:
        Treatment("land", 1.0, **{"algorithm": "map-elites", **changes})
    assert str(caught.value).startswith(message) and "\n" not in str(caught.value)


def test_softevo_evolve_runs_map_elites():
    local = softevo.evolve("land", 1.0, population=3, generations=3, workspace=(3, 3, 3), cycles=1, seed=2,
                           algorithm="map-elites", measures=("frequency", "voxel_count"), cells=(3, 9))
    config = local.evolution.config
    assert config.mode == "map-elites" and config.grid == Grid(("frequency", "voxel_count"),
                                                                ((0.0, 5.0), (1.0, 27.0)), (3, 9))
    assert local.evolution.next_id == 3 * 3  # a batch of the population size each generation
    with pytest.raises(UserError, match="cells: one count per measure"):
        softevo.evolve("land", 1.0, algorithm="map-elites", cells=(4,))
