"""The model and engine registries (``sim.models``, ``sim.engines``) and the import graph of
``sim``: one home per model, per option field and per engine, and no module of ``sim`` in an
import cycle."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

from softevo import sim
from softevo.sim import engines, models
from softevo.sim.scene import SceneError, parse_scene

SIM = Path(sim.__file__).parent


def test_models_registry_gives_names_options_and_defaults():
    assert models.names() == ("voxelyze-2", "voxcad-land-water")
    assert models.DEFAULT == "voxelyze-2"
    paper = models.get("voxcad-land-water")
    assert (paper.dt_fraction, paper.amplitude) == (0.7, 0.14) and paper.description
    assert models.options("voxcad-land-water") is paper.options
    assert models.defaults("voxelyze-2") == {
        "dt_fraction": 0.5, "amplitude": 0.39, "model_options": models.ModelOptions().to_dict()}
    # what a REST schema derives: the model enum and every option with its choices
    assert models.option_names() == tuple(models.ModelOptions().to_dict())
    assert models.option("drag").choices == ("faces", "mesh")
    with pytest.raises(KeyError, match="unknown model 'nope'; choose one of voxelyze-2"):
        models.get("nope")


def test_a_registered_model_runs_through_the_scene_parser():
    soft = models.register(models.Model(
        "soft-fork", models.options("voxcad-land-water").replace(rotation_damping=1.0), 0.6,
        0.2, "the fork without its angular damping"))
    try:
        scene = parse_scene({"body": [[[2]]], "model": "soft-fork",
                             "model_options": {"drag": "faces"}})
        assert scene.options == soft.options.replace(drag="faces")
        assert (scene.dt_fraction, scene.actuation.amplitude) == (0.6, 0.2)
        with pytest.raises(ValueError, match="already registered"):
            models.register(soft)
    finally:
        models.unregister("soft-fork")
    with pytest.raises(ValueError, match="built in"):
        models.unregister("voxelyze-2")
    with pytest.raises(SceneError, match="^model: must be one of voxelyze-2, voxcad-land-water"):
        parse_scene({"body": [[[2]]], "model": "soft-fork"})


@pytest.mark.parametrize(("options", "message"), [
    ({"rotation_damping": 1e4}, r"^model_options.rotation_damping: must be in \[0, 1000\]"),
    ({"collision_horizon": 1.5}, "^model_options.collision_horizon: must be a whole number"),
    ({"contact": "sphere"}, "^model_options.contact: must be one of voxelyze-2, voxcad"),
    ({"actuation_lag": True}, "^model_options.actuation_lag: must be a number"),
])
def test_bad_model_options_name_their_field(options, message):
    with pytest.raises(SceneError, match=message):
        parse_scene({"body": [[[2]]], "model_options": {"drag": "mesh", **options}})


def test_engine_registry_names_each_engine_once():
    assert engines.ENGINES == ("numba", "cuda", "sleep") and engines.DEFAULT == "numba"
    assert engines.module("sleep").simulate_many is not None
    with pytest.raises(engines.EngineUnavailable, match="engine: must be one of numba, cuda, sleep"):
        engines.get("opencl")
    assert sim.simulate_many is engines.simulate_many


def _imports(path: Path) -> set[str]:
    """The sibling modules of ``sim`` that ``path`` imports, at any depth of its code."""
    out = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom) and node.level == 1:
            if node.module:
                out.add(node.module.split(".")[0])
            else:
                out.update(alias.name for alias in node.names)
    return out


def test_no_module_of_sim_is_in_an_import_cycle():
    graph = {p.stem: _imports(p) for p in SIM.glob("*.py") if p.stem != "__init__"}
    for start in graph:
        seen, todo = set(), list(graph[start])
        while todo:
            name = todo.pop()
            assert name != start, f"sim.{start} imports itself through sim.{name}"
            if name in seen or name not in graph:
                continue
            seen.add(name)
            todo.extend(graph[name])
