"""The analyses compute on data they are given: no module of ``analysis/`` imports
``softevo.service``, and none imports a ``_private`` name from another top-level package.
Checked by parsing the imports (ast), so nothing is imported to check it."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ANALYSIS = Path(__file__).resolve().parents[2] / "analysis"
PACKAGE = "softevo.analysis"
# Another branch removes these modules' service imports; drop each from here once merged.
PENDING = {
    "motion.py": "re-simulation still reads the database through service (other branch)",
    "robots.py": "stored robots still read through service (other branch)",
}


def imports(path: Path) -> list[tuple[str, list[str]]]:
    """(absolute module, imported names) of every import in ``path``, at any depth."""
    found = []
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"), filename=str(path))):
        if isinstance(node, ast.Import):
            found += [(alias.name, []) for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:  # relative: from the module's package (analysis/) upwards
                parts = PACKAGE.split(".")
                parts = parts[: len(parts) - (node.level - 1)]
                base = ".".join([*parts, base] if base else parts)
            found.append((base, [alias.name for alias in node.names]))
    return found


def top_level(module: str) -> str:
    """``softevo.service.db`` -> ``softevo.service``; ``softevo.errors`` -> ``softevo``."""
    parts = module.split(".")
    if parts[0] != "softevo":
        return parts[0]
    return "softevo" if len(parts) < 2 or parts[1] == "errors" else ".".join(parts[:2])


def problems(path: Path) -> list[str]:
    found = []
    for module, names in imports(path):
        if module == "softevo.service" or module.startswith("softevo.service."):
            found.append(f"imports {module}")
        if top_level(module) != PACKAGE:
            private = [n for n in names if n.startswith("_") and not n.startswith("__")]
            found += [f"imports the private {module}.{name}" for name in private]
    return found


MODULES = sorted(ANALYSIS.glob("*.py"))


def test_every_analysis_module_is_checked():
    assert {"data.py", "report.py", "figures.py", "stats_tables.py", "__init__.py"} <= {
        p.name for p in MODULES
    }


@pytest.mark.parametrize(
    "path",
    [
        pytest.param(p, id=p.name, marks=pytest.mark.xfail(reason=PENDING[p.name], strict=False))
        if p.name in PENDING
        else pytest.param(p, id=p.name)
        for p in MODULES
    ],
)
def test_analysis_imports_nothing_from_service(path):
    assert problems(path) == []


def test_the_check_sees_service_and_private_imports(tmp_path):
    module = tmp_path / "example.py"
    module.write_text(
        "from softevo.service.db import open_database\n"
        "def f():\n    from softevo.service.cli_sim import _default_record_every\n"
        "from softevo.evolution.stats import _private\n"
        "from softevo.analysis.data import _internal\n"
        "from .render import _local\n"
    )
    assert sorted(problems(module)) == [
        "imports softevo.service.cli_sim",
        "imports softevo.service.db",
        "imports the private softevo.evolution.stats._private",
        "imports the private softevo.service.cli_sim._default_record_every",
    ]
