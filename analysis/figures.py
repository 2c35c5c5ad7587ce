"""The report's figures (matplotlib, Agg), each written as PNG and SVG.

Every figure function takes an ``ExperimentData`` (and what else it needs) and an output
directory, and returns a ``FigureFile`` (or None when the experiment has nothing to show,
e.g. no transition treatment). Sizes are fixed by ``figure_size`` at ``DPI`` dots per inch,
so a figure's pixel size depends only on the number of treatments.

Colours: one hue per environment schedule (land orange, water blue, land->water purple,
water->land green), darker for stiffer material.
"""

from __future__ import annotations

import math
import textwrap
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")
# user text (treatment names) in labels, ticks and titles is shown as typed: a `$` must not
# reach matplotlib's math-text parser (it raised on odd names and broke the report; issue 30)
matplotlib.rcParams["text.parse_math"] = False

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402
from matplotlib.axes import Axes  # noqa: E402
from matplotlib.figure import Figure  # noqa: E402
from matplotlib.patches import Patch  # noqa: E402
from matplotlib.ticker import MaxNLocator  # noqa: E402

from softevo.analysis.data import ExperimentData  # noqa: E402
from softevo.analysis.matching import arrival_generation  # noqa: E402
from softevo.analysis.render import ACTIVE_COLOR, PASSIVE_COLOR, draw_body  # noqa: E402
from softevo.analysis.stats_tables import ALPHA, ci_table, few_runs_text  # noqa: E402
from softevo.evolution import environments, traits  # noqa: E402
from softevo.evolution.selection import non_dominated_sort  # noqa: E402

DPI = 100
TRANSITION_CMAPS = ("Purples", "Greens", "Reds", "YlGn", "PuRd", "GnBu")  # transitions, in order
MAX_BRACKETS = 6
SAMPLES_PER_FRONT = 3
MOVED_SHARE = 0.02
TITLES = {
    "fitness": "Fitness over generations",
    "descriptors": "Descriptors per run at matched generations",
    "pareto": "Aggregated Pareto fronts",
    "transitions": "Transitions against static controls",
    "robots": "Robots sampled from the fronts",
    "start_end": "Descriptors at the start vs the end of evolution",
    "exaptation": "Founder lines across the switch",  # analysis.exaptation, transition runs only
    "qd": "Quality-diversity over generations",  # analysis.qd: each run's MAP-Elites archive
}
FIGURES = tuple(TITLES)


@dataclass(frozen=True)
class FigureFile:
    """A written figure: its name, title, caption, PNG and SVG paths and PNG size in pixels."""

    name: str
    title: str
    caption: str
    png: Path
    svg: Path
    size_px: tuple[int, int]


def figure_size(name: str, n_treatments: int, n_transitions: int = 0) -> tuple[float, float]:
    """(width, height) in inches of figure ``name`` for an experiment of that many
    treatments (and transition treatments)."""
    n = max(1, n_treatments)
    if name in ("fitness",):
        return (12.0, 8.0)
    if name in ("descriptors", "start_end"):
        return (16.0, 9.0)
    if name == "pareto":
        cols = min(4, n)
        return (3.6 * cols, 3.2 * math.ceil(n / cols) + 0.4)
    if name == "transitions":
        return (15.0, 4.0 * max(1, n_transitions) + 0.4)
    if name == "exaptation":
        return (14.0, 4.8)
    if name == "qd":
        return (14.0, 4.8)
    if name == "robots":
        per_row = min(2, n)
        return (2.4 * SAMPLES_PER_FRONT * per_row, 2.6 * math.ceil(n / per_row) + 0.4)
    raise ValueError(f"unknown figure {name!r}")


def _new_figure(name: str, data: ExperimentData, layout: str | None = "constrained") -> Figure:
    n_transitions = int(data.treatments["switch_at"].notna().sum())
    size = figure_size(name, len(data.treatments), n_transitions)
    return plt.figure(figsize=size, dpi=DPI, layout=layout)


def _fit_suptitle(fig: Figure) -> None:
    """Wrap the figure's title onto more lines where it is wider than the figure (a pareto
    figure of one treatment is one panel wide): the layout then makes room for it."""
    title = fig._suptitle  # matplotlib keeps the suptitle's Text here
    if title is None or not title.get_text():
        return
    width = title.get_window_extent(fig.canvas.get_renderer()).width
    room = 0.94 * fig.bbox.width
    if width > room:
        text = title.get_text().replace("\n", " ")
        title.set_text(textwrap.fill(text, max(12, int(len(text) * room / width))))


def save(fig: Figure, out_dir: Path, name: str, caption: str) -> FigureFile:
    """Write ``fig`` as ``out_dir/name.png`` and ``.svg`` and close it."""
    out_dir.mkdir(parents=True, exist_ok=True)
    png, svg = out_dir / f"{name}.png", out_dir / f"{name}.svg"
    _fit_suptitle(fig)
    fig.savefig(png, dpi=DPI)
    fig.set_layout_engine("none")  # keep the layout just computed; do not redo it for the SVG
    fig.savefig(svg)
    width, height = fig.get_size_inches() * DPI
    plt.close(fig)
    size = (int(round(width)), int(round(height)))
    return FigureFile(name, TITLES[name], caption, png, svg, size)


# ---- colours -----------------------------------------------------------------------------------
def treatment_colors(treatments: pd.DataFrame) -> dict[str, tuple]:
    """A colour per treatment name: hue by environment, shade by log stiffness."""
    log_e = np.log10(treatments["stiffness_mpa"].astype(float))
    low, high = min(log_e.min(), -3.0), max(log_e.max(), 1.0)
    colors = {}
    for name, env, value in zip(treatments["name"], treatments["environment"], log_e, strict=True):
        shade = 0.35 + 0.6 * (value - low) / (high - low)
        colors[name] = plt.get_cmap(environment_cmap(env))(shade)
    return colors


def environment_cmap(environment: str) -> str:
    """The colormap of a treatment environment: a world's own (``sim.worlds``), the
    transitions' in the registry's order of them, grey for an unknown one."""
    if environment in environments.names():
        return environments.get(environment).colormap
    transitions = [e for e in environments.environments() if environments.is_transition(e)]
    if environment in transitions:
        return TRANSITION_CMAPS[transitions.index(environment) % len(TRANSITION_CMAPS)]
    return "Greys"


def environment_title(environment: str) -> str:
    """``land``; ``land \u2192 water`` for a transition."""
    return " \u2192 ".join(environment.split(environments.TRANSITION))


def _grid(fig: Figure, n: int, cols: int, **kwargs) -> list[Axes]:
    rows = math.ceil(n / cols)
    axes = fig.subplots(rows, cols, squeeze=False, **kwargs).ravel()
    for ax in axes[n:]:
        ax.set_visible(False)
    return list(axes[:n])


# ---- fitness over generations ------------------------------------------------------------------
def _curve(ax: Axes, curve: pd.DataFrame, color, label: str, style: str = "-") -> None:
    ax.plot(curve["generation"], curve["mean"], style, color=color, label=label, lw=1.6)
    ax.fill_between(curve["generation"], curve["low"], curve["high"], color=color, alpha=0.2, lw=0)
    ax.xaxis.set_major_locator(MaxNLocator(integer=True))  # generations: no tick at 0.25


def _switch_line(ax: Axes, switch_at) -> None:
    if pd.notna(switch_at):
        ax.axvline(int(switch_at) - 0.5, color="0.3", ls="--", lw=1)
        ax.annotate(
            "switch",
            (int(switch_at) - 0.5, 1.0),
            xycoords=("data", "axes fraction"),
            xytext=(3, -12),
            textcoords="offset points",
            fontsize=8,
            color="0.3",
        )


GRADUAL_PANEL = "during a gradual switch"  # the fitness panel of the compound worlds


def world_panel(environment: str) -> str:
    """The fitness panel of a world: its own, one for all compound worlds of a gradual switch."""
    return GRADUAL_PANEL if environments.is_compound(environment) else environment


def fitness_figure(data: ExperimentData, curves: pd.DataFrame, out_dir: Path) -> FigureFile:
    """Best distance over generations per treatment: mean over repetitions, 95% CI band;
    one panel per world, each with its own distance axis (distances of different worlds are
    not comparable): a transition's curve goes on in its new world's panel."""
    fig = _new_figure("fitness", data)
    panels = curves["environment"].map(world_panel)
    names = list(dict.fromkeys(panels))
    order = environments.environments()
    names.sort(key=lambda w: order.index(w) if w in order else len(order))
    axes = _grid(fig, len(names), min(2, len(names)))
    colors = treatment_colors(data.treatments)
    switches = dict(zip(data.treatments["name"], data.treatments["switch_at"], strict=True))
    for ax, panel in zip(axes, names, strict=True):
        in_panel = curves[panels == panel]
        shown = [name for name in data.treatment_names if (in_panel["treatment"] == name).any()]
        for name in shown:
            _curve(ax, in_panel[in_panel["treatment"] == name], colors[name], name)
        for switch_at in sorted({int(switches[n]) for n in shown if pd.notna(switches[n])}):
            _switch_line(ax, switch_at)
        ax.set_title(f"in {panel}" if panel != GRADUAL_PANEL else panel)
        ax.set_xlabel("generation")
        ax.set_ylabel("best distance (voxel lengths)")
        ax.set_ylim(bottom=0)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8, loc="upper left")
    fig.suptitle(f"Fitness over generations: mean of {_reps(data)} with 95% t interval")
    return save(
        fig,
        out_dir,
        "fitness",
        "Best distance (voxel lengths) of the population at each generation, mean over "
        "repetitions with its 95% t confidence band (clipped at 0); one panel per world, each "
        "with its own axis: a transition's curve goes on in its new world's panel.",
    )


def _reps(data: ExperimentData) -> str:
    counts = data.runs.groupby("treatment").size()
    low, high = int(counts.min()), int(counts.max())
    text = f"{low}" if low == high else f"{low}-{high}"
    return f"{text} repetition{'s' if high > 1 else ''}"


# ---- descriptors of the final populations ------------------------------------------------------
def _boxes(ax: Axes, samples: Sequence[np.ndarray], colors: Sequence, positions=None) -> None:
    positions = np.arange(len(samples)) if positions is None else np.asarray(positions)
    kept = [(p, s, c) for p, s, c in zip(positions, samples, colors, strict=True) if len(s)]
    if not kept:
        return
    parts = ax.boxplot(
        [s for _, s, _ in kept],
        positions=[p for p, _, _ in kept],
        widths=0.6,
        patch_artist=True,
        showfliers=False,
        medianprops={"color": "black"},
    )
    for patch, (_, _, color) in zip(parts["boxes"], kept, strict=True):
        patch.set_facecolor(color)
        patch.set_alpha(0.55)
    jitter = np.random.default_rng(0)
    for p, s, c in kept:
        x = p + jitter.uniform(-0.18, 0.18, len(s))
        ax.scatter(x, s, s=7, color=c, edgecolor="black", linewidth=0.3, zorder=3)


def from_zero(ax: Axes) -> None:
    """The y axis from 0 when every value plotted is at least 0, so that a change in the third
    decimal does not fill the panel (issue 59.3); axes of signed values are left as drawn."""
    low, _ = ax.dataLim.intervaly
    if np.isfinite(low) and low >= 0:
        ax.set_ylim(bottom=0)


def _brackets(ax: Axes, tests: pd.DataFrame, position: dict[str, int]) -> None:
    """Brackets with stars over the significant pairs (Bonferroni-adjusted p < ALPHA); where no
    pair was tested (fewer than ``MIN_TESTED_RUNS`` runs a group), says so instead."""
    if not tests.empty and tests["p_bonferroni"].isna().all():
        n = int(min(tests["n_a"].min(), tests["n_b"].min()))
        ax.set_title(f"{ax.get_title()}\n{few_runs_text(n)}", fontsize=9)
        return
    significant = tests[tests["p_bonferroni"] < ALPHA].sort_values("p_bonferroni")
    if significant.empty:
        ax.set_title(f"{ax.get_title()}\nno pair differs (p<{ALPHA:g}, Bonferroni)", fontsize=9)
        return
    low, high = ax.get_ylim()
    step = 0.07 * (high - low)
    for level, row in enumerate(significant.head(MAX_BRACKETS).itertuples()):
        x1, x2 = sorted((position[row.a], position[row.b]))
        y = high + step * (level + 0.3)
        ax.plot([x1, x1, x2, x2], [y - step * 0.25, y, y, y - step * 0.25], color="0.2", lw=0.8)
        ax.text((x1 + x2) / 2, y, row.significance, ha="center", va="bottom", fontsize=8)
    ax.set_ylim(low, high + step * (min(len(significant), MAX_BRACKETS) + 0.8))
    if len(significant) > MAX_BRACKETS:
        ax.text(
            0.01,
            0.98,
            f"+{len(significant) - MAX_BRACKETS} more (see table)",
            transform=ax.transAxes,
            va="top",
            fontsize=7,
            color="0.35",
        )


def descriptors_figure(data: ExperimentData, tests: pd.DataFrame, out_dir: Path) -> FigureFile:
    """Box plots of each trait's run values (population means, one per run) per treatment at
    its display generation, with brackets over significantly different pairs compared at
    that generation; the last panel is the best distance of each run."""
    fig = _new_figure("descriptors", data)
    axes = _grid(fig, len(traits.names()) + 1, 4)
    names = data.treatment_names
    colors = treatment_colors(data.treatments)
    position = {name: k for k, name in enumerate(names)}
    shown = {name: data.display_generation(name) for name in names}
    values = data.display_run_values()
    labels = traits.labels()
    for ax, metric in zip(axes, [*traits.names(), "best_distance"], strict=True):
        samples = [values.loc[values["treatment"] == n, metric].dropna().to_numpy(float) for n in names]
        _boxes(ax, samples, [colors[n] for n in names])
        ax.set_xticks(range(len(names)), names, rotation=60, ha="right", fontsize=7)
        ax.set_title(labels[metric] + " (per run)", fontsize=10)
        ax.grid(axis="y", alpha=0.3)
        from_zero(ax)
        chosen = tests[(tests["metric"] == metric) & (tests["comparison"] == "between treatments")]
        matched = np.array(
            [
                shown[a] == g == shown[b]
                for a, b, g in zip(chosen["a"], chosen["b"], chosen["generation"], strict=True)
            ],
            dtype=bool,
        )
        _brackets(ax, chosen.loc[matched], position)
    fig.suptitle(
        f"Run values across treatments at {_generations_text(data)} "
        "(Mann-Whitney U over runs, Bonferroni; * p<0.05, ** p<0.01, *** p<0.001)"
    )
    return save(
        fig,
        out_dir,
        "descriptors",
        "One value per run (its population's mean of the descriptor; the last panel: its "
        "best distance), per treatment, static treatments at their common last generation and "
        "transitions at their last. Brackets mark pairs compared at that generation whose "
        "Bonferroni-adjusted Mann-Whitney p is below 0.05.",
    )


def _generations_text(data: ExperimentData) -> str:
    """ "generation G" (or "generations G1 (static), G2 (name), ...") of the display."""
    shown = {name: data.display_generation(name) for name in data.treatment_names}
    distinct = sorted({g for g in shown.values() if g is not None})
    if len(distinct) <= 1:
        return f"generation {distinct[0] if distinct else '-'}"
    static = data.static_generation
    others = [f"{g} ({n})" for n, g in shown.items() if g != static and g is not None]
    return "generations " + ", ".join([f"{static} (static)", *others])


# ---- Pareto fronts -----------------------------------------------------------------------------
def pareto_front(frame: pd.DataFrame) -> pd.DataFrame:
    """Rows of ``frame`` not dominated on (max distance, min active_share), sorted by
    active_share; duplicates of a front point are all kept."""
    valid = frame.dropna(subset=["distance", "active_share"])
    if valid.empty:
        return valid
    objectives = np.column_stack([-valid["distance"].to_numpy(float), valid["active_share"].to_numpy(float)])
    front = valid[non_dominated_sort(objectives) == 0]
    return front.sort_values(["active_share", "distance"])


def pareto_figure(data: ExperimentData, out_dir: Path) -> FigureFile:
    """Populations at each treatment's display generation (all repetitions pooled) in the
    distance / active-share plane, one panel per treatment, with the aggregated
    non-dominated front drawn as a staircase."""
    fig = _new_figure("pareto", data)
    names = data.treatment_names
    axes = _grid(fig, len(names), min(4, len(names)), sharex=True)
    colors = treatment_colors(data.treatments)
    final = data.display_populations()
    for ax, name in zip(axes, names, strict=True):
        frame = final[final["treatment"] == name]
        ax.scatter(
            frame["active_share"],
            frame["distance"],
            s=14,
            color=colors[name],
            edgecolor="0.3",
            linewidth=0.3,
            alpha=0.7,
            label="final populations",
        )
        front = pareto_front(frame)
        if not front.empty:
            ax.step(
                front["active_share"],
                front["distance"],
                where="post",
                color="black",
                lw=1.2,
                label="non-dominated front",
            )
            ax.scatter(
                front["active_share"],
                front["distance"],
                s=26,
                facecolor="none",
                edgecolor="black",
                linewidth=0.9,
            )
        ax.set_title(f"{name} (generation {data.display_generation(name)})", fontsize=10)
        ax.set_xlim(-0.05, 1.05)
        ax.set_xlabel("active share (energy)")
        ax.set_ylabel("distance (voxel lengths)")
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=7, loc="upper left")
    fig.suptitle("Aggregated Pareto fronts: distance (max) vs active share (min)")
    return save(
        fig,
        out_dir,
        "pareto",
        "Individuals of the final populations of all repetitions in the objective "
        "plane distance (maximised) vs share of active voxels (minimised); the black "
        "staircase is their non-dominated front.",
    )


# ---- transitions against their static controls -------------------------------------------------
def transition_controls(treatments: pd.DataFrame) -> dict[str, list[str]]:
    """For each transition treatment, its static controls: the treatments at the same
    stiffness in each of its two environments (when present)."""
    controls = {}
    for row in treatments[treatments["switch_at"].notna()].itertuples():
        same = treatments[np.isclose(treatments["stiffness_mpa"], row.stiffness_mpa)]
        controls[row.name] = [
            n for env in row.environment.split("-") for n in same.loc[same["environment"] == env, "name"]
        ]
    return controls


def _transition_curves(
    axes, curves: pd.DataFrame, treatments: pd.DataFrame, name: str, static: list[str], colors: dict
) -> None:
    """A transition's fitness in two panels, one per world, each with its own axis: in the
    first, its generations before the switch beside the static control of that world; in the
    second, the rest (a gradual switch's compound generations too) beside the other control."""
    first, second = treatments.loc[name, "environment"].split(environments.TRANSITION)
    switch_at = treatments.loc[name, "switch_at"]
    own = curves[curves["treatment"] == name]
    before = own["generation"] < switch_at
    for ax, world, part in ((axes[0], first, own[before]), (axes[1], second, own[~before])):
        _curve(ax, part, colors[name], name, ".-")  # dots: a part of one generation shows too
        for control in (c for c in static if treatments.loc[c, "environment"] == world):
            _curve(ax, curves[curves["treatment"] == control], colors[control], control, "--")
        _switch_line(ax, switch_at)
        ax.set(xlabel="generation", ylabel=f"best distance in {world}", title=f"{name} in {world}")
        ax.set_ylim(bottom=0)
        ax.legend(fontsize=8, loc="upper left")
        ax.grid(alpha=0.3)


def transitions_figure(
    data: ExperimentData, curves: pd.DataFrame, tests: pd.DataFrame, out_dir: Path
) -> FigureFile | None:
    """Per transition treatment: its fitness curve against its static controls, and its
    runs' best distance (the primary measure) and active share (population mean) against
    theirs at the generation they are compared at. None without a transition treatment."""
    controls = transition_controls(data.treatments)
    if not controls:
        return None
    fig = _new_figure("transitions", data)
    axes = fig.subplots(len(controls), 4, squeeze=False)
    colors = treatment_colors(data.treatments)
    treatments = data.treatments.set_index("name")
    for row, (name, static) in zip(axes, controls.items(), strict=True):
        group = [name, *static]
        _transition_curves(row[:2], curves, treatments, name, static, colors)
        at = {m: data.end_generation(name) if m == name else data.pair_generation(name, m) for m in group}
        for ax, metric in zip(row[2:], ("best_distance", "active_share"), strict=True):
            samples = []
            for m in group:
                values = data.run_values(at[m]) if at[m] is not None else data.run_values(-1)
                samples.append(values.loc[values["treatment"] == m, metric].dropna().to_numpy(float))
            _boxes(ax, samples, [colors[m] for m in group])
            ax.set_xticks(range(len(group)), group, rotation=20, ha="right", fontsize=8)
            ax.set_title(f"{traits.labels()[metric]} per run, generation {at[name]}", fontsize=10)
            ax.grid(axis="y", alpha=0.3)
            from_zero(ax)
            chosen = tests[
                (tests["metric"] == metric)
                & (tests["comparison"] == "between treatments")
                & ((tests["a"] == name) | (tests["b"] == name))
                & tests["a"].isin(group)
                & tests["b"].isin(group)
            ]
            _brackets(ax, chosen, {m: k for k, m in enumerate(group)})
    fig.suptitle("Environment transitions against static controls (same stiffness)")
    return save(
        fig,
        out_dir,
        "transitions",
        "Each transition treatment against the static treatments of the same stiffness "
        "in its first and second environment: best distance over generations (mean, "
        "95% CI; dashed line: the switch), a panel per world with its own axis (the transition "
        "before its switch beside its first world's control, after it beside its second's), "
        "and each run's best distance (the primary measure) "
        "and population mean of active share at the generation the pair is compared at (the "
        "last both stored). Stars: the pairwise tests (secondary; the findings table holds "
        "the headline tests).",
    )


# ---- robots sampled from the fronts ------------------------------------------------------------
def front_samples(front: pd.DataFrame, k: int = SAMPLES_PER_FRONT) -> pd.DataFrame:
    """Up to ``k`` distinct individuals spread along a front (sorted by active share): the
    farthest-travelling, the most economical, and ones in between. Robots that hardly moved
    (under ``MOVED_SHARE`` of the front's best distance) are left out when others moved."""
    unique = front.drop_duplicates("individual_id")
    moving = unique["distance"] > MOVED_SHARE * unique["distance"].max()
    if moving.any():
        unique = unique[moving]
    if len(unique) <= k:
        return unique.sort_values("distance", ascending=False)
    picks = np.unique(np.round(np.linspace(len(unique) - 1, 0, k)).astype(int))[::-1]
    return unique.iloc[picks]


def robots_figure(
    data: ExperimentData, phenotypes: Callable[[list[int]], dict[int, Any]], out_dir: Path
) -> FigureFile:
    """3-D renders of robots sampled from each treatment's aggregated front (active voxels
    red, passive cyan), with their distance and active share. ``phenotypes(ids)`` gives the
    stored individuals' phenotypes (``Robots.phenotypes``, which ``service.reports.report`` binds to
    a database)."""
    final = data.display_populations()
    names = data.treatment_names
    samples = {n: front_samples(pareto_front(final[final["treatment"] == n])) for n in names}
    ids = [int(i) for s in samples.values() for i in s["individual_id"]]
    bodies = {i: p.body for i, p in phenotypes(ids).items()}
    fig = _new_figure("robots", data, layout=None)  # fixed margins: 3-D axes need no solver
    per_row = min(2, len(names))
    top = 1.0 - 0.75 / fig.get_size_inches()[1]
    grid = fig.add_gridspec(
        math.ceil(len(names) / per_row),
        SAMPLES_PER_FRONT * per_row,
        left=0.0,
        right=1.0,
        bottom=0.0,
        top=top,
        wspace=0.0,
        hspace=0.12,
    )
    for t, name in enumerate(names):
        row, col0 = divmod(t, per_row)
        picks = list(samples[name].itertuples())
        for s in range(SAMPLES_PER_FRONT):
            ax = fig.add_subplot(grid[row, col0 * SAMPLES_PER_FRONT + s], projection="3d")
            if s >= len(picks):
                ax.set_axis_off()
                continue
            pick = picks[s]
            title = (f"{name}\n" if s == 0 else "\n") + (
                f"#{pick.individual_id}  d={pick.distance:.2f}  a={pick.active_share:.2f}"
            )
            body = bodies.get(int(pick.individual_id), np.zeros((1, 1, 1)))
            draw_body(ax, body, title, side=max(body.shape))
    if per_row > 1:  # a rule between the two treatments of a row
        fig.add_artist(plt.Line2D([0.5, 0.5], [0.0, top], color="0.75", lw=0.8))
    _material_legend(fig)
    fig.suptitle("Robots sampled from the aggregated Pareto fronts (d: distance, a: active share)")
    return save(
        fig,
        out_dir,
        "robots",
        "Robots from each treatment's aggregated non-dominated front, from the "
        "farthest-travelling to the most economical; active voxels red, passive cyan.",
    )


def _material_legend(fig: Figure) -> None:
    fig.legend(
        handles=[Patch(color=ACTIVE_COLOR, label="active"), Patch(color=PASSIVE_COLOR, label="passive")],
        loc="lower right",
        fontsize=8,
        ncols=2,
    )


# ---- start vs end of evolution -----------------------------------------------------------------
def _end_values(data: ExperimentData) -> pd.DataFrame:
    """Each treatment's run values at its end generation."""
    return _values_at(data, {name: data.end_generation(name) for name in data.treatment_names})


def _start_values(data: ExperimentData) -> pd.DataFrame:
    """Each treatment's run values at its first generation wholly in its final world (0; a
    transition's arrival): start and end in one world."""
    arrivals = {row["name"]: arrival_generation(row) for _, row in data.treatments.iterrows()}
    return _values_at(data, arrivals)


def _values_at(data: ExperimentData, generations: dict[str, int | None]) -> pd.DataFrame:
    parts = [data.run_values(-1)]
    for name, generation in generations.items():
        if generation is not None:
            values = data.run_values(generation)
            parts.append(values[values["treatment"] == name])
    return pd.concat(parts, ignore_index=True)


def start_end_figure(data: ExperimentData, tests: pd.DataFrame, out_dir: Path) -> FigureFile:
    """Each trait at generation 0 and at the treatment's end generation: mean of the per-run
    population means with 95% t intervals, stars where start and end differ."""
    fig = _new_figure("start_end", data)
    axes = _grid(fig, len(traits.names()), 4)
    names = data.treatment_names
    colors = treatment_colors(data.treatments)
    start, end = _start_values(data), _end_values(data)
    x = np.arange(len(names))
    for ax, trait in zip(axes, traits.names(), strict=True):
        for frame, offset, label, filled in ((start, -0.15, "start", False), (end, 0.15, "end", True)):
            table = ci_table(frame, trait, "treatment")
            table = table.set_index("treatment").reindex(names)
            for k, name in enumerate(names):
                mean, low, high = table.loc[name, ["mean", "low", "high"]]
                ax.errorbar(
                    x[k] + offset,
                    mean,
                    yerr=[[mean - low], [high - mean]],
                    fmt="o",
                    color=colors[name],
                    mfc=colors[name] if filled else "white",
                    capsize=2,
                    ms=5,
                    label=label if k == 0 else None,
                )
        chosen = tests[(tests["metric"] == trait) & (tests["comparison"] == "start vs end")]
        _start_end_marks(ax, chosen, names)
        ax.set_xticks(x, names, rotation=60, ha="right", fontsize=7)
        ax.set_title(traits.labels()[trait], fontsize=10)
        ax.grid(axis="y", alpha=0.3)
        from_zero(ax)
    axes[0].legend(fontsize=8, loc="best")
    fig.suptitle(
        "Start (open, generation 0) vs end (filled, last generation) of evolution: "
        "mean over repetitions, 95% t interval"
    )
    return save(
        fig,
        out_dir,
        "start_end",
        "Each descriptor at the start (open markers, generation 0; a transition's first "
        "generation in its final world) and at the end (filled, last generation) of "
        "evolution: mean of the per-run population means "
        "with 95% t intervals. Stars: Bonferroni-adjusted Wilcoxon signed-rank p (each run "
        "against itself) "
        "between start and end below 0.05.",
    )


def _start_end_marks(ax: Axes, tests: pd.DataFrame, names: Sequence[str]) -> None:
    marks = dict(zip(tests["a"].str.removesuffix(" start"), tests["significance"], strict=True))
    for k, name in enumerate(names):
        mark = marks.get(name, "")
        if mark and mark not in ("ns", "n/a"):
            ax.annotate(mark, (k, 1.0), xycoords=("data", "axes fraction"), ha="center", va="top", fontsize=9)
