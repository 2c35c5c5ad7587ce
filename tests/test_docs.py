"""The docs say what the code does (issue 28, item 7): every `softevo` command line in the
README and docs/ names a command and options that exist, and the README describes
docs/results at the scale and model its own README says made it."""

from __future__ import annotations

import re
from pathlib import Path

import pytest
import typer

ROOT = Path(__file__).resolve().parents[1]
DOCS = [ROOT / "README.md", *sorted((ROOT / "docs").rglob("*.md"))]


def softevo_lines(path: Path) -> list[str]:
    """The `softevo ...` lines inside the file's fenced blocks (continuations joined)."""
    lines, inside, pending = [], False, ""
    for raw in path.read_text(encoding="utf-8").splitlines():
        if raw.startswith("```"):
            inside = not inside
            continue
        if not inside:
            continue
        text = pending + raw.strip()
        if text.endswith("\\"):
            pending = text[:-1] + " "
            continue
        pending = ""
        if text.startswith("softevo "):
            lines.append(text)
    return lines


def click_app():
    from softevo.service.cli import _register, app

    _register()
    return typer.main.get_command(app)


CASES = [(path, line) for path in DOCS for line in softevo_lines(path)]


def test_the_docs_hold_softevo_commands():
    assert len(CASES) >= 10


@pytest.mark.parametrize("path,line", CASES, ids=[f"{p.name}:{i}" for i, (p, _) in enumerate(CASES)])
def test_every_documented_command_and_option_exists(path, line):
    group = click_app()
    text = re.split(r" #| > | && |; | & ", line)[0]
    name = text.split()[1]
    if name.startswith("-"):
        assert name in {"--version", "--help"}, f"{path.name}: {line}"
        return
    for alternative in name.split("|"):  # a synopsis: `softevo run|experiment ...`
        command = group.commands.get(alternative)
        assert command is not None, f"{path.name}: no command {alternative!r} in {line!r}"
        known = {opt for param in command.params for opt in (*param.opts, *param.secondary_opts)}
        for option in re.findall(r"(?<![\w-])--[a-z][a-z0-9-]*", text):
            message = f"{path.name}: {alternative} has no option {option!r} ({line!r})"
            assert option in known | {"--help"}, message


def test_the_readme_names_the_scale_and_model_of_docs_results():
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    sentence = next(line for line in readme.splitlines() if "run of the paper's grid" in line)
    results = (ROOT / "docs" / "results" / "README.md").read_text(encoding="utf-8")
    documented = softevo_lines(ROOT / "docs" / "results" / "README.md")
    command = next(line for line in documented if " experiment " in line)
    scale = re.search(r"--scale (\w+)", command).group(1)
    assert f"`{scale}`" in sentence
    model = re.search(r"--model ([\w-]+)", command)
    if model is not None:
        name = {"voxelyze-2": "Voxelyze 2", "voxcad-land-water": "paper's engine"}[model.group(1)]
        assert name in readme[readme.index(sentence) : readme.index(sentence) + 300]
    runs = (ROOT / "docs" / "results" / "export" / "runs.csv").read_text(encoding="utf-8").splitlines()
    assert runs[1].split(",")[1] == f"paper-{scale}"
    # the export is the preset as it stands: every treatment with the scale's repetitions
    from softevo.evolution.treatments import preset_grid

    grid = preset_grid("paper", scale)
    assert len(runs) - 1 == sum(t.repetitions for t in grid)
    assert f"{grid[0].repetitions} repetitions" in results


def test_the_readme_says_the_next_step_right_after_the_quickstart():
    """Between the quickstart and the test command: how to look at the result (the
    dashboard on the quickstart's database, with its URL) and how long the bare defaults
    take (issue 49.15)."""
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    blocks = [m.start() for m in re.finditer(r"^```bash", readme, flags=re.MULTILINE)]
    between = readme[blocks[0] : blocks[1]]
    assert "softevo dashboard --db sqlite:///quickstart.db" in between
    assert "http://127.0.0.1:8000/dashboard/" in between
    assert re.search(r"takes\s+about\s+\d+\s+minutes\s+on\s+2\s+cores", between)


def test_the_mapping_table_of_docs_algorithm_is_the_csv_its_script_wrote():
    """docs/algorithm.md's table of random robots' frequencies per mapping holds the rows of
    docs/results/mapping_table.csv (written by docs/results/mapping_table.py), number for number."""
    rows = (ROOT / "docs" / "results" / "mapping_table.csv").read_text(encoding="utf-8").splitlines()
    header, *rows = [row.split(",") for row in rows]
    assert header[:3] == ["workspace", "mapping", "n"] and len(rows) == 6
    text = (ROOT / "docs" / "algorithm.md").read_text(encoding="utf-8")
    for workspace, mapping, *numbers in rows:
        assert f"| {workspace} | `{mapping}` | {' | '.join(numbers)} |" in text, (workspace, mapping)
