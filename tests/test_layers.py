"""The import graph between softevo's packages, read from the sources (ast: nothing is
imported to check it), against the rules of shared/STYLE.md ("Which way imports point"):

- each package imports only the packages below it (no cycle): sim imports none of the
  others; evolution only sim; worker evolution and sim; the service evolution, worker and
  analysis, and never sim (it reaches physics only through the worker: ``worker.physics``,
  ``worker.evaluate``); analysis computes on what it is given (evolution, sim, and the
  worker's replay of a stored robot);
- storage (``service.storage``) imports no analysis, and the domain (evolution) nothing of
  the service; the worker never touches SQL or HTTP (no sqlalchemy, fastapi, httpx);
- no module imports a ``_private`` name from another package;
- inside the service, each subpackage imports only those below it in ``SERVICE_ALLOWED``'s
  table (cli and api on top, storage and settings at the bottom), and the command line
  reaches the REST API only for the app, in the commands that serve it.

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


# service's own subpackages (``settings``: the module service/settings.py) -> the others each
# may import. The edges point one way, from the edges people use (the command line, the REST
# API) down to storage:
#
#   subpackage | imports                                      | what for
#   -----------+----------------------------------------------+---------------------------------
#   cli        | api*, plan, reports, runs, storage, settings | the commands
#   api        | plan, reports, runs, storage, settings       | the routes
#   reports    | storage                                      | reports from stored runs
#   plan       | runs                                         | specs, costs (executors, limits)
#   runs       | storage, settings                            | coordinator, executors, limits
#   storage    | settings                                     | SQL
#   settings   | -                                            | SOFTEVO_* variables
#
#   * the command line reaches the API only for its app (``CLI_API``), and only in the
#     commands that serve it (``SERVES``): no HTTP schema or request model; a spec file is
#     read by ``service.plan.spec``, which the API uses too.
SERVICE_ALLOWED = {
    "cli": {"api", "plan", "reports", "runs", "storage", "settings"},
    "api": {"plan", "reports", "runs", "storage", "settings"},
    "reports": {"storage"},
    "plan": {"runs", "settings"},
    "runs": {"storage", "settings"},
    "storage": {"settings"},
    "settings": set(),
}
CLI_API = {"softevo.service.api.app"}  # what of the API the command line may import
SERVES = {"softevo.service.cli.service", "softevo.service.cli.dashboard"}  # serve, dashboard
SERVICE_MODULES = [path for path in sorted((ROOT / "service").rglob("*.py"))
                   if path.parent != ROOT / "service" or path.stem == "settings"]


def service_part(module: str) -> str | None:
    """The subpackage of service that ``module`` lies in (None: not one of service's)."""
    parts = module.split(".")
    return parts[2] if parts[:2] == ["softevo", "service"] and len(parts) > 2 else None


def service_reached(module: str, names: list[str]) -> list[str]:
    """The service modules an import reaches (``from softevo.service.api import app`` reaches
    ``softevo.service.api.app``; ``from softevo.service import runs``, ``softevo.service.runs``)."""
    if module.split(".")[:2] != ["softevo", "service"]:
        return []
    if module.count(".") >= 2:
        inside = [f"{module}.{name}" for name in names if service_part(module) == "api" and name == "app"]
        return inside or [module]
    return [f"{module}.{name}" for name in names if name in SERVICE_ALLOWED]


def service_problems(path: Path) -> list[str]:
    name = module_name(path, "service")
    own = service_part(name)
    found = []
    for module, names in imports(path, "service"):
        for target in service_reached(module, names):
            other = service_part(target)
            if other == own:
                continue
            if other not in SERVICE_ALLOWED[own]:
                found.append(f"service.{own} imports service.{other} ({target})")
            elif (own, other) == ("cli", "api") and (target not in CLI_API or name not in SERVES):
                found.append(f"{name} imports {target}: the command line imports only the app, "
                             "in the commands that serve")
    return found


def test_the_service_table_has_no_cycle_and_names_every_subpackage():
    on_disk = {path.name for path in (ROOT / "service").iterdir() if (path / "__init__.py").exists()}
    assert on_disk | {"settings"} == set(SERVICE_ALLOWED)
    order = []  # each subpackage after every one it imports
    while len(order) < len(SERVICE_ALLOWED):
        ready = [p for p, below in SERVICE_ALLOWED.items() if p not in order and below <= set(order)]
        assert ready, f"a cycle among {sorted(set(SERVICE_ALLOWED) - set(order))}"
        order += ready


@pytest.mark.parametrize("path", SERVICE_MODULES, ids=[str(p.relative_to(ROOT)) for p in SERVICE_MODULES])
def test_service_subpackages_follow_their_table(path):
    assert service_problems(path) == []


def test_the_service_check_sees_what_it_forbids(tmp_path, monkeypatch):
    cli = tmp_path / "service" / "cli"
    storage = tmp_path / "service" / "storage"
    cli.mkdir(parents=True)
    storage.mkdir()
    sources = {
        cli / "plan.py": "from softevo.service.api.schemas import ExperimentIn\n",
        cli / "runs.py": "def f():\n    from softevo.service.api import app\n",
        cli / "service.py": "from softevo.service.api.app import create_app\n"
                            "from softevo.service import runs\n",
        storage / "bad.py": "from softevo.service.runs.limits import check_treatment\n",
    }
    for path, source in sources.items():
        path.write_text(source)
    monkeypatch.setattr(f"{__name__}.ROOT", tmp_path)
    assert service_problems(cli / "plan.py") == [
        "softevo.service.cli.plan imports softevo.service.api.schemas: the command line imports only the "
        "app, in the commands that serve"]
    assert len(service_problems(cli / "runs.py")) == 1  # the app, from a command that does not serve
    assert service_problems(cli / "service.py") == []
    assert service_problems(storage / "bad.py") == [
        "service.storage imports service.runs (softevo.service.runs.limits)"]
