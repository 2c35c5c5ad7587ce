"""A world is named in code in one place, the registry (issue 27): outside tests and docs at
most 3 files hold a world's name as a string literal. Docstrings and comments are prose and
do not count; a literal counts when its first word is a registered world's name (``"water"``,
``"land-water S3"``, ``"land:0,water:50"``).

Prose counts too when it quotes a world's name as code would (``'water'``, ``"land"``: an
example to copy): outside tests, bench and docs at most 3 code files do (issue 57); the
others write the registry's records (``LAND.name``, ``WATER.name``)."""

from __future__ import annotations

import ast
import re
import subprocess
from pathlib import Path

import pytest

from softevo.sim import worlds

ROOT = Path(__file__).resolve().parents[1]
MOST_FILES = 3
JS_STRING = re.compile(r"""(["'`])((?:(?!\1).){1,60})\1""")


def names_a_world(value: str) -> bool:
    first = re.split(r"[-:>@,+\s]", value.strip(), maxsplit=1)[0]
    return first in worlds.names()


def python_literals(source: str) -> list[str]:
    tree = ast.parse(source)
    prose = {
        id(node.value)
        for node in ast.walk(tree)
        if isinstance(node, ast.Expr) and isinstance(node.value, ast.Constant)
    }
    return [
        node.value
        for node in ast.walk(tree)
        if isinstance(node, ast.Constant) and isinstance(node.value, str) and id(node) not in prose
    ]


def js_literals(source: str) -> list[str]:
    code = re.sub(r"^\s*//.*$", "", re.sub(r"/\*.*?\*/", "", source, flags=re.S), flags=re.M)
    return [match.group(2) for match in JS_STRING.finditer(code)]


def quoted_names(source: str) -> list[str]:
    """World names in quotes anywhere in ``source``, prose included: ``'water'``, ``"land"``
    (an apostrophe after a letter opens no quote)."""
    names = "|".join(re.escape(name) for name in worlds.names())
    return [match.group(2) for match in re.finditer(rf"(?<!\w)([\"'])({names})\1", source)]


def code_files(skip: tuple[str, ...]) -> list[str]:
    """The tracked Python and JavaScript files outside the folders ``skip`` and vendored code."""
    try:
        listed = subprocess.run(
            ["git", "ls-files", "*.py", "*.js"], cwd=ROOT, capture_output=True, text=True, check=True
        ).stdout.split()
    except (OSError, subprocess.CalledProcessError):
        pytest.skip("not a git checkout")
    return [name for name in listed if not name.startswith(skip) and "/vendor/" not in name]


def files_naming_worlds() -> dict[str, list[str]]:
    found = {}
    for name in code_files(("tests/", "docs/")):
        source = (ROOT / name).read_text(encoding="utf-8")
        literals = python_literals(source) if name.endswith(".py") else js_literals(source)
        hits = [value for value in literals if names_a_world(value)]
        if hits:
            found[name] = hits
    return found


def files_quoting_worlds() -> dict[str, list[str]]:
    found = {}
    for name in code_files(("tests/", "docs/", "bench/")):
        hits = quoted_names((ROOT / name).read_text(encoding="utf-8"))
        if hits:
            found[name] = hits
    return found


def test_the_finder_sees_a_world_literal_and_ignores_prose():
    assert python_literals('"""On land."""\nx = "water"\n') == ["water"]
    assert names_a_world("land-water S3") and names_a_world("land:0,water:50")
    assert not names_a_world("voxcad-land-water") and not names_a_world("on land")
    assert js_literals("// 'land'\nconst a = `water`;") == ["water"]


def test_world_names_stand_in_at_most_three_files():
    found = files_naming_worlds()
    assert "sim/worlds.py" in found  # the registry itself: the finder works on the tree
    assert len(found) <= MOST_FILES, found


def test_the_quote_finder_reads_prose_and_skips_apostrophes():
    source = "def f():\n    \"\"\"e.g. ``evolve('water', 1)``: the robot's land.\"\"\"\n    return \"land\"\n"
    assert quoted_names(source) == ["water", "land"]
    assert quoted_names("the 'water-land' transition, \"voxcad-land-water\", 'watery'") == []


def test_world_names_are_quoted_in_at_most_three_files_prose_included():
    found = files_quoting_worlds()
    assert "sim/worlds.py" in found  # the registry itself: the finder works on the tree
    assert len(found) <= MOST_FILES, found
