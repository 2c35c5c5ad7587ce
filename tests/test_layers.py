"""The import graph between softevo's packages, read from the sources (ast: nothing is
imported to check it), against the rules of shared/STYLE.md ("Which way imports point"):

- each package imports only the packages below it (no cycle): sim imports none of the
  others; evolution only sim; worker evolution and sim; the service evolution, worker and
  analysis, and never sim (it reaches physics only through the worker: ``worker.physics``,
  ``worker.evaluate``); analysis computes on what it is given (evolution, sim, and the
  worker's replay of a stored robot);
- storage (``service.storage``) imports no analysis, and the domain (evolution) nothing of
  the service; the worker never touches SQL or HTTP (no sqlalchemy, fastapi, httpx);
- no module imports a ``_private`` name from another package.

``softevo.errors`` and the version in ``softevo/__init__.py`` are leaves every package may
use; the facade (``softevo``'s functions) sits on top of everything."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
ALLOWED = {  # package -> the softevo packages it may import
    "sim": set(),
    "evolution": {"sim"},
    "worker": {"evolution", "sim"},
    "analysis": {"worker", "evolution", "sim"},
    "service": {"analysis", "worker", "evolution"},
    "migrations": {"service"},
}
LEAVES = {"softevo", "softevo.errors"}


def imports(path: Path, package: str) -> list[tuple[str, list[str]]]:
    """(absolute module, imported names) of every import in ``path``, at any depth."""
    module = ".".join(["softevo", package, *path.relative_to(ROOT / package).with_suffix("").parts])
    parts = module.split(".")[:-1]  # the package a relative import starts from
    found = []
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"), filename=str(path))):
        if isinstance(node, ast.Import):
            found += [(alias.name, []) for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                up = parts[: len(parts) - (node.level - 1)]
                base = ".".join([*up, base] if base else up)
            found.append((base, [alias.name for alias in node.names]))
    return found


def package_of(module: str, names: list[str]) -> list[str]:
    """The softevo packages an import reaches (``from softevo import sim`` reaches sim)."""
    parts = module.split(".")
    if parts[0] != "softevo":
        return []
    if len(parts) >= 2:
        return [parts[1]] if parts[1] in ALLOWED else []
    return [name for name in names if name in ALLOWED]


def problems(path: Path, package: str) -> list[str]:
    found = []
    for module, names in imports(path, package):
        for other in package_of(module, names):
            if other != package and other not in ALLOWED[package]:
                found.append(f"{package} imports {other} ({module})")
        reached = package_of(module, names)
        if reached and reached != [package] and module not in LEAVES:
            private = [n for n in names if n.startswith("_") and n != "__version__"]
            found += [f"imports the private {module}.{n}" for n in private]
    return found


MODULES = [(package, path) for package in ALLOWED for path in sorted((ROOT / package).rglob("*.py"))]


def test_the_allowed_graph_has_no_cycle():
    seen: dict[str, int] = {}

    def visit(package: str) -> None:
        assert seen.get(package) != 1, f"import cycle through {package}"
        if seen.get(package) == 2:
            return
        seen[package] = 1
        for other in ALLOWED[package]:
            visit(other)
        seen[package] = 2

    for package in ALLOWED:
        visit(package)


def test_every_package_is_read():
    assert {package for package, _ in MODULES} == set(ALLOWED)
    assert len(MODULES) > 60


@pytest.mark.parametrize(("package", "path"), MODULES, ids=[str(p.relative_to(ROOT)) for _, p in MODULES])
def test_imports_follow_the_layers(package, path):
    assert problems(path, package) == []


def test_the_check_sees_upward_and_private_imports(tmp_path, monkeypatch):
    fake = tmp_path / "analysis"
    fake.mkdir()
    module = fake / "example.py"
    module.write_text(
        "from softevo.service.storage import open_database\n"
        "def f():\n    from softevo import service\n"
        "from softevo.evolution.stats import _private\n"
        "from softevo.analysis.data import _internal\n"
        "from .render import _local\n"
        "from softevo.errors import UserError\n"
    )
    monkeypatch.setattr(f"{__name__}.ROOT", tmp_path)
    assert sorted(problems(module, "analysis")) == [
        "analysis imports service (softevo)",
        "analysis imports service (softevo.service.storage)",
        "imports the private softevo.evolution.stats._private",
    ]


def test_one_import_name_is_installed():
    import tomllib

    config = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]
    assert {package.split(".")[0] for package in config["packages"]} == {"softevo"}
    assert {name.split(".")[0] for name in config["package-dir"]} == {"softevo"}
    assert {f"softevo.{package}" for package in ALLOWED} <= set(config["packages"])


GPU_ONLY = "numba.cuda"  # the GPU target, which only softevo.sim may import (the cuda engine)


@pytest.mark.parametrize(("package", "path"), MODULES, ids=[str(p.relative_to(ROOT)) for _, p in MODULES])
def test_only_sim_imports_numba_cuda(package, path):
    reached = {module for module, names in imports(path, package)
               if module == GPU_ONLY or module.startswith(GPU_ONLY + ".")
               or (module == "numba" and "cuda" in names)}
    assert package == "sim" or not reached, f"{package} imports {sorted(reached)}: only sim may"


# Subpackages held to a narrower rule than their package: prefix -> the softevo packages they
# must not import.
NARROWER = {"softevo.service.storage": {"analysis"}}
NO_SQL_OR_HTTP = ("sqlalchemy", "fastapi", "httpx", "starlette", "uvicorn")


def module_name(path: Path, package: str) -> str:
    return ".".join(["softevo", package, *path.relative_to(ROOT / package).with_suffix("").parts])


@pytest.mark.parametrize(("package", "path"), MODULES, ids=[str(p.relative_to(ROOT)) for _, p in MODULES])
def test_storage_imports_no_analysis_and_the_worker_no_sql_or_http(package, path):
    name = module_name(path, package)
    found = imports(path, package)
    for prefix, banned in NARROWER.items():
        if name.startswith(prefix):
            reached = {other for module, names in found for other in package_of(module, names)}
            assert not reached & banned, f"{name} imports {sorted(reached & banned)}"
    if package == "worker":
        outside = {module.split(".")[0] for module, _ in found}
        assert not outside & set(NO_SQL_OR_HTTP), f"{name} imports {sorted(outside & set(NO_SQL_OR_HTTP))}"


def test_the_narrower_rules_see_what_they_forbid(tmp_path, monkeypatch):
    storage = tmp_path / "service" / "storage"
    storage.mkdir(parents=True)
    (storage / "bad.py").write_text("from softevo.analysis.data import ExperimentData\n")
    worker = tmp_path / "worker"
    worker.mkdir()
    (worker / "bad.py").write_text("import sqlalchemy\n")
    monkeypatch.setattr(f"{__name__}.ROOT", tmp_path)
    with pytest.raises(AssertionError, match="analysis"):
        test_storage_imports_no_analysis_and_the_worker_no_sql_or_http("service", storage / "bad.py")
    with pytest.raises(AssertionError, match="sqlalchemy"):
        test_storage_imports_no_analysis_and_the_worker_no_sql_or_http("worker", worker / "bad.py")
    assert problems(storage / "bad.py", "service") == []  # the package rule alone lets it pass
