"""One row per run: the primary measure and what it rests on (``summary.csv`` of the report).

The primary measure (issue 46, as the paper): each run's best distance in its final
generation. Beside it, per run (``run_summary``):

- ``final_generation`` (the run's last stored generation) and ``world_final``, the world
  it was evaluated in then; ``world_generation0`` likewise at generation 0;
- ``best_distance_final``, ``best_distance_generation0`` (voxel lengths) and ``gain`` =
  final - generation 0, left empty when the two generations are in different worlds (a
  transition: distances of two worlds are not compared); ``start_final_world`` is the first
  generation wholly in the final world (0, or a transition's arrival) and
  ``gain_final_world`` the best distance gained since then;
- ``frequency_final`` and ``frequency_generation0``: the mean actuation frequency (Hz) over
  the run's population at those generations;
- for the best robot of the final population (the member with the largest distance):
  ``best_frequency`` (Hz), ``seconds`` (its evaluation's length after settling:
  ``evaluation_seconds``), ``cycles_run`` (seconds x frequency), ``capped`` (whether the
  treatment's cap on seconds cut its cycles), ``distance_per_cycle`` and
  ``distance_per_second``. Per cycle and per second read differently when frequencies
  differ: a robot at 8 Hz covers per second 8 times what it covers per cycle.
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd

from softevo.analysis.data import ExperimentData
from softevo.analysis.matching import arrival_generation

SUMMARY_COLUMNS = [
    "treatment", "run_id", "repetition", "seed", "status", "final_generation", "world_final",
    "world_generation0", "best_distance_final", "best_distance_generation0", "gain",
    "start_final_world", "gain_final_world", "frequency_final", "frequency_generation0",
    "best_frequency", "seconds", "cycles_run", "capped", "distance_per_cycle",
    "distance_per_second",
]  # fmt: skip


def evaluation_seconds(frequency, cycles: float, max_seconds: float | None) -> np.ndarray:
    """Seconds an evaluation runs after settling: ``cycles`` / |frequency|, at most
    ``max_seconds`` where the treatment caps it (NaN for a frequency of 0 or unknown)."""
    frequency = np.abs(np.asarray(frequency, float))
    with np.errstate(divide="ignore", invalid="ignore"):
        seconds = np.where(frequency > 0, cycles / frequency, np.nan)
    if max_seconds is not None and not pd.isna(max_seconds):
        seconds = np.minimum(seconds, float(max_seconds))
    return seconds


def capped(frequency, cycles: float, max_seconds: float | None) -> np.ndarray:
    """Whether the cap on seconds cut an evaluation short: cycles / |frequency| >
    max_seconds (False without a cap)."""
    frequency = np.abs(np.asarray(frequency, float))
    if max_seconds is None or pd.isna(max_seconds):
        return np.zeros(frequency.shape, bool)
    return frequency * float(max_seconds) < cycles


def best_distance_at(data: ExperimentData, generation: int) -> pd.Series:
    """Each run's best distance at ``generation`` (the generation summary), by run_id."""
    rows = data.generations[data.generations["generation"] == generation]
    return rows.set_index("run_id")["best_distance"]


def _population_frequency(data: ExperimentData, run_id: int, generation: int) -> float:
    members = data.populations
    chosen = members[(members["run_id"] == run_id) & (members["generation"] == generation)]
    return float(chosen["frequency"].abs().mean()) if len(chosen) else math.nan


def _best_member(data: ExperimentData, run_id: int, generation: int) -> pd.Series | None:
    members = data.populations
    chosen = members[(members["run_id"] == run_id) & (members["generation"] == generation)]
    chosen = chosen.dropna(subset=["distance"])
    return None if chosen.empty else chosen.loc[chosen["distance"].idxmax()]


def _world_at(data: ExperimentData, run_id: int, generation: int) -> str | None:
    summary = data.generations
    rows = summary[(summary["run_id"] == run_id) & (summary["generation"] == generation)]
    return None if rows.empty else str(rows["environment"].iloc[0])


def run_row(data: ExperimentData, run: pd.Series, treatment: pd.Series) -> dict:
    """The summary row (``SUMMARY_COLUMNS``) of one run (a row of ``data.runs``) of
    ``treatment`` (its row of ``data.treatments``)."""
    run_id, final = int(run["run_id"]), int(run["generation"])
    start = arrival_generation(treatment)
    best = {g: best_distance_at(data, g).get(run_id, math.nan) for g in {0, start, final}}
    world_final, world_0 = _world_at(data, run_id, final), _world_at(data, run_id, 0)
    member = _best_member(data, run_id, final)
    frequency = abs(float(member["frequency"])) if member is not None else math.nan
    cycles, cap = float(treatment["cycles"]), treatment.get("max_seconds")
    seconds = float(evaluation_seconds(frequency, cycles, cap))
    distance = float(member["distance"]) if member is not None else math.nan
    return {
        "treatment": run["treatment"], "run_id": run_id, "repetition": int(run["repetition"]),
        "seed": run.get("seed"), "status": run.get("status"), "final_generation": final,
        "world_final": world_final, "world_generation0": world_0,
        "best_distance_final": best[final], "best_distance_generation0": best[0],
        "gain": best[final] - best[0] if world_final == world_0 else math.nan,
        "start_final_world": start,
        "gain_final_world": best[final] - best[start] if final >= start else math.nan,
        "frequency_final": _population_frequency(data, run_id, final),
        "frequency_generation0": _population_frequency(data, run_id, 0),
        "best_frequency": frequency, "seconds": seconds, "cycles_run": seconds * frequency,
        "capped": bool(capped(frequency, cycles, cap)) if math.isfinite(frequency) else None,
        "distance_per_cycle": distance / (seconds * frequency) if seconds * frequency > 0 else math.nan,
        "distance_per_second": distance / seconds if seconds > 0 else math.nan,
    }  # fmt: skip


def run_summary(data: ExperimentData) -> pd.DataFrame:
    """One row per run that stored a generation, in treatment then run order (module doc)."""
    treatments = data.treatments.set_index("name", drop=False)
    rows = [
        run_row(data, run, treatments.loc[run["treatment"]])
        for name in data.treatment_names
        for _, run in data.runs[data.runs["treatment"] == name].sort_values("run_id").iterrows()
        if run["generation"] >= 0
    ]
    return pd.DataFrame(rows, columns=SUMMARY_COLUMNS)
