"""Each figure on a real tiny experiment: a non-empty PNG of the expected size and an SVG."""

from __future__ import annotations

import dataclasses

import pytest
from PIL import Image

from softevo.analysis import figures
from softevo.analysis.exaptation import exaptation_figure, run_statistics
from softevo.analysis.qd import qd_curves, qd_figure
from softevo.analysis.stats_tables import fitness_curves, statistics_table
from softevo.service.reports.report import exaptation_data, qd_data, stored_robots

# 2 treatments (one transition): hand-computed from figures.figure_size at 100 dpi
EXPECTED_PX = {
    "fitness": (1200, 800),
    "descriptors": (1600, 900),
    "pareto": (720, 360),  # 2 panels of 3.6 x 3.2 in, + 0.4 in for the title
    "transitions": (1500, 440),  # one transition row of 4 in, + 0.4 in
    "robots": (1440, 300),  # 2 treatments x 3 robots of 2.4 in, one row of 2.6 in + 0.4 in
    "start_end": (1600, 900),
    "exaptation": (1400, 480),
    "qd": (1400, 480),
}


@pytest.fixture(scope="module")
def inputs(tiny_data):
    return tiny_data, statistics_table(tiny_data), fitness_curves(tiny_data)


def _make(name, data, tests, curves, engine, out):
    return {
        "fitness": lambda: figures.fitness_figure(data, curves, out),
        "descriptors": lambda: figures.descriptors_figure(data, tests, out),
        "pareto": lambda: figures.pareto_figure(data, out),
        "transitions": lambda: figures.transitions_figure(data, curves, tests, out),
        "robots": lambda: figures.robots_figure(data, stored_robots(engine).phenotypes, out),
        "start_end": lambda: figures.start_end_figure(data, tests, out),
        "exaptation": lambda: _exaptation(data, engine, out),
        "qd": lambda: qd_figure(data, qd_curves(data, qd_data(engine, data)), out),
    }[name]()


def _exaptation(data, engine, out):
    found = exaptation_data(engine, data)
    return exaptation_figure(data, found, run_statistics(data, found), out)


@pytest.mark.parametrize("name", figures.FIGURES)
def test_figure_writes_png_and_svg_of_the_expected_size(name, inputs, tiny, tmp_path):
    data, tests, curves = inputs
    made = _make(name, data, tests, curves, tiny.engine, tmp_path)
    assert made.name == name and made.title == figures.TITLES[name]
    assert made.png == tmp_path / f"{name}.png" and made.svg == tmp_path / f"{name}.svg"
    assert made.png.stat().st_size > 10_000
    with Image.open(made.png) as image:
        assert image.format == "PNG"
        assert image.size == made.size_px == EXPECTED_PX[name]
        # not a blank canvas: the picture has many distinct colours
        assert len(image.convert("RGB").getcolors(maxcolors=1 << 20)) > 50
    svg = made.svg.read_text(encoding="utf-8")
    assert "<svg" in svg and svg.rstrip().endswith("</svg>")


def test_no_transition_figure_without_a_transition_treatment(inputs, tmp_path):
    data, tests, curves = inputs
    static = dataclasses.replace(data, treatments=data.treatments[data.treatments["switch_at"].isna()])
    assert figures.transitions_figure(static, curves, tests, tmp_path) is None
    assert not list(tmp_path.iterdir())


def test_transition_controls_are_the_same_stiffness_in_each_environment(tiny_data):
    assert figures.transition_controls(tiny_data.treatments) == {"water-land S3": ["land S3"]}


def test_pareto_front_is_the_non_dominated_staircase():
    import pandas as pd

    frame = pd.DataFrame(
        {
            "individual_id": [1, 2, 3, 4, 5],
            "distance": [5.0, 3.0, 4.0, 1.0, 0.0],
            "active_share": [0.9, 0.2, 0.5, 0.6, 0.0],
        }
    )
    front = figures.pareto_front(frame)
    assert front["individual_id"].tolist() == [5, 2, 3, 1]  # 4 is dominated by 2 and 3
    picks = figures.front_samples(front, 3)
    assert picks["individual_id"].tolist() == [1, 3, 2]  # the robot that never moved is left out


def test_one_treatment_pareto_title_fits_the_figure(inputs, tmp_path, monkeypatch):
    """A pareto figure of one treatment is one panel wide: its title wraps instead of running
    off both edges (issue 49.15)."""
    data, _, _ = inputs
    one = data.treatment_names[:1]
    single = dataclasses.replace(data, treatments=data.treatments[data.treatments["name"].isin(one)])
    kept = []
    monkeypatch.setattr(figures.plt, "close", kept.append)  # keep the saved figure to measure it
    figures.pareto_figure(single, tmp_path)
    (fig,) = kept
    box = fig._suptitle.get_window_extent(fig.canvas.get_renderer())
    assert 0 <= box.x0 and box.x1 <= fig.bbox.width


def test_fitness_ticks_are_whole_generations(inputs, tmp_path, monkeypatch):
    """A run of a few generations gets ticks at whole generations, not at 0.25 (issue 49.15)."""
    data, _, curves = inputs
    ticks = []
    original = figures.save

    def checked(fig, out_dir, name, caption):
        fig.canvas.draw()
        ticks.extend(t for ax in fig.axes if ax.get_visible() for t in ax.get_xticks())
        return original(fig, out_dir, name, caption)

    monkeypatch.setattr(figures, "save", checked)
    figures.fitness_figure(data, curves, tmp_path)
    assert ticks and all(float(t).is_integer() for t in ticks)


def test_the_fitness_figure_has_a_panel_per_world(inputs, tmp_path, monkeypatch):
    """Water and land distances never share an axis: the water-land transition's curve is in
    the water panel before its switch and in the land panel after it (issue 49.4)."""
    data, _, curves = inputs
    kept = []
    monkeypatch.setattr(figures.plt, "close", kept.append)
    figures.fitness_figure(data, curves, tmp_path)
    (fig,) = kept
    panels = {ax.get_title(): ax for ax in fig.axes if ax.get_visible() and ax.get_title()}
    assert set(panels) == {"in land", "in water"}
    switch_at, generations = 2, 3  # tests/analysis/conftest.py
    for title, ax in panels.items():
        transition = next(line.get_xdata() for line in ax.get_lines() if line.get_label() == "water-land S3")
        expected = range(switch_at) if title == "in water" else range(switch_at, generations)
        assert list(transition) == list(expected)
    assert "land S3" in {line.get_label() for line in panels["in land"].get_lines()}
    assert "land S3" not in {line.get_label() for line in panels["in water"].get_lines()}


def test_the_transitions_figure_plots_each_world_on_its_own_axis(inputs, tmp_path, monkeypatch):
    """The transition before its switch beside nothing of the other world, after it beside
    its new world's control (issue 49.4: fitness plots split by world)."""
    data, tests, curves = inputs
    kept = []
    monkeypatch.setattr(figures.plt, "close", kept.append)
    figures.transitions_figure(data, curves, tests, tmp_path)
    (fig,) = kept
    panels = {ax.get_title(): ax for ax in fig.axes if ax.get_title().startswith("water-land S3 in")}
    assert set(panels) == {"water-land S3 in water", "water-land S3 in land"}

    def lines(title):
        return {line.get_label(): list(line.get_xdata()) for line in panels[title].get_lines()}

    assert lines("water-land S3 in water")["water-land S3"] == [0, 1]
    assert "land S3" not in lines("water-land S3 in water")
    assert lines("water-land S3 in land")["water-land S3"] == [2]
    assert lines("water-land S3 in land")["land S3"] == [0, 1, 2]


def test_a_descriptor_axis_starts_at_zero_so_a_tiny_change_looks_tiny():
    """Issue 59.3: each descriptor's y axis stretched over a change in the third decimal."""
    import matplotlib.pyplot as plt

    from softevo.analysis.figures import from_zero

    fig, (shares, signed) = plt.subplots(1, 2)
    shares.plot([0, 1], [0.501, 0.503])
    from_zero(shares)
    assert shares.get_ylim()[0] == 0 and shares.get_ylim()[1] >= 0.503
    signed.plot([0, 1], [-0.2, 0.3])
    before = signed.get_ylim()
    from_zero(signed)
    assert signed.get_ylim() == before  # values below 0: left as drawn
    plt.close(fig)
