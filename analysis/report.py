"""The experiment report: every figure, the statistics and the run settings, as one
self-contained HTML page (figures embedded as base64 PNG) and a Markdown file beside it.

``write_report(data, out_dir, robots=...)`` writes it from an ``ExperimentData``; ``robots``
(a ``Robots``) reaches the stored robots for the renders, the evaluation settings and the
animation. The database side (``service.reports.report``, behind ``softevo report`` and the REST
service) reads the data and binds the robots. ``out_dir`` receives::

    report.html          self-contained page
    report.md            the same content; figures linked from figures/
    figures/NAME.png     and NAME.svg, one pair per figure (see analysis.figures)
    figures/best.gif     the best robot's motion (unless animation=False)
    findings.csv         one row per headline finding, one test each, Holm across them
                         (analysis.findings.findings_table)
    summary.csv          one row per run: best distance final and at generation 0, gain,
                         frequencies, distance per cycle and per second (analysis.run_summary)
    statistics.csv       every pairwise comparison (secondary): its family, test, p, A12,
                         detectable A12 and interval (analysis.stats_tables.statistics_table)
    treatment_summary.csv  means and t intervals over repetitions per treatment and metric
    qd.csv               QD score and coverage per treatment and generation, mean and t interval
                         over runs (analysis.qd; given qd=)
"""

from __future__ import annotations

import base64
import html
import math
import tempfile
import warnings
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from datetime import UTC, datetime
from importlib.metadata import PackageNotFoundError, version
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
from rich.console import Console
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

from softevo import sim
from softevo.analysis import figures as fig
from softevo.analysis.data import ExperimentData
from softevo.analysis.exaptation import ExaptationData, exaptation_figure, run_statistics, treatment_summary
from softevo.analysis.findings import Finding, findings_display, findings_frame, headline_findings
from softevo.analysis.methods import evaluation_methods, methods_text
from softevo.analysis.motion import animate
from softevo.analysis.qd import final_table, qd_curves, qd_figure
from softevo.analysis.run_summary import run_summary
from softevo.analysis.stats_tables import (
    INTERVAL,
    MANN_WHITNEY,
    MIN_TESTED_RUNS,
    NOT_TESTED,
    RUN_PAIRED,
    SEED_PAIRED,
    few_runs_text,
    fitness_curves,
    is_untested,
    metric_labels,
    statistics_table,
    summary_table,
)
from softevo.errors import UserError
from softevo.evolution.selection import Objective, objectives_named

METHODS = (
    "These pairwise tests are secondary: the headline questions, one test each, are in the "
    "Findings section. A metric whose run values are constant or identical to another's "
    "(frequency over active robots when every robot has an active voxel, a passive share "
    "always 0) is left out. "
    f"Intervals: {INTERVAL} of the mean over repetitions, and of a difference of means "
    "(Welch's t for independent samples, the paired t for seed-matched runs); their coverage "
    "at n = 7 was checked by simulation (docs/analysis.md). The unit is the run: every test "
    "compares one value per run (its population's best distance, or its population's mean of "
    "a descriptor), n = repetitions. Every comparison names its generation: static "
    "treatments are compared at their common last generation, a transition against a static "
    "treatment at the last generation both stored, start vs end at the first generation in the "
    "treatment's final world (0; a transition's arrival) against its last. Families (the "
    "family column; family_size its tests): stiffness "
    "within one world, per metric; each transition against the static control of its final "
    "world, per metric; start vs end per metric. Bonferroni runs within the family: "
    "p_bonferroni = min(1, p x family_size); * p<0.05, ** p<0.01, *** p<0.001 after "
    "correction. Cross-world pairs (land against water, a transition against its first "
    "world, the transitions against each other) are described, never tested: distances are "
    "horizontal on land and 3-D in water, and their absolute differences come from "
    f"arbitrary parameter choices. Tests (the test column): {MANN_WHITNEY} when the two "
    f"treatments' runs have seeds of their own; {SEED_PAIRED} when they share seeds (their "
    f"generation-0 populations are then identical); {RUN_PAIRED} for start vs end; "
    f"{NOT_TESTED} for the cross-world rows. All two-sided. Effect sizes: Vargha-Delaney "
    "A12 = P(a > b) + P(a = b)/2 (for paired rows the share of seed pairs with a above b); "
    "0.5: none; 0.71 or 0.29 and beyond: large. detectable_A12: the smallest A12 (or its "
    "mirror) the row's test detects with 80% power at its n and alpha / family_size (normal "
    "model); empty when the smallest p the rank test can give at that n is not below the "
    "threshold, so no effect could be significant. Read an ns with it: no difference larger "
    "than that was detectable, not no difference. frequency (active robots) leaves out the "
    "robots with no active voxel, whose frequency moves nothing; passive robots is their "
    "share; both frequencies are shown. A transition run's values after the switch are "
    "measured in its second environment."
)


class ReportWarning(UserWarning):
    """What a report's reader must know about its statistics (``softevo report`` prints it
    as a ``warning:`` line; the report says it too)."""


def sample_size_warning(data: ExperimentData) -> str | None:
    """Which treatments have too few runs for an interval or a test (fewer than
    ``MIN_TESTED_RUNS``: at n = 1 every p is 1, at n = 2 a t interval spans far beyond the
    values), or None."""
    runs = data.runs.groupby("treatment", sort=False)["run_id"].nunique()
    few = {str(name): int(count) for name, count in runs.items() if count < MIN_TESTED_RUNS}
    if not few:
        return None
    counts = sorted(set(few.values()))
    n = " or ".join(str(c) for c in counts)
    return (
        f"{len(few)} of {len(runs)} treatment(s) have fewer than {MIN_TESTED_RUNS} runs "
        f"({', '.join(few)}): n = {n}: not tested, no interval; run {MIN_TESTED_RUNS} or more "
        "repetitions per treatment"
    )


def failed_runs_warning(data: ExperimentData) -> str | None:
    """Which runs failed, and why (the run's stored error), or None."""
    runs = data.runs
    if "status" not in runs.columns:
        return None
    failed = runs[runs["status"] == "failed"]
    if failed.empty:
        return None
    reasons = "; ".join(
        f"r{int(row.run_id)} ({row.treatment}): {getattr(row, 'error', None) or 'no reason stored'}"
        for row in failed.itertuples(index=False)
    )
    return f"{len(failed)} of {len(runs)} run(s) failed: {reasons}"


# ---- document model: blocks rendered to Markdown and to HTML ----------------------------------
@dataclass
class Document:
    """An ordered list of blocks: ("h", level, text), ("p", text), ("table", DataFrame),
    ("figure", FigureFile) or ("animation", path, caption)."""

    title: str
    blocks: list[tuple] = field(default_factory=list)

    def heading(self, text: str, level: int = 2) -> None:
        self.blocks.append(("h", level, text))

    def paragraph(self, text: str) -> None:
        self.blocks.append(("p", text))

    def table(self, frame: pd.DataFrame) -> None:
        self.blocks.append(("table", frame))


NUMERICAL_ZERO = 1e-9  # |x| below this is floating-point noise around 0 (3.93e-16), shown as 0


def number(value: float, digits: int = 3) -> str:
    """``value`` to ``digits`` significant digits, a numerically-zero value as ``0``."""
    return "0" if abs(value) < NUMERICAL_ZERO else f"{value:.{digits}g}"


def interval_cell(mean: float, low: float, high: float) -> str:
    """``mean [low, high]``; ``mean (n < 3: no interval)`` where there are too few values
    (its bounds are NaN); empty without a value."""
    if not np.isfinite(mean):
        return ""
    if not (np.isfinite(low) and np.isfinite(high)):
        return f"{number(mean)} (n < {MIN_TESTED_RUNS}: no interval)"
    return f"{number(mean)} [{number(low)}, {number(high)}]"


def _cell(value: Any) -> str:
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return ""
    if isinstance(value, float | np.floating):
        return number(float(value), 4)
    return str(value)


def markdown_table(frame: pd.DataFrame) -> str:
    """A GitHub-flavoured Markdown table (pipes in cells escaped)."""

    def row(cells) -> str:
        return "| " + " | ".join(_cell(c).replace("|", "\\|") for c in cells) + " |"

    lines = [row(frame.columns), "| " + " | ".join("---" for _ in frame.columns) + " |"]
    lines += [row(values) for values in frame.itertuples(index=False)]
    return "\n".join(lines)


def html_table(frame: pd.DataFrame) -> str:
    """An HTML table, every cell escaped."""
    head = "".join(f"<th>{html.escape(str(c))}</th>" for c in frame.columns)
    body = "".join(
        "<tr>" + "".join(f"<td>{html.escape(_cell(v))}</td>" for v in values) + "</tr>"
        for values in frame.itertuples(index=False)
    )
    return f"<table><thead><tr>{head}</tr></thead><tbody>{body}</tbody></table>"


def to_markdown(doc: Document, out_dir: Path) -> str:
    """The document as Markdown; figures are linked relative to ``out_dir``."""
    parts = [f"# {doc.title}"]
    for block in doc.blocks:
        kind = block[0]
        if kind == "h":
            parts.append("#" * block[1] + " " + block[2])
        elif kind == "p":
            parts.append(block[1])
        elif kind == "table":
            parts.append(markdown_table(block[1]))
        elif kind == "figure":
            figure = block[1]
            link = figure.png.relative_to(out_dir).as_posix()
            svg = figure.svg.relative_to(out_dir).as_posix()
            parts.append(f"![{figure.name}]({link})\n\n*{figure.caption}* ([SVG]({svg}))")
        elif kind == "animation":
            parts.append(f"![animation]({block[1].relative_to(out_dir).as_posix()})\n\n*{block[2]}*")
    return "\n\n".join(parts) + "\n"


STYLE = """
body{font-family:system-ui,-apple-system,Segoe UI,Helvetica,Arial,sans-serif;max-width:1500px;
margin:2em auto;padding:0 1em;color:#222;line-height:1.45}
h1{border-bottom:2px solid #ddd;padding-bottom:.3em}h2{margin-top:2em;border-bottom:1px solid #eee}
table{border-collapse:collapse;font-size:13px;margin:1em 0}
th,td{border:1px solid #ddd;padding:3px 8px;text-align:right}th{background:#f4f4f4}
td:first-child,th:first-child{text-align:left}
figure{margin:1.5em 0}figure img{max-width:100%;border:1px solid #eee}
figcaption{font-size:14px;color:#444;margin-top:.4em}
.scroll{max-height:600px;overflow:auto}
"""


def _data_uri(path: Path, mime: str) -> str:
    return f"data:{mime};base64," + base64.b64encode(path.read_bytes()).decode("ascii")


def to_html(doc: Document) -> str:
    """The document as one self-contained HTML page (images inlined as base64)."""
    parts = [f"<h1>{html.escape(doc.title)}</h1>"]
    for block in doc.blocks:
        kind = block[0]
        if kind == "h":
            parts.append(f"<h{block[1]}>{html.escape(block[2])}</h{block[1]}>")
        elif kind == "p":
            parts.append(f"<p>{html.escape(block[1])}</p>")
        elif kind == "table":
            parts.append(f'<div class="scroll">{html_table(block[1])}</div>')
        elif kind == "figure":
            figure = block[1]
            parts.append(
                f'<figure id="{figure.name}"><img alt="{figure.name}" '
                f'src="{_data_uri(figure.png, "image/png")}">'
                f"<figcaption>{html.escape(figure.caption)}</figcaption></figure>"
            )
        elif kind == "animation":
            parts.append(
                f'<figure id="animation"><img alt="animation" '
                f'src="{_data_uri(block[1], "image/gif")}">'
                f"<figcaption>{html.escape(block[2])}</figcaption></figure>"
            )
    body = "\n".join(parts)
    return (
        '<!DOCTYPE html>\n<html lang="en"><head><meta charset="utf-8">'
        f"<title>{html.escape(doc.title)}</title><style>{STYLE}</style></head>"
        f"<body>\n{body}\n</body></html>\n"
    )


# ---- content ------------------------------------------------------------------------------------
def settings_table(data: ExperimentData) -> pd.DataFrame:
    """One row per treatment: schedule, stiffness, sizes, seeds, runs finished."""
    finished = data.runs[data.runs["status"] == "finished"].groupby("treatment").size()
    total = data.runs.groupby("treatment").size()
    t = data.treatments
    seeds = [
        f"{s}" if r == 1 else f"{s}..{s + r - 1}" for s, r in zip(t["seed"], t["repetitions"], strict=True)
    ]
    return pd.DataFrame(
        {
            "treatment": t["name"],
            "environment schedule (env:first generation)": t["schedule"],
            "stiffness (MPa)": t["stiffness_mpa"],
            "population": t["population"],
            "generations": t["generations"],
            "workspace": t["workspace"],
            "cycles": [
                _cycles_text(c, cap)
                for c, cap in zip(t["cycles"], t.get("max_seconds", [None] * len(t)), strict=True)
            ],
            "repetitions": t["repetitions"],
            "seeds": seeds,
            "algorithm": t["algorithm"],
            "runs finished": [f"{finished.get(n, 0)}/{total.get(n, 0)}" for n in t["name"]],
        }
    )


def treatment_objectives(treatment: pd.Series) -> tuple[Objective, ...]:
    """The objectives a treatment (a row of ``data.treatments``) selects on: those its
    settings name, or the paper's; an objective no longer registered keeps its name, with
    the direction unknown ("?")."""
    names = treatment.get("objectives")
    names = list(names) if isinstance(names, list | tuple) else []
    found = []
    for name in names:
        try:
            found.append(objectives_named([name])[0])
        except ValueError:
            found.append(Objective(name, "?"))
    return tuple(found) or objectives_named(())


def objectives_table(data: ExperimentData) -> pd.DataFrame:
    """One row per treatment and objective it selects on: the direction, and the mean and the
    best (the largest of one maximised, the smallest of one minimised) of the objective over
    the members each treatment is shown with (``display_populations``). A minimised
    objective's best is taken over the robots with an active voxel: a passive body (one voxel,
    nothing active) is its trivial optimum and moves nothing (issue 59.3)."""
    members = data.display_populations()
    rows = []
    for _, treatment in data.treatments.iterrows():
        mine = members[members["treatment"] == treatment["name"]] if not members.empty else members
        for objective in treatment_objectives(treatment):
            values = _objective_column(mine, objective.name)
            active = _objective_column(_with_active_voxel(mine), objective.name)
            best = values.max() if objective.direction == "max" else active.min()
            rows.append(
                {
                    "treatment": treatment["name"],
                    "objective": objective.name,
                    "direction": {"max": "maximised", "min": "minimised"}.get(objective.direction, "?"),
                    "mean": float(values.mean()) if len(values) else math.nan,
                    "best": float(best) if pd.notna(best) else math.nan,
                }
            )
    return pd.DataFrame(rows, columns=["treatment", "objective", "direction", "mean", "best"])


def _with_active_voxel(members: pd.DataFrame) -> pd.DataFrame:
    """The members with an active voxel (all of them where active share is not known)."""
    if "active_share" not in members.columns:
        return members
    return members[members["active_share"].fillna(0) > 0]


def _objective_column(members: pd.DataFrame, name: str) -> pd.Series:
    """The members' values of objective ``name`` (from their ``objectives``, else the column
    of that name), missing ones dropped."""
    stored = members["objectives"] if "objectives" in members.columns else pd.Series(dtype=object)
    values = [o.get(name) if isinstance(o, dict) else None for o in stored]
    if name in members.columns:
        values = [
            v if v is not None else c
            for v, c in zip(values or [None] * len(members), members[name], strict=True)
        ]
    return pd.Series(values, dtype=float).dropna()


def _cycles_text(cycles: int, max_seconds: float | None) -> str:
    """E.g. ``8``, or ``8 (<= 4.5 s)`` for cycles capped in seconds."""
    if max_seconds is None or pd.isna(max_seconds):
        return f"{int(cycles)}"
    return f"{int(cycles)} (<= {float(max_seconds):g} s)"


def _as_utc(value) -> datetime | None:
    if value is None or pd.isna(value):
        return None
    value = pd.Timestamp(value).to_pydatetime()
    return value if value.tzinfo else value.replace(tzinfo=UTC)


def timing_text(data: ExperimentData) -> str:
    """Wall time from the experiment's creation to its last stored generation, and the
    evaluations it took."""
    created = _as_utc(data.experiment.get("created_at"))
    last = _as_utc(data.generations["created_at"].max()) if len(data.generations) else None
    evaluations = int(data.generations["evaluations"].sum())
    seconds = float(data.generations["evaluation_seconds"].sum())
    wall = (last - created).total_seconds() if created and last else float("nan")
    return (
        f"Wall time from the experiment's creation to its last stored generation: "
        f"{_duration(wall)} ({len(data.runs)} runs, {len(data.generations)} generations, "
        f"{evaluations:,} simulated evaluations; {_duration(seconds)} of evaluation time, the "
        "evaluations' own simulation times summed over all workers, queue waits left out)."
    )


def _duration(seconds: float) -> str:
    if not math.isfinite(seconds):
        return "unknown"
    hours, rest = divmod(int(round(seconds)), 3600)
    minutes, secs = divmod(rest, 60)
    return f"{hours} h {minutes:02d} min {secs:02d} s" if hours else f"{minutes} min {secs:02d} s"


def summary_pivot(summary: pd.DataFrame, names: list[str]) -> pd.DataFrame:
    """Treatments as rows, metrics as columns, cells ``mean [low, high]``."""
    cells = summary.assign(
        cell=[
            interval_cell(m, lo, hi)
            for m, lo, hi in zip(summary["mean"], summary["low"], summary["high"], strict=True)
        ]
    )
    table = cells.pivot(index=["treatment", "generation"], columns="metric", values="cell")
    labels = metric_labels()
    metrics = [m for m in labels if m in table.columns]
    order = {name: k for k, name in enumerate(names)}
    table = table.reindex(columns=list(dict.fromkeys(metrics)))
    table = table.sort_index(key=lambda col: col.map(order) if col.name == "treatment" else col)
    table.columns = [labels[m] for m in table.columns]
    return table.reset_index()


PER_RUN_SHOWN = {
    "best_distance_final": "best distance, final",
    "best_distance_generation0": "best distance, generation 0",
    "gain": "gain",
    "distance_per_cycle": "best robot: distance per cycle",
    "distance_per_second": "distance per second",
    "best_frequency": "its frequency (Hz)",
    "frequency_final": "population frequency, final (Hz)",
}


def per_run_means(runs: pd.DataFrame) -> pd.DataFrame:
    """Per treatment: the number of runs and the mean over its runs of the per-run summary's
    main columns (``analysis.run_summary``)."""
    grouped = runs.groupby("treatment", sort=False)
    table = grouped[list(PER_RUN_SHOWN)].mean().rename(columns=PER_RUN_SHOWN)
    table.insert(0, "runs", grouped.size())
    return table.reset_index()


def _statistics_display(stats: pd.DataFrame) -> pd.DataFrame:
    dropped = ["median_a", "median_b", "difference", "difference_low", "difference_high", "unit"]
    shown = stats.drop(columns=dropped)
    labels = metric_labels()
    shown["metric"] = [labels.get(m, m) for m in shown["metric"]]
    shown["a - b [95% CI]"] = [
        interval_cell(d, lo, hi)
        for d, lo, hi in zip(
            stats["difference"], stats["difference_low"], stats["difference_high"], strict=True
        )
    ]
    return shown


# ---- building -----------------------------------------------------------------------------------
@dataclass(frozen=True)
class Report:
    """What ``write_report`` wrote."""

    html: Path
    markdown: Path
    figures: list[fig.FigureFile]
    statistics: Path
    summary: Path
    animation: Path | None
    findings: Path | None = None
    treatment_summary: Path | None = None


@dataclass(frozen=True)
class Robots:
    """How the report reaches stored robots; the caller binds these to its database.

    phenotypes(ids) -> {id: Phenotype}; scene(id, environment) -> (scene, record) as
    ``analysis.robots.record_scene`` (record with treatment, phenotype_object and task, the
    ``worker.tasks.Task`` replayed); motion(id, environment) -> Motion; evaluations() ->
    every evaluation of the experiment (columns treatment, frequency) or None: the methods
    count the cap's cuts over them (else over the evaluations ``data`` holds).
    """

    phenotypes: Callable[[list[int]], dict[int, Any]]
    scene: Callable[[int, str | None], tuple[dict[str, Any], dict[str, Any]]]
    motion: Callable[[int, str | None], Any]
    evaluations: Callable[[], pd.DataFrame | None] = lambda: None


@contextmanager
def _steps(total: int, enabled: bool) -> Iterator[Callable[[str], None]]:
    """A rich progress bar over ``total`` steps; yields ``advance(description)``."""
    if not enabled:
        yield lambda _description: None
        return
    columns = (TextColumn("{task.description:<28}"), BarColumn(), MofNCompleteColumn(), TimeElapsedColumn())
    with Progress(*columns, console=Console(stderr=True), transient=True) as progress:
        task = progress.add_task("report", total=total)
        yield lambda description: progress.update(task, advance=1, description=description)


def write_report(
    data: ExperimentData,
    out_dir: str | Path,
    *,
    robots: Robots | None = None,
    animation: bool = True,
    progress: bool = False,
    seed: int = 0,
    exaptation: ExaptationData | None = None,
    qd: pd.DataFrame | None = None,
) -> Report:
    """Write the report of ``data`` into ``out_dir`` (see the module doc). Without ``robots``
    the robot renders, the evaluation settings and the animation are left out. ``seed``
    is accepted and unused (the intervals are t intervals: nothing resamples). ``exaptation``
    (``analysis.exaptation``; transition runs' founders and surviving lines) adds the
    exaptation section and ``exaptation.csv``; ``qd`` (``analysis.qd.QD_COLUMNS``: each run's
    archive per generation) the quality-diversity figure, section and ``qd.csv``."""
    if data.generations.empty:
        raise UserError(f"experiment e{data.experiment['id']} has no stored generation yet")
    out = _output_dir(out_dir)
    for note in (failed_runs_warning(data), sample_size_warning(data), data.left_out_note):
        if note is not None:
            warnings.warn(note, ReportWarning, stacklevel=2)
    figures_dir = out / "figures"
    animation = animation and robots is not None
    with _steps(9 if animation else 8, progress) as step:
        step("statistics")
        stats, summary = statistics_table(data), summary_table(data)
        findings, runs = headline_findings(data), run_summary(data)
        curves = fitness_curves(data)
        figures = []
        for name, make in _figure_makers(data, robots, stats, curves, figures_dir):
            step(f"figure: {name}")
            made = make()
            if made is not None:
                figures.append(made)
        exaptation_stats = None
        if exaptation is not None and not exaptation.empty:
            exaptation_stats = run_statistics(data, exaptation)
            made = exaptation_figure(data, exaptation, exaptation_stats, figures_dir)
            if made is not None:
                figures.append(made)
            exaptation_stats.to_csv(out / "exaptation.csv", index=False)
        qd_stats = None
        if qd is not None and not qd.empty:
            qd_stats = qd_curves(data, qd)
            made = qd_figure(data, qd_stats, figures_dir)
            if made is not None:
                figures.append(made)
            qd_stats.to_csv(out / "qd.csv", index=False)
        gif = None
        if animation:
            step("animation of the best robot")
            gif = _best_animation(robots, data, figures_dir)
        step("writing the report")
        paths = {
            name: out / f"{name}.csv" for name in ("findings", "summary", "statistics", "treatment_summary")
        }
        findings_frame(findings).to_csv(paths["findings"], index=False)
        runs.to_csv(paths["summary"], index=False)
        stats.to_csv(paths["statistics"], index=False)
        summary.to_csv(paths["treatment_summary"], index=False)
        evaluation = None if robots is None else evaluation_text(robots, data)
        doc = build_document(data, stats, summary, figures, gif, evaluation, exaptation_stats, findings, runs,
                             qd_stats)
        markdown, page = out / "report.md", out / "report.html"
        markdown.write_text(to_markdown(doc, out), encoding="utf-8")
        page.write_text(to_html(doc), encoding="utf-8")
    return Report(page, markdown, figures, paths["statistics"], paths["summary"], gif, paths["findings"],
                  paths["treatment_summary"])  # fmt: skip


def _output_dir(out_dir: str | Path) -> Path:
    out = Path(out_dir)
    try:
        (out / "figures").mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise UserError(f"cannot create output directory {out}: {exc.strerror or exc}") from exc
    return out


def _figure_makers(data, robots, stats, curves, figures_dir):
    makers = [
        ("fitness", lambda: fig.fitness_figure(data, curves, figures_dir)),
        ("descriptors", lambda: fig.descriptors_figure(data, stats, figures_dir)),
        ("pareto", lambda: fig.pareto_figure(data, figures_dir)),
        ("transitions", lambda: fig.transitions_figure(data, curves, stats, figures_dir)),
        ("robots", lambda: fig.robots_figure(data, robots.phenotypes, figures_dir)),
        ("start_end", lambda: fig.start_end_figure(data, stats, figures_dir)),
    ]
    return [(name, make) for name, make in makers if robots is not None or name != "robots"]


def evaluation_text(robots: Robots, data: ExperimentData) -> str | None:
    """The physics every evaluation used, read from one stored individual's scene (the
    same for all treatments but stiffness and world), and per treatment, from its own
    stored settings, its model, frequency mapping, settling, cycles and cap
    (``analysis.methods``)."""
    best = best_individual(data)
    if best is None:
        return None
    scene, record = robots.scene(int(best["individual_id"]), best["environment"])
    parsed, phenotype = sim.parse_scene(scene), record["phenotype_object"]
    m = parsed.material
    every = robots.evaluations()
    methods = evaluation_methods(data.treatments, data.evaluations if every is None else every, phenotype)
    algorithms = set(data.treatments["algorithm"])
    selection = "with age (AFPO)" if algorithms == {"afpo"} else f"algorithm {', '.join(sorted(algorithms))}"
    return (
        f"Evaluation: voxel edge {parsed.voxel_size:g} m, density {m.density:g} kg/m\u00b3, "
        f"Poisson ratio {m.poisson_ratio:g}, friction {m.friction_static:g} static / "
        f"{m.friction_kinetic:g} kinetic, actuation {parsed.actuation.waveform} of linear strain "
        f"amplitude {parsed.actuation.amplitude:g} at the robot's evolved frequency with "
        f"evolved per-voxel phases; distance counts from the end of settling. Per treatment, "
        f"from its stored settings: {methods_text(methods)} Objectives: distance (max), "
        f"active share (min), voxel count (min), {selection}."
    )


def best_individual(data: ExperimentData) -> dict[str, Any] | None:
    """The final-population member with the largest distance (None if there is none)."""
    final = data.final_populations().dropna(subset=["distance"])
    if final.empty:
        return None
    return final.loc[final["distance"].idxmax()].to_dict()


def _best_animation(robots: Robots, data: ExperimentData, out_dir: Path) -> Path | None:
    """A GIF of the best final robot; None (the report says so) if it cannot be made."""
    best = best_individual(data)
    if best is None:
        return None
    try:
        motion = robots.motion(int(best["individual_id"]), best["environment"])
        return animate(motion, out_dir / "best.gif")
    except UserError:
        return None


def build_document(
    data: ExperimentData,
    stats: pd.DataFrame,
    summary: pd.DataFrame,
    figures: list[fig.FigureFile],
    gif: Path | None,
    evaluation: str | None = None,
    exaptation: pd.DataFrame | None = None,
    findings: list[Finding] | None = None,
    runs: pd.DataFrame | None = None,
    qd: pd.DataFrame | None = None,
) -> Document:
    """The report's content, in order; ``evaluation`` is ``evaluation_text``; ``exaptation``
    the per-run statistics of ``analysis.exaptation.run_statistics``; ``findings`` those of
    ``analysis.findings.headline_findings`` (computed here when not given); ``runs`` the
    per-run summary (``analysis.run_summary``); ``qd`` the curves of ``analysis.qd.qd_curves``."""
    experiment = data.experiment
    doc = Document(f"softevo report: experiment e{experiment['id']} \u201c{experiment['name']}\u201d")
    created = _as_utc(experiment.get("created_at"))
    doc.paragraph(
        f"Preset: {experiment.get('preset') or '-'}; scale: {experiment.get('scale') or '-'}; "
        f"created {created:%Y-%m-%d %H:%M} UTC; report generated "
        f"{datetime.now(UTC):%Y-%m-%d %H:%M} UTC by softevo {_version()}."
        if created
        else f"Report generated {datetime.now(UTC):%Y-%m-%d %H:%M} UTC."
    )
    findings_block(doc, headline_findings(data) if findings is None else findings)
    doc.heading("Run settings")
    doc.table(settings_table(data))
    doc.paragraph(timing_text(data))
    if evaluation is not None:
        doc.paragraph(evaluation)
    note = sample_size_warning(data)
    for warning in (failed_runs_warning(data), note, data.left_out_note):
        if warning is not None:
            doc.paragraph(f"Warning: {warning}.")
    doc.heading("Objectives")
    doc.paragraph(
        "What each treatment's selection optimises, with each objective's mean and best over "
        "the members the treatment is shown with (the same generation as the summary). The best "
        "of a minimised objective is over the robots with an active voxel: a passive body (one "
        "voxel, nothing active) is its trivial optimum, and it moves nothing."
    )
    doc.table(objectives_table(data))
    doc.heading("Summary")
    doc.paragraph(
        f"Mean over repetitions with its {INTERVAL} interval, at each generation the "
        "treatment is shown or compared at. Best distance: each run's best at that "
        "generation; other columns: each run's population mean then; frequency (active "
        "robots): the mean over the robots with an active voxel; passive robots: the share of "
        "the population with no active voxel (their frequency moves nothing)."
    )
    doc.table(summary_pivot(summary, data.treatment_names))
    if runs is not None and not runs.empty:
        doc.paragraph(
            "Per run (summary.csv; here the mean over each treatment's runs): the primary "
            "measure, each run's best distance in its final generation, at generation 0 and "
            "the gain (empty where the two are in different worlds); the best robot's distance "
            "per cycle and per second (its evaluation's seconds after settling: cycles / "
            "frequency, at most the cap) and its frequency."
        )
        doc.table(per_run_means(runs))
    doc.heading("Figures")
    for figure in figures:
        doc.heading(figure.title, 3)
        doc.blocks.append(("figure", figure))
    if not any(f.name == "transitions" for f in figures):
        doc.paragraph("No transition treatment in this experiment: no transition figure.")
    _animation_block(doc, data, gif)
    if exaptation is not None and not exaptation.empty:
        exaptation_block(doc, exaptation)
    if qd is not None and not qd.empty:
        qd_block(doc, qd)
    doc.heading("Statistics")
    if note is not None:
        doc.paragraph(f"Warning: {note}.")
    if data.left_out_note is not None:
        doc.paragraph(f"Warning: {data.left_out_note}.")
    tested = stats[stats["p"].notna()] if "p" in stats.columns else stats
    if tested.empty:  # no row with a p-value: none to show (issue 59.3)
        n = int(min(stats["n_a"].min(), stats["n_b"].min())) if len(stats) else 0
        doc.paragraph(f"No pairwise test: {few_runs_text(n)} (a test needs {MIN_TESTED_RUNS} or more runs "
                      "per treatment). statistics.csv holds each comparison's means.")
        return doc
    doc.paragraph(METHODS)
    untested = int(stats["test"].map(is_untested).sum())
    if untested:
        doc.paragraph(f"{untested} comparison(s) of treatments with fewer than {MIN_TESTED_RUNS} runs are "
                      "left out of this table (not tested; statistics.csv holds their means).")
    doc.table(_statistics_display(stats[~stats["test"].map(is_untested)]))
    return doc


FINDINGS_METHODS = (
    "One declared primary measure per hypothesis, one value per run: each run's best distance "
    "in its final generation (the paper's measure) for the distance trends and the transitions; "
    "each run's change of its population's mean frequency from generation 0 for the frequency "
    "trends (at generation 0 frequency depends on the genome alone). Stiffness trends: "
    "Jonckheere-Terpstra, one-sided in the paper's direction, over S2..S5 on land (the paper "
    "calls S1 on land non-functional) and S1..S5 in water, at the last generation all their runs "
    "stored. Transitions: two-sided Mann-Whitney U against the static control of the final world "
    "at equal total generations (the paper's contrast). Holm within each family: primary, the "
    "distance gain (absolute and log, its own family), secondary (frequency levels; the "
    "transitions at equal time in the final world). A12 with its bootstrap 95% interval; A12 at "
    "start on the same runs at generation 0 (random robots; a transition's arrival against the "
    "control's generation 0). Power and runs needed (at the effect seen and at A12 0.71, 80% "
    "power) by simulation at the family's strictest threshold. Verdicts (evolved, present in "
    "random bodies, not detected, reversed) by code, as docs/results/README.md defines them. No "
    "test pairs runs of different worlds; the pairwise tests under Statistics are secondary. "
    "Columns as in findings.csv; per-run values in summary.csv."
)


def findings_block(doc: Document, findings: list[Finding]) -> None:
    """The findings table with each finding's start and gain (``analysis.findings``)."""
    doc.heading("Findings")
    if not findings:
        doc.paragraph("This experiment holds none of the paper's headline comparisons.")
        return
    if not any(np.isfinite(f.row["p"]) for f in findings):  # issue 59.3: no p-values to show
        doc.paragraph(f"Not tested: fewer than {MIN_TESTED_RUNS} runs per group in every headline "
                      "comparison (findings.csv holds their means and A12).")
        return
    doc.paragraph(FINDINGS_METHODS)
    doc.table(findings_display(findings))


def _animation_block(doc: Document, data: ExperimentData, gif: Path | None) -> None:
    best = best_individual(data)
    if gif is None or best is None:
        return
    doc.heading("Motion of the best robot", 3)
    doc.blocks.append(
        (
            "animation",
            gif,
            f"Individual {int(best['individual_id'])} ({best['treatment']}, repetition "
            f"{int(best['repetition'])}), the farthest-travelling member of the final populations "
            f"({best['distance']:.3g} voxel lengths in {best['environment']}), re-simulated. "
            f"`softevo show {int(best['individual_id'])} --out FILE.gif` makes it again.",
        )
    )


def exaptation_block(doc: Document, stats: pd.DataFrame) -> None:
    doc.heading("Exaptation across the switch")
    doc.paragraph(
        "Per transition run (each run one observation): the founders (the population kept just "
        "before the switch), how many have a line reaching the last generation, the share of the "
        "final population descending from a founder, and for each trait the mean at birth of the "
        "surviving founders minus that of all founders (a positive shift: the survivors carried "
        "more of it before the switch). Definitions: docs/sql.md; per line: softevo exaptation RUN."
    )
    doc.table(treatment_summary(stats).round(3))
    shown = ["treatment", "repetition", "founders", "founders_surviving", "final_from_founders",
             "voxel_count_shift", "active_share_shift", "symmetry_shift"]  # fmt: skip
    doc.table(stats[shown].round(3))


def qd_block(doc: Document, curves: pd.DataFrame) -> None:
    doc.heading("Quality-diversity")
    doc.paragraph(
        "Per treatment at its last generation (each run one observation; mean and 95% t interval, "
        "none below three runs): the QD score (the sum of the elites' distances) and coverage (the "
        "share of cells filled) of each run's MAP-Elites archive, the best robot of each cell of "
        "the archive's measures in the world evaluated then. Every generation: qd.csv; per run: "
        "softevo archive RUN."
    )
    doc.table(final_table(curves).round(3))


def _version() -> str:
    try:
        return version("softevo")
    except PackageNotFoundError:
        return "(not installed)"


def report_html(data: ExperimentData, robots: Robots | None = None, **options: Any) -> str:
    """The report page as a string (for the REST service), built in a temporary directory."""
    with tempfile.TemporaryDirectory(prefix="softevo-report-") as tmp:
        return write_report(data, tmp, robots=robots, **options).html.read_text(encoding="utf-8")
