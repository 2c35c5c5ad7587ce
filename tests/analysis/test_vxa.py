"""VoxCAD export: a known robot against a hand-written file; a stored individual via the CLI."""

from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest

from softevo.analysis.robots import record_scene
from softevo.analysis.vxa import VxaWarning, data_layers, scene_to_vxa, value_layers, write_vxa
from softevo.service.storage.individuals import individual_record
from tests.support import softevo

EXPECTED = Path(__file__).parent / "data" / "small.vxa"

# body[x][y][z], 2 x 3 x 2: no two layers, rows or columns alike, so any transposition shows
BODY = [
    [[1, 0], [2, 1], [0, 2]],
    [[2, 2], [0, 1], [1, 0]],
]
PHASE = [
    [[0.0, 0.1], [0.2, 0.3], [0.4, 0.5]],
    [[0.6, 0.7], [0.8, 0.9], [1.0, 1.1]],
]
SCENE = {
    "body": BODY,
    "phase": PHASE,
    "material": {"youngs_modulus": 1e5},
    "environment": {"kind": "land"},
    "actuation": {"frequency": 2.0},
    "duration": {"cycles": 4},
    "settle_seconds": 0.5,
    "dt_fraction": 0.2,  # as the hand-written file says, whatever the default
}


def _parse(text: str) -> ET.Element:
    return ET.fromstring(text.encode("iso-8859-1"))


def test_known_robot_matches_the_hand_written_file(tmp_path):
    with pytest.warns(VxaWarning, match="the robot's model is voxelyze-2"):
        written = write_vxa(SCENE, tmp_path / "small.vxa")
    assert written.read_text(encoding="iso-8859-1") == EXPECTED.read_text(encoding="iso-8859-1")


def test_layers_are_z_bottom_first_then_y_rows_of_x():
    root = _parse(scene_to_vxa(SCENE))
    structure = root.find("VXC/Structure")
    assert structure.get("Compression") == "ASCII_READABLE"
    assert [structure.findtext(t) for t in ("X_Voxels", "Y_Voxels", "Z_Voxels")] == ["2", "3", "2"]
    layers = [layer.text for layer in structure.findall("Data/Layer")]
    body = np.array(BODY)
    for z, layer in enumerate(layers):
        expected = "".join(str(body[x, y, z]) for y in range(3) for x in range(2))
        assert layer == expected
    assert layers == ["122001", "021120"]
    phases = [[float(v) for v in layer.text.split(",")] for layer in structure.findall("PhaseOffset/Layer")]
    # in cycles, as the fork reads them: sin(2 pi (t / TempPeriod + offset))
    assert phases[1] == pytest.approx(np.array([0.1, 0.7, 0.3, 0.9, 0.5, 1.1]) / (2 * np.pi))


def test_layer_helpers_on_a_single_voxel_column():
    column = np.array([[[1, 2, 0]]])  # x = y = 1, z = 3
    assert data_layers(column) == ["1", "2", "0"]
    assert value_layers(np.array([[[0.5, -1.25, 0.0]]])) == ["0.5", "-1.25", "0"]


def test_water_has_no_gravity_no_floor_and_the_forks_fluid_tags():
    root = _parse(scene_to_vxa({**SCENE, "environment": {"kind": "water"}}))
    assert root.findtext("Environment/Gravity/GravEnabled") == "0"
    assert root.findtext("Environment/Gravity/FloorEnabled") == "0"
    # directly under <Environment>, where the fork reads them (VX_Environment.cpp)
    assert root.findtext("Environment/FluidEnvironment") == "1"
    assert float(root.findtext("Environment/AggregateDragCoefficient")) == 0.5 * 1000 * 1.5


@pytest.mark.parametrize("amplitude", [0.14, 0.39, 0.05])
def test_the_fork_reads_the_scenes_amplitude(amplitude):
    root = _parse(scene_to_vxa({**SCENE, "actuation": {"frequency": 2.0, "amplitude": amplitude}}))
    # the fork: TempAmplitude = TempAmp - TempBase, strain = TempAmplitude x CTE
    thermal = root.find("Environment/Thermal")
    swing = float(thermal.findtext("TempAmp")) - float(thermal.findtext("TempBase"))
    ctes = [float(m.findtext("Mechanical/CTE")) for m in root.findall("VXC/Palette/Material")]
    assert ctes == [0.0, 0.01]
    assert swing * ctes[1] == pytest.approx(amplitude, rel=1e-12)


@pytest.mark.parametrize(("horizon", "text"), [(1, "0.666666666667"), (2, None), (3, "2"), (7, None)])
def test_collision_horizon_reads_back_in_the_forks_rounding(horizon, text):
    scene = {**SCENE, "model": "voxcad-land-water", "model_options": {"collision_horizon": horizon}}
    value = _parse(scene_to_vxa(scene)).findtext("Simulator/Collisions/CollisionHorizon")
    assert int(float(value) * 1.5) == horizon  # VX_Sim.cpp: CalcNearby(int(CollisionHorizon * 1.5))
    assert text is None or value == text


def test_stop_condition_is_simulated_seconds_from_the_settled_start():
    root = _parse(scene_to_vxa(SCENE))
    assert root.findtext("Simulator/StopCondition/StopConditionType") == "2"
    assert float(root.findtext("Simulator/StopCondition/StopConditionValue")) == pytest.approx(0.5 + 4 / 2.0)
    assert float(root.findtext("Simulator/StopCondition/InitCmTime")) == 0.5


def test_a_frequency_field_of_several_values_warns_and_writes_the_mean():
    field = np.full((2, 3, 2), 2.0)
    field[0, 1, 0] = 4.0  # an active voxel
    with pytest.warns(UserWarning, match="one actuation period"):
        root = _parse(scene_to_vxa({**SCENE, "frequency_field": field.tolist()}))
    active = np.array(BODY) == 2
    assert float(root.findtext("Environment/Thermal/TempPeriod")) == pytest.approx(1 / field[active].mean())


def test_export_vxa_command_writes_the_stored_individual(capsys, tiny, tiny_data, tmp_path):
    final = tiny_data.final_populations()
    member = final[final["treatment"] == "water-land S3"].iloc[0]
    individual = int(member["individual_id"])
    out = tmp_path / "robot.vxa"
    code, stdout, err = softevo(capsys, "export-vxa", str(individual), "--out", str(out), "--db", tiny.url)
    assert code == 0, err
    assert stdout.strip() == str(out)
    root = _parse(out.read_text(encoding="iso-8859-1"))
    scene, _ = record_scene(individual_record(tiny.engine, individual))
    body = np.array(scene["body"])
    assert body.shape == (4, 4, 4)
    assert [layer.text for layer in root.findall("VXC/Structure/Data/Layer")] == data_layers(body)
    # after the switch the individual lives on land: gravity, a floor, the run's stiffness
    assert root.findtext("Environment/Gravity/FloorEnabled") == "1"
    assert float(root.findtext("VXC/Palette/Material/Mechanical/Elastic_Mod")) == pytest.approx(1e5)
    period = float(root.findtext("Environment/Thermal/TempPeriod"))
    assert period == pytest.approx(1.0 / scene["actuation"]["frequency"])


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["999999", "--out", "x.vxa"], "no individual 999999"),
        (["1", "--out", "x.txt"], "--out must end in .vxa"),
        (["1", "--out", "x.vxa", "--environment", "moon"], "environment must be land or water"),
    ],
)
def test_export_vxa_mistakes_are_one_line_and_exit_2(capsys, tiny, tmp_path, args, message):
    args = [a if not a.startswith("x.") else str(tmp_path / a) for a in args]
    code, _, err = softevo(capsys, "export-vxa", *args, "--db", tiny.url)
    assert code == 2
    assert err.startswith("error: ") and err.count("\n") == 1 and message in err


def test_a_voxelyze_2_robot_is_exported_with_a_warning_that_its_import_repeats(tmp_path):
    """Issue 49.6: a voxelyze-2 robot exported and imported again silently became a
    voxcad-land-water scene (6.313 where the stored distance is 5.222). The export warns,
    the file says so in a comment, and import-vxa warns again; a paper-model robot is
    written without either."""
    from softevo import import_vxa

    with pytest.warns(VxaWarning, match="model is voxelyze-2: a .vxa file holds the paper's engine"):
        written = write_vxa(SCENE, tmp_path / "v2.vxa")
    assert "<!-- softevo: written from a voxelyze-2 scene" in written.read_text(encoding="iso-8859-1")
    imported = "written from a voxelyze-2 robot: imported, it runs the paper's engine"
    with pytest.warns(VxaWarning, match=imported):
        assert import_vxa(written)["model"] == "voxcad-land-water"
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error", VxaWarning)
        paper = write_vxa({**SCENE, "model": "voxcad-land-water"}, tmp_path / "paper.vxa")
        import_vxa(paper)
    assert "softevo: written from" not in paper.read_text(encoding="iso-8859-1")
