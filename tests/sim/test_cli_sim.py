"""``softevo simulate`` end to end, as a user runs it (subprocess).

Output formats (summary, ``--json`` = ``Result.to_dict()``, ``--record`` .npz) and the error
contract: a user's mistake is one ``error: ...`` line on stderr naming the field, exit 2,
never a traceback.
"""

from __future__ import annotations

import json
import subprocess
from pathlib import Path

import numpy as np
import pytest

from softevo import sim
from tests import support
from tests.support import softevo_process

REPO = Path(__file__).resolve().parents[2]
EXAMPLES = REPO / "examples"
TINY = {
    "voxel_size": 0.05,
    "environment": {"kind": "land"},
    "body": [[[2], [2]], [[1], [1]]],
    "actuation": {"frequency": 5.0},
    "duration": {"cycles": 1},
}


def softevo(*args: str, cwd: Path | None = None) -> subprocess.CompletedProcess:
    """The installed console command, as a user runs it (slow: a fresh interpreter)."""
    return softevo_process(*args, cwd=cwd)


def softevo_here(capsys, *args: str) -> subprocess.CompletedProcess:
    """The same entry point in this process (fast; any stray exception fails the test)."""
    return subprocess.CompletedProcess(list(args), *support.softevo(capsys, *args))


def write(tmp_path: Path, scene, name: str = "scene.json") -> Path:
    path = tmp_path / name
    path.write_text(scene if isinstance(scene, str) else json.dumps(scene))
    return path


def assert_user_error(proc: subprocess.CompletedProcess, *needles: str) -> None:
    assert proc.returncode == 2, (proc.returncode, proc.stderr)
    assert "Traceback" not in proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1, proc.stderr
    assert lines[0].startswith("error: ")
    for needle in needles:
        assert needle in lines[0], lines[0]
    assert proc.stdout == ""


def test_json_output_is_exactly_the_result(tmp_path):
    proc = softevo("simulate", str(write(tmp_path, TINY)), "--json")
    assert proc.returncode == 0, proc.stderr
    assert len(proc.stdout.strip().splitlines()) == 1
    printed = json.loads(proc.stdout)
    assert printed == json.loads(json.dumps(sim.simulate(TINY).to_dict()))


def test_precision_option_runs_the_scene_in_that_precision(tmp_path, capsys):
    """``--precision mixed`` is the scene with ``model_options.precision`` "mixed": the same
    result as simulating that scene, near float64's but not equal to it; a wrong value is
    one line."""
    path = write(tmp_path, TINY)
    proc = softevo_here(capsys, "simulate", str(path), "--json", "--precision", "mixed")
    assert proc.returncode == 0, proc.stderr
    mixed = json.loads(proc.stdout)
    expected = sim.simulate({**TINY, "model_options": {"precision": "mixed"}}).to_dict()
    assert mixed == json.loads(json.dumps(expected))
    float64 = sim.simulate(TINY)
    assert mixed["final_positions"] != np.asarray(float64.final_positions).tolist()
    assert mixed["distance"] == pytest.approx(float64.distance, rel=1e-3)
    assert_user_error(softevo_here(capsys, "simulate", str(path), "--precision", "half"),
                      "--precision: must be one of float64, mixed (got 'half')")


def test_plain_summary(tmp_path, capsys):
    proc = softevo_here(capsys, "simulate", str(write(tmp_path, TINY)))
    assert proc.returncode == 0, proc.stderr
    out = proc.stdout
    for word in ("stable", "yes", "distance", "voxel lengths", "steps", "wall time"):
        assert word in out, out
    assert len(out.strip().splitlines()) <= 6
    assert "(horizontal, land)" in out, out


@pytest.mark.parametrize(("model", "axes"), [("voxelyze-2", "horizontal"), ("voxcad-land-water", "3-D")])
def test_summary_names_the_models_distance(tmp_path, capsys, model, axes):
    """The paper's model measures a land distance in 3-D (issue 49.8: it said horizontal)."""
    proc = softevo_here(capsys, "simulate", str(write(tmp_path, {**TINY, "model": model})))
    assert proc.returncode == 0, proc.stderr
    assert f"voxel lengths ({axes}, land)" in proc.stdout, proc.stdout


def test_record_default_frames(tmp_path, capsys):
    out = tmp_path / "frames.npz"
    proc = softevo_here(capsys, "simulate", str(write(tmp_path, TINY)), "--record", str(out))
    assert proc.returncode == 0, proc.stderr
    data = np.load(out)
    t, pos, voxels = data["t"], data["positions"], data["voxels"]
    assert len(t) > 5 and t[0] == 0.0 and np.all(np.diff(t) > 0)
    assert pos.shape == (len(t), 4, 3)
    assert voxels.shape == (4, 3)
    result = sim.simulate(TINY)
    np.testing.assert_allclose(pos[0], (np.asarray(result.voxels) + 0.5) * 0.05, atol=1e-12)


def test_record_uses_the_scene_record_field(tmp_path, capsys):
    out = tmp_path / "frames.npz"
    scene = TINY | {"record": {"every": 7}}
    proc = softevo_here(capsys, "simulate", str(write(tmp_path, scene)), "--record", str(out), "--json")
    assert proc.returncode == 0, proc.stderr
    printed = json.loads(proc.stdout)
    data = np.load(out)
    assert len(data["t"]) == printed["steps"] // 7 + 1
    np.testing.assert_allclose(data["t"], printed["frames"]["t"])
    np.testing.assert_allclose(data["positions"], printed["frames"]["positions"])


@pytest.mark.parametrize(
    ("content", "needles"),
    [
        ("{bad json", ("invalid JSON", "line 1")),
        ("[1, 2]", ("must be a JSON object",)),
        (TINY | {"material": {"youngs_modulus": -1.0}}, ("material.youngs_modulus",)),
        (TINY | {"colour": "red"}, ("colour", "unknown field")),
        (TINY | {"body": [[[0]]]}, ("body",)),
        (TINY | {"body": [1, 2]}, ("body",)),
        (TINY | {"actuation": {"waveform": "triangle"}}, ("actuation.waveform",)),
        (TINY | {"environment": {"kind": "space"}}, ("environment.kind",)),
    ],
)
def test_bad_scene_is_one_line_exit_2(tmp_path, capsys, content, needles):
    assert_user_error(softevo_here(capsys, "simulate", str(write(tmp_path, content))), *needles)


def test_bad_scene_from_the_shell(tmp_path):
    """The real console command: exit 2, one stderr line naming the field, no traceback."""
    bad = write(tmp_path, TINY | {"material": {"youngs_modulus": -1.0}}, "bad.json")
    assert_user_error(softevo("simulate", str(bad)), "material.youngs_modulus")


def test_missing_file_is_one_line_exit_2(tmp_path):
    assert_user_error(softevo("simulate", str(tmp_path / "nope.json")), "nope.json",
                      "no such file")


def test_directory_is_one_line_exit_2(tmp_path, capsys):
    assert_user_error(softevo_here(capsys, "simulate", str(tmp_path)))


def test_unwritable_record_is_one_line_exit_2(tmp_path, capsys):
    proc = softevo_here(capsys, "simulate", str(write(tmp_path, TINY)), "--record",
                   str(tmp_path / "no" / "such" / "dir" / "out.npz"))
    assert_user_error(proc, "--record")


def test_usage_error_is_one_line_exit_2():
    """Bad arguments are a user's mistake too (service/cli/__init__.py promises one line, exit 2)."""
    assert_user_error(softevo("simulate"))


@pytest.mark.parametrize(("name", "at_least"), [("walker_land.json", 2.0),
                                                ("flapper_water.json", 1.0),
                                                ("cantilever.json", 0.0)])
def test_examples_run(capsys, name, at_least):
    """The newcomer's examples run, stay stable, and the robots really move."""
    proc = softevo_here(capsys, "simulate", str(EXAMPLES / name), "--json")
    assert proc.returncode == 0, proc.stderr
    result = json.loads(proc.stdout)
    assert result["stable"], result["reason"]
    assert result["distance"] >= at_least


def test_cantilever_example_matches_beam_theory():
    """The example cantilever's tip (mean over the last 0.5 s) is the lumped-load
    Euler-Bernoulli deflection 1.112 cm to within 3% (its ~11% sag of the span shortens it
    by ~1.5% through geometric nonlinearity, as in Voxelyze)."""
    scene = json.loads((EXAMPLES / "cantilever.json").read_text())
    result = sim.simulate(scene | {"record": {"every": 100}})
    t = np.asarray(result.frames["t"])
    pos = np.asarray(result.frames["positions"])
    tip = [n for n, v in enumerate(result.voxels) if tuple(v) == (9, 0, 0)][0]
    sag = -(pos[t >= 0.5, tip, 2].mean() - pos[0, tip, 2])
    L, E, rho, g = 0.01, 1e6, 1000.0, 9.81
    ei, m = E * L**4 / 12, rho * L**3
    span = 9 * L
    expected = sum(m * g * (j * L) ** 2 * (3 * span - j * L) / (6 * ei) for j in range(1, 10))
    assert sag == pytest.approx(expected, rel=0.03)


def test_energy_adds_the_audit_to_the_json(tmp_path, capsys):
    """``--json --energy``: the result as without it, plus an ``energy`` object: the
    actuators' work, the mechanical change, the dissipation, the balance (``sim.energy``)."""
    path = write(tmp_path, TINY)
    plain = softevo_here(capsys, "simulate", str(path), "--json")
    proc = softevo_here(capsys, "simulate", str(path), "--json", "--energy")
    assert proc.returncode == 0, proc.stderr
    out = json.loads(proc.stdout)
    audit = out.pop("energy")
    assert out == json.loads(plain.stdout)
    assert audit["actuator_work"] > 0.0 and audit["dissipated_known"] > 0.0
    assert audit["unaccounted"] == pytest.approx(
        audit["actuator_work"] + audit["external_work"] - audit["mechanical_change"]
        - audit["dissipated_known"], abs=1e-12)
    assert audit["engine_agreement"] == 0.0
    assert audit["steps"] == out["steps"]
    summary = softevo_here(capsys, "simulate", str(path), "--energy")
    assert "actuator work" in summary.stdout and "unaccounted" in summary.stdout


def test_energy_on_the_sleep_engine_is_a_user_error(tmp_path, capsys):
    proc = softevo_here(capsys, "simulate", str(write(tmp_path, TINY)), "--energy",
                        "--engine", "sleep")
    assert_user_error(proc, "--energy", "sleep")
