"""Quality-diversity over generations: each run's MAP-Elites archive (``evolution.archive``),
its QD score and coverage per generation, as mean over runs with a 95% t interval.

Input (``QD_COLUMNS``, built by ``service.reports.report.qd_data`` from
``service.storage.archive.run_qd_curve``): one row per run and stored generation, the
coverage and QD score of the archive of the world the run evaluated then (an archive holds
one world's evaluations: distances of two worlds do not compare), so a transition's curve
moves on to its new world's archive at the switch. Any run has an archive, whatever its
algorithm: the grid is its treatment's (``map-elites``) or the default one.

Each run is one observation; the interval is ``analysis.stats_tables.t_interval``'s, none
below three runs (as every interval of the report), clipped to what the measure allows
(coverage within [0, 1], QD score at least 0).
"""

from __future__ import annotations

from pathlib import Path

import matplotlib.pyplot as plt
import pandas as pd
from matplotlib.ticker import MaxNLocator

from softevo.analysis import figures as fig
from softevo.analysis.data import ExperimentData
from softevo.analysis.stats_tables import ci_table

NAME = "qd"  # its title is figures.TITLES[NAME]
QD_COLUMNS = ("run_id", "generation", "environment", "coverage", "qd_score")
METRICS = {
    "qd_score": "QD score (sum of the elites' distances)",
    "coverage": "coverage (share of cells filled)",
}
CURVE_COLUMNS = ("treatment", "metric", "generation", "environment", "n", "mean", "low", "high")


def qd_curves(data: ExperimentData, qd: pd.DataFrame) -> pd.DataFrame:
    """Per treatment, metric (``METRICS``), generation and world: n (runs), mean, low, high
    over runs (``CURVE_COLUMNS``, in the order of the treatments, then generation)."""
    if qd.empty:
        return pd.DataFrame(columns=list(CURVE_COLUMNS))
    named = qd.merge(data.runs[["run_id", "treatment"]], on="run_id")
    long = named.melt(id_vars=["treatment", "generation", "environment"], value_vars=list(METRICS),
                      var_name="metric", value_name="value")
    table = ci_table(long, "value", ["treatment", "metric", "generation", "environment"])
    table["order"] = table["treatment"].map({name: k for k, name in enumerate(data.treatment_names)})
    table = table.sort_values(["order", "metric", "generation"], kind="stable")
    return table[list(CURVE_COLUMNS)].reset_index(drop=True)


def final_table(curves: pd.DataFrame) -> pd.DataFrame:
    """Per treatment: its last generation's world, runs, and mean QD score and coverage with
    their intervals."""
    rows = []
    for name, part in curves.groupby("treatment", sort=False):
        last = part[part["generation"] == part["generation"].max()].set_index("metric")
        row = {"treatment": name, "generation": int(last["generation"].iloc[0]),
               "world": last["environment"].iloc[0], "runs": int(last["n"].iloc[0])}
        for metric in METRICS:
            row |= {metric: last.at[metric, "mean"], f"{metric}_low": last.at[metric, "low"],
                    f"{metric}_high": last.at[metric, "high"]}
        rows.append(row)
    return pd.DataFrame(rows)


def qd_figure(data: ExperimentData, curves: pd.DataFrame, out_dir: Path) -> fig.FigureFile | None:
    """Left: QD score, right: coverage over generations, per treatment the mean over runs with
    its 95% t band; a dashed line at each transition's switch. None without a curve."""
    if curves.empty:
        return None
    colors = fig.treatment_colors(data.treatments)
    switches = dict(zip(data.treatments["name"], data.treatments["switch_at"], strict=True))
    figure, axes = plt.subplots(1, 2, figsize=fig.figure_size(NAME, len(data.treatments)), dpi=fig.DPI,
                                layout="constrained")
    for ax, (metric, label) in zip(axes, METRICS.items(), strict=True):
        for name in data.treatment_names:
            curve = curves[(curves["treatment"] == name) & (curves["metric"] == metric)]
            if curve.empty:
                continue
            ax.plot(curve["generation"], curve["mean"], "-", color=colors[name], label=name, lw=1.6)
            ax.fill_between(curve["generation"], curve["low"], curve["high"], color=colors[name], alpha=0.2,
                            lw=0)
            if pd.notna(switches.get(name)):
                ax.axvline(int(switches[name]) - 0.5, color=colors[name], ls="--", lw=1)
        ax.xaxis.set_major_locator(MaxNLocator(integer=True))
        ax.set(xlabel="generation", ylabel=label, title=label.split(" (")[0])
        ax.set_ylim(bottom=0)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8, loc="upper left")
    caption = (
        "Each run's MAP-Elites archive after every generation (the best robot of each cell of "
        "the archive's measures, in the world evaluated then; softevo archive RUN): its QD "
        "score (left) and coverage (right), mean over runs with the 95% t band (none below three "
        "runs); a dashed line marks a transition's switch, where the curve moves on to the new "
        "world's archive."
    )
    return fig.save(figure, out_dir, NAME, caption)
