"""One registration reaches every room: a trait and a physics model, each registered once
(a deployment's plugin, ``SOFTEVO_PLUGINS``), are stored in SQL, answered by REST, shown by
the dashboard and reported, with nothing else written for them (issue 48)."""

from __future__ import annotations

import json
from pathlib import Path

import httpx
import pytest
from sqlalchemy import create_engine, select

from softevo.evolution.genotype import EncodingConfig, Genotype, develop
from softevo.service.storage.models import EvaluationRow, IndividualRow, TreatmentRow
from tests.support import softevo_process

ROOT = Path(__file__).resolve().parents[4]


def height(phenotype) -> float:
    """The plugin's trait, recomputed here (importing the plugin would register it in this
    process, and every other test of the session would see a trait more)."""
    return float(phenotype.body.any(axis=(0, 1)).sum())
PLUGIN = {"SOFTEVO_PLUGINS": "tests.service.plugin_height", "PYTHONPATH": str(ROOT)}
WORKSPACE = (4, 4, 4)


def stored_run(folder: Path, plugin: dict, *options: str) -> tuple[Path, str]:
    """A tiny run (``softevo run`` with ``options``) stored with ``plugin`` loaded: (folder,
    database URL)."""
    url = f"sqlite:///{folder / 'run.db'}"
    done = softevo_process("run", "--stiffness", "1", "--generations", "2", "--cycles", "1", *options,
                           "--db", url, env=plugin, cwd=ROOT)
    assert done.returncode == 0, done.stderr
    return folder, url


@pytest.fixture(scope="module")
def height_db(tmp_path_factory) -> tuple[Path, str]:
    return stored_run(tmp_path_factory.mktemp("height"), PLUGIN, "--env", "land", "--population", "4",
                      "--workspace", ",".join(map(str, WORKSPACE)), "--seed", "5")


def stored_heights(url: str) -> dict[int, tuple[float | None, float]]:
    """{individual id: (stored height, height of its genome developed again)}."""
    engine = create_engine(url)
    evaluations, individuals = EvaluationRow.__table__, IndividualRow.__table__
    with engine.connect() as conn:
        rows = conn.execute(
            select(individuals.c.id, individuals.c.genome, evaluations.c.descriptors)
            .join(evaluations, evaluations.c.individual_id == individuals.c.id)
        ).all()
    engine.dispose()
    encoding = EncodingConfig(workspace=WORKSPACE)
    return {
        int(i): ((descriptors or {}).get("height"), height(develop(Genotype.from_dict(genome), encoding)))
        for i, genome, descriptors in rows
    }


def test_a_registered_trait_is_stored_in_sql_as_measured(height_db):
    heights = stored_heights(height_db[1])
    assert len(heights) >= 8  # two generations of four
    assert all(stored == again for stored, again in heights.values())
    assert len({again for _, again in heights.values()}) >= 1 and all(h >= 1 for _, h in heights.values())


def test_a_registered_trait_reaches_rest_the_dashboard_and_the_report(height_db, start_server, open_page):
    folder, url = height_db
    individual, (expected, _) = next(iter(stored_heights(url).items()))
    base = start_server("dashboard", url, env=PLUGIN)
    answer = httpx.get(f"{base}/individuals/{individual}", timeout=30).json()
    assert answer["evaluations"][-1]["traits"]["height"] == expected
    assert answer["descriptors"]["height"] == expected

    page = open_page(base).page
    page.goto(f"{base}/dashboard/individuals/{individual}")
    page.get_by_text("height (voxels)").first.wait_for(timeout=30_000)
    assert json.loads(page.locator("body").get_attribute("data-traits"))["height"] == "height (voxels)"

    out = folder / "report"
    done = softevo_process("report", "latest", "--db", url, "--out", str(out), "--no-animation", "--quiet",
                           env=PLUGIN, cwd=ROOT)
    assert done.returncode == 0, done.stderr
    assert "height (voxels)" in (out / "report.md").read_text()
    summary = (out / "treatment_summary.csv").read_text()
    assert "\nheight," in summary


def test_without_the_plugin_the_trait_is_unknown_and_old_rows_still_read(height_db):
    """A process that did not load the plugin reads the same database without the trait."""
    folder, url = height_db
    done = softevo_process("export", "latest", "--db", url, "--out", str(folder / "plain"), cwd=ROOT)
    assert done.returncode == 0, done.stderr
    header = (folder / "plain" / "individuals.csv").read_text().splitlines()[0].split(",")
    assert "height" not in header
    assert "shape_entropy" in header
    done = softevo_process(
        "export", "latest", "--db", url, "--out", str(folder / "plugged"), env=PLUGIN, cwd=ROOT
    )
    assert done.returncode == 0, done.stderr
    header = (folder / "plugged" / "individuals.csv").read_text().splitlines()[0].split(",")
    assert "height" in header


def test_a_plugin_that_cannot_be_imported_is_one_line():
    done = softevo_process("status", env={"SOFTEVO_PLUGINS": "no_such_module_here"})
    assert done.returncode == 2
    assert done.stderr.strip() == (
        "error: SOFTEVO_PLUGINS: cannot import 'no_such_module_here' (No module named 'no_such_module_here')"
    )


MODEL_PLUGIN = {"SOFTEVO_PLUGINS": "tests.service.plugin_model", "PYTHONPATH": str(ROOT)}


@pytest.fixture(scope="module")
def model_db(tmp_path_factory) -> tuple[Path, str]:
    return stored_run(tmp_path_factory.mktemp("model"), MODEL_PLUGIN, "--env", "water", "--population", "3",
                      "--workspace", "3,3,3", "--model", "soft-fork")


def test_a_registered_model_is_run_and_stored(model_db):
    engine = create_engine(model_db[1])
    with engine.connect() as conn:
        (settings,) = conn.execute(select(TreatmentRow.__table__.c.settings)).scalars()
        stable = conn.execute(select(EvaluationRow.__table__.c.stable)).scalars().all()
    engine.dispose()
    assert settings["model"] == "soft-fork"
    assert len(stable) >= 6 and any(stable)  # the worker processes simulated it
    unknown = softevo_process("run", "--env", "water", "--stiffness", "1", "--model", "soft-fork",
                              "--db", model_db[1], cwd=ROOT)  # the plugin not loaded
    assert unknown.returncode == 2 and "soft-fork" in unknown.stderr


def test_a_registered_model_reaches_rest_the_dashboard_and_the_report(model_db, start_server, open_page):
    folder, url = model_db
    base = start_server("dashboard", url, env=MODEL_PLUGIN)
    analysis = httpx.get(f"{base}/experiments/1/analysis", timeout=60).json()
    assert [t["model"] for t in analysis["treatments"]] == ["soft-fork"]
    schema = httpx.get(f"{base}/openapi.json", timeout=30).json()["components"]["schemas"]
    enums = [s.get("enum", []) for s in _walk(schema) if isinstance(s, dict)]
    assert any("soft-fork" in e and "voxelyze-2" in e for e in enums)  # the REST enum of models

    page = open_page(base).page
    page.goto(f"{base}/dashboard/experiments/1")
    page.locator("#treatments td", has_text="soft-fork").first.wait_for(timeout=30_000)

    out = folder / "report"
    done = softevo_process("report", "latest", "--db", url, "--out", str(out), "--no-animation", "--quiet",
                           env=MODEL_PLUGIN, cwd=ROOT)
    assert done.returncode == 0, done.stderr
    assert "physics model soft-fork" in (out / "report.md").read_text()


def _walk(node):
    """Every dict and list inside a JSON value."""
    yield node
    children = node.values() if isinstance(node, dict) else node if isinstance(node, list) else ()
    for child in children:
        yield from _walk(child)
