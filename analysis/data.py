"""An experiment as pandas DataFrames, the input of every analysis.

``ExperimentData`` holds, for all runs of one experiment (``service.storage.experiments.
load_experiment(engine, id)`` reads it from the database; ``experiment_data`` assembles it
from the frames read):

- ``treatments``: one row per treatment in creation order (name, environment, stiffness_mpa,
  switch_at (first generation in the second environment, or <NA>), population,
  generations, workspace, cycles, repetitions, seed, algorithm);
- ``runs``: the export's runs table plus ``generation`` (the last one stored);
- ``generations``: per run and generation, the stored summary (environment, best_distance,
  mean_distance, front_size, evaluations, evaluation_seconds, created_at);
- ``populations``: the populations kept at generation 0, at each run's last stored
  generation and at every generation an analysis compares or shows
  (``analysis.matching.analysis_generations``; the loader reads any others asked for)
  (run_id, generation, individual_id, front_rank), each member with the traits of its
  latest evaluation at or before that generation (after an environment switch: the one in
  the new environment);
- ``evaluations``: every evaluation of those members (``service.storage.export.individual_columns``) with
  ``treatment`` and ``repetition``.

Only those generations' populations are read: a paper-scale experiment stores tens of
millions of evaluations, and the analyses need the per-generation summaries and the
populations at a few generations.

Comparisons are made at matched generations (``analysis.matching``): ``run_values(g)`` gives
one value per run at generation ``g`` (the unit of every statistic), ``display_populations``
the members each treatment is shown with.

Trait columns are ``evolution.traits.names()``: distance (voxel lengths), active_share, voxel_count,
frequency (Hz), branching, shape_entropy (bits), symmetry.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import pandas as pd

from softevo.analysis import matching
from softevo.evolution import traits


@dataclass(frozen=True)
class ExperimentData:
    """Everything the analyses need about one experiment (see the module doc)."""

    experiment: dict[str, Any]
    treatments: pd.DataFrame
    runs: pd.DataFrame
    evaluations: pd.DataFrame
    generations: pd.DataFrame
    populations: pd.DataFrame

    @property
    def treatment_names(self) -> list[str]:
        """Treatment names in creation order."""
        return list(self.treatments["name"])

    def final_populations(self) -> pd.DataFrame:
        """Members of each run's population at its last stored generation."""
        last = self.populations["run_id"].map(self.runs.set_index("run_id")["generation"])
        return self.populations[self.populations["generation"] == last].reset_index(drop=True)

    def initial_populations(self) -> pd.DataFrame:
        """Members of each run's population at generation 0."""
        return self.populations_at(0)

    def populations_at(self, generation: int) -> pd.DataFrame:
        """Members of the populations kept at ``generation`` (runs that stored it)."""
        return self.populations[self.populations["generation"] == generation].reset_index(drop=True)

    def run_values(self, generation: int) -> pd.DataFrame:
        """One row per run that stored ``generation``: run_id, treatment, repetition,
        generation, ``best_distance`` (its population's best, from the generation summary)
        and each trait's mean over its population then (``evolution.traits.names()``)."""
        summary = self.generations[self.generations["generation"] == generation]
        rows = summary[["run_id", "treatment", "repetition", "generation", "best_distance"]]
        members = self.populations_at(generation)
        means = members.groupby("run_id")[list(traits.names())].mean().reset_index()
        merged = rows.merge(means, on="run_id", how="left")
        return merged.sort_values("run_id", kind="stable").reset_index(drop=True)

    # ---- matched generations (analysis.matching) --------------------------------------------
    @property
    def static_generation(self) -> int | None:
        """The generation the static treatments are compared at."""
        return matching.static_generation(self.treatments, self.runs)

    def pair_generation(self, a: str, b: str) -> int | None:
        """The generation treatments ``a`` and ``b`` are compared at."""
        return matching.pair_generation(self.treatments, self.runs, a, b)

    def end_generation(self, name: str) -> int | None:
        """The last generation every started run of treatment ``name`` has stored."""
        return matching.end_generation(self.runs, name)

    def display_generation(self, name: str) -> int | None:
        """The generation treatment ``name`` is shown at."""
        return matching.display_generation(self.treatments, self.runs, name)

    @property
    def left_out_note(self) -> str | None:
        """Which runs stopped before their treatment's compared generation and are left out
        of the summary and the tests (``analysis.matching.left_out_note``), or None."""
        return matching.left_out_note(self.treatments, self.runs)

    def _per_treatment(self, frame_at) -> pd.DataFrame:
        parts = []
        for name in self.treatment_names:
            generation = self.display_generation(name)
            if generation is not None:
                frame = frame_at(generation)
                parts.append(frame[frame["treatment"] == name])
        if not parts:
            return frame_at(-1)
        return pd.concat(parts, ignore_index=True)

    def display_populations(self) -> pd.DataFrame:
        """Each treatment's members at its display generation."""
        return self._per_treatment(self.populations_at)

    def display_run_values(self) -> pd.DataFrame:
        """Each treatment's ``run_values`` at its display generation."""
        return self._per_treatment(self.run_values)


def experiment_data(
    experiment: dict[str, Any],
    treatments: pd.DataFrame,
    runs: pd.DataFrame,
    generations: pd.DataFrame,
    members: pd.DataFrame,
    evaluations: pd.DataFrame,
) -> ExperimentData:
    """An ``ExperimentData`` from the frames as read: ``runs`` with run_id, treatment and
    repetition; ``members`` the end populations (run_id, generation, individual_id,
    front_rank); ``evaluations`` every evaluation of those members (one row per evaluation).
    Adds the treatment and repetition labels and each member's traits."""
    labels = runs[["run_id", "treatment", "repetition"]]
    evaluations = evaluations.merge(labels, on="run_id", how="left")
    generations = generations.merge(labels, on="run_id", how="left")
    populations = member_traits(members, evaluations).merge(labels, on="run_id", how="left")
    return ExperimentData(experiment, treatments, runs, evaluations, generations, populations)


def member_traits(members: pd.DataFrame, evaluations: pd.DataFrame) -> pd.DataFrame:
    """Members with the traits of their latest evaluation at or before the member's
    generation (``evaluation_generation``, ``environment``, ``stable``, every trait, and
    ``objectives``, {name: value}, where the evaluations have it)."""
    extra = ["objectives"] if "objectives" in evaluations.columns else []
    latest = evaluations[["individual_id", "generation", "environment", "stable", *traits.names(), *extra]]
    latest = latest.rename(columns={"generation": "evaluation_generation"})
    if members.empty:  # nothing stored yet: merge_asof cannot type empty keys
        return pd.DataFrame(columns=[*members.columns, *latest.columns.drop("individual_id")])
    left = members.sort_values("generation", kind="stable").reset_index(drop=True)
    right = latest.sort_values("evaluation_generation", kind="stable").reset_index(drop=True)
    merged = pd.merge_asof(
        left,
        right,
        left_on="generation",
        right_on="evaluation_generation",
        by="individual_id",
        direction="backward",
    )
    return merged.sort_values(["run_id", "generation", "front_rank", "individual_id"]).reset_index(drop=True)
