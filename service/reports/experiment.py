"""An experiment's treatments side by side, as JSON for the dashboard's experiment page
(``GET /experiments/{id}/analysis``): what the report's figures and tables show, computed
by the same ``analysis`` functions on the same ``ExperimentData``.

- ``treatments``: each treatment's settings, the generation it is shown at
  (``analysis.matching``), its best distance there (mean and t interval over runs,
  ``analysis.stats_tables.ci_table``) and every run (id, repetition, seed, status);
- ``curves``: best distance per generation, mean over runs with its 95% t interval
  (``analysis.stats_tables.fitness_curves``, one value per run per generation, thinned to
  about 500 generations);
- ``qd``: per treatment and metric (QD score, coverage), the mean over its runs of their
  MAP-Elites archives after each generation with its 95% t interval (``analysis.qd.qd_curves``
  over ``service.reports.report.qd_data``: each run's archive of the world it evaluated then);
- ``fronts``: the display populations of all runs pooled in the distance / active share
  (energy) plane and their non-dominated front (``analysis.figures.pareto_front``), as in
  the paper's figures 8, 13, 18 and 20; at most ``MAX_POINTS`` points per treatment (an
  even sample; the front is always whole);
- ``descriptors``: one value per run (its population's mean of the trait, or its best
  distance) per treatment at its display generation (``ExperimentData.display_run_values``);
- ``findings``: the findings, one test each, with their verdicts (``analysis.findings.
  findings_table``'s columns; power, detectable A12 and runs needed are null here: they
  take seconds to simulate, and the report has them);
- ``statistics``: every row of ``analysis.stats_tables.statistics_table`` (family, test, p,
  Bonferroni-adjusted p, A12, difference with its interval), the secondary pairwise tests;
- ``left_out``: one sentence naming the runs that stopped before the generation their
  treatment is compared at (cancelled, failed) and are left out, or null
  (``analysis.matching.left_out_note``).

Floats that are not finite become null. ``analysis_json(db, id)`` is what the API runs in its
background process (``service.api.expensive``).
"""

from __future__ import annotations

import json
from typing import Any

import numpy as np
import pandas as pd
from sqlalchemy import Engine

from softevo.analysis.data import ExperimentData
from softevo.analysis.figures import pareto_front, treatment_colors
from softevo.analysis.findings import FINDING_COLUMNS, findings_table
from softevo.analysis.qd import METRICS as QD_METRICS
from softevo.analysis.qd import qd_curves
from softevo.analysis.stats_tables import INTERVAL, ci_table, fitness_curves, metric_labels, statistics_table
from softevo.evolution import traits
from softevo.service.reports.data import load_experiment
from softevo.service.reports.report import engine_of, qd_data
from softevo.service.storage.rows import finite

MAX_POINTS = 2000  # population members drawn per treatment's front panel
POINT_COLUMNS = ("individual_id", "run_id", "distance", "active_share", "voxel_count")
STAT_FIELDS = (
    "comparison", "family", "family_size", "test", "metric", "a", "b", "generation", "start_generation",
    "n_a", "n_b",
    "mean_a", "mean_b", "median_a", "median_b", "p", "p_bonferroni", "significance", "A12",
    "detectable_A12", "difference", "difference_low", "difference_high", "interval",
)  # fmt: skip


def experiment_analysis(source: str | Engine, experiment_id: int) -> dict[str, Any]:
    """The page's data for experiment ``experiment_id`` (see the module doc); UserError if
    there is no such experiment or it has no runs."""
    engine = engine_of(source)
    data = load_experiment(engine, experiment_id)
    experiment = data.experiment
    return finite(
        {
            "experiment": {"id": int(experiment["id"]), "name": experiment["name"]},
            "interval": INTERVAL,
            "treatments": treatments(data),
            "curves": curves(data),
            "qd": qd(data, qd_curves(data, qd_data(engine, data))),
            "fronts": fronts(data),
            "descriptors": descriptors(data),
            "findings": _records(findings_table(data, design_figures=False), FINDING_COLUMNS),
            "statistics": statistics(data),
            "left_out": data.left_out_note,  # runs that stopped early and are left out, or null
        }
    )


def analysis_json(db: str, experiment_id: int) -> bytes:
    """``experiment_analysis`` as JSON bytes (what the API caches and sends)."""
    return json.dumps(experiment_analysis(db, experiment_id), separators=(",", ":")).encode()


def _records(frame: pd.DataFrame, columns) -> list[dict[str, Any]]:
    """Rows of ``frame`` as plain Python dicts (NumPy and pandas scalars converted)."""
    return json.loads(frame[list(columns)].to_json(orient="records"))


def _columns(frame: pd.DataFrame, columns) -> dict[str, list]:
    """``frame``'s ``columns`` as lists (plain Python values, missing ones None)."""
    return {column: json.loads(frame[column].to_json(orient="values")) for column in columns}


def _hex(rgba) -> str:
    return "#" + "".join(f"{round(channel * 255):02x}" for channel in rgba[:3])


def treatments(data: ExperimentData) -> list[dict[str, Any]]:
    """Per treatment, in creation order: its settings, colour, display generation, best
    distance there (mean, low, high over runs) and its runs."""
    colors = treatment_colors(data.treatments)
    best = ci_table(data.display_run_values(), "best_distance", "treatment").set_index("treatment")
    runs = data.runs.sort_values("run_id")
    found = []
    for row in data.treatments.itertuples(index=False):
        shown = best.loc[row.name] if row.name in best.index else None
        generation = data.display_generation(row.name)
        found.append(
            {
                "name": row.name,
                "environment": row.environment,
                "schedule": row.schedule,
                "stiffness_mpa": float(row.stiffness_mpa),
                "model": str(row.model),
                "switch_at": None if pd.isna(row.switch_at) else int(row.switch_at),
                "generations": int(row.generations),
                "population": int(row.population),
                "color": _hex(colors[row.name]),
                "display_generation": generation,
                "best_distance": {
                    key: (None if shown is None else float(shown[key])) for key in ("mean", "low", "high")
                }
                | {"n": 0 if shown is None else int(shown["n"])},
                "runs": _records(
                    runs[runs["treatment"] == row.name],
                    ("run_id", "repetition", "seed", "status", "generation"),
                ),
            }
        )
    return found


def curves(data: ExperimentData) -> list[dict[str, Any]]:
    """Per treatment: generations, the world each was evaluated in, and the mean best
    distance over its runs with the 95% t interval (``fitness_curves``, clipped at 0) and the
    number of runs at each generation."""
    table = fitness_curves(data)
    return [
        {
            "treatment": name,
            **_columns(
                table[table["treatment"] == name],
                ("generation", "environment", "n", "mean", "low", "high"),
            ),
        }
        for name in data.treatment_names
    ]


def qd(data: ExperimentData, table: pd.DataFrame) -> list[dict[str, Any]]:
    """Per treatment and QD metric (``analysis.qd.METRICS``) with a curve: its label,
    generations, the world of each, runs, mean, low and high."""
    found = []
    for name in data.treatment_names:
        for metric, label in QD_METRICS.items():
            part = table[(table["treatment"] == name) & (table["metric"] == metric)]
            if part.empty:
                continue
            columns = _columns(part, ("generation", "environment", "n", "mean", "low", "high"))
            found.append({"treatment": name, "metric": metric, "label": label, **columns})
    return found


def _sample(frame: pd.DataFrame, front: pd.DataFrame, limit: int) -> pd.DataFrame:
    """At most ``limit`` rows of ``frame`` spread evenly, with every row of ``front``."""
    if len(frame) <= limit:
        return frame
    spread = frame.iloc[np.unique(np.linspace(0, len(frame) - 1, limit).round().astype(int))]
    return pd.concat([spread, front]).drop_duplicates(subset=["run_id", "individual_id"])


def fronts(data: ExperimentData, limit: int = MAX_POINTS) -> list[dict[str, Any]]:
    """Per treatment: its display generation, how many members its runs' populations hold
    then, up to ``limit`` of them and their non-dominated front (distance max, active share
    min), each point with individual and run ids."""
    members = data.display_populations()
    found = []
    for name in data.treatment_names:
        frame = members[members["treatment"] == name].dropna(subset=["distance", "active_share"])
        front = pareto_front(frame)
        found.append(
            {
                "treatment": name,
                "generation": data.display_generation(name),
                "members": len(frame),
                "points": _columns(_sample(frame, front, limit), POINT_COLUMNS),
                "front": _columns(front, POINT_COLUMNS),
            }
        )
    return found


def descriptors(data: ExperimentData) -> list[dict[str, Any]]:
    """Per descriptor (best distance and every trait, ``evolution.traits``): its label and, per
    treatment, one value per run at the treatment's display generation, with the run ids."""
    values = data.display_run_values()
    found = []
    labels = traits.labels()
    for metric in ("best_distance", *traits.names()):
        per_treatment = []
        for name in data.treatment_names:
            chosen = values[values["treatment"] == name].dropna(subset=[metric])
            per_treatment.append({"treatment": name, "run_id": _columns(chosen, ["run_id"])["run_id"],
                                  "values": _columns(chosen, [metric])[metric]})  # fmt: skip
        found.append({"metric": metric, "label": labels[metric], "treatments": per_treatment})
    return found


def statistics(data: ExperimentData) -> list[dict[str, Any]]:
    """Every row of the report's statistics table, with the metric's label."""
    table = statistics_table(data)
    rows = _records(table, STAT_FIELDS)
    for row in rows:
        row["metric_label"] = metric_labels().get(row["metric"], row["metric"])
    return rows
