"""A world is named in code in one place, the registry (issue 27): outside tests and docs at
most 3 files hold a world's name as a string literal. Docstrings and comments are prose and
do not count; a literal counts when its first word is a registered world's name (``"water"``,
``"land-water S3"``, ``"land:0,water:50"``)."""

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


def files_naming_worlds() -> dict[str, list[str]]:
    try:
        listed = subprocess.run(
            ["git", "ls-files", "*.py", "*.js"], cwd=ROOT, capture_output=True, text=True, check=True
        ).stdout.split()
    except (OSError, subprocess.CalledProcessError):
        pytest.skip("not a git checkout")
    found = {}
    for name in listed:
        if name.startswith(("tests/", "docs/")) or "/vendor/" in name:  # vendor: others' code
            continue
        source = (ROOT / name).read_text(encoding="utf-8")
        literals = python_literals(source) if name.endswith(".py") else js_literals(source)
        hits = [value for value in literals if names_a_world(value)]
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
