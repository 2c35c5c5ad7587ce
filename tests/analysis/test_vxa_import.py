"""VoxCAD import: evosoro's sample files, export -> import round trips, malformed and hostile files."""

from __future__ import annotations

import base64
import json
import math
import zlib
from pathlib import Path

import numpy as np
import pytest

import softevo
from softevo import sim
from softevo.analysis.vxa import VxaError, VxaWarning, scene_to_vxa
from softevo.analysis.vxa_import import MAX_FILE_BYTES, read_vxa, vxa_to_scene
from tests.support import softevo as run_cli

SAMPLES = Path(__file__).parent / "data" / "vxa"
LAND = ("hopper", "land_stiffness_phaseoffset", "pusher_land", "quadruped_land")
WATER = ("flapping_passive_tissue", "full_cross", "hexapus", "quadrupus_passive_tissue")
# voxel counts (empty, passive, active) and the fork's TempPeriod of each sample
COUNTS = {
    "flapping_passive_tissue": (203, 46, 94),
    "full_cross": (0, 27, 316),
    "hexapus": (183, 0, 160),
    "hopper": (127, 43, 173),
    "land_stiffness_phaseoffset": (120, 51, 45),
    "pusher_land": (184, 23, 136),
    "quadruped_land": (171, 59, 113),
    "quadrupus_passive_tissue": (185, 28, 130),
}


def _layer_digits(path: Path) -> list[str]:
    text = path.read_text(encoding="iso-8859-1")
    data = text.split("<Data>")[1].split("</Data>")[0]
    return [part.split("]]>")[0] for part in data.split("<![CDATA[")[1:]]


def _phase_offsets(path: Path) -> np.ndarray:
    text = path.read_text(encoding="iso-8859-1")
    block = text.split("<PhaseOffset>")[1].split("</PhaseOffset>")[0]
    return np.array(
        [
            [float(v) for v in part.split("]]>")[0].split(",") if v.strip()]
            for part in block.split("<![CDATA[")[1:]
        ]
    )


@pytest.mark.parametrize("name", sorted(COUNTS))
def test_each_evosoro_sample_imports_without_warnings(name):
    path = SAMPLES / f"{name}.vxa"
    imported = read_vxa(path)
    assert imported.warnings == ()
    scene = imported.scene
    parsed = sim.parse_scene(scene)
    body = parsed.body
    assert body.shape == ((6, 6, 6) if name == "land_stiffness_phaseoffset" else (7, 7, 7))
    assert tuple(np.bincount(body.ravel(), minlength=3)) == COUNTS[name]
    # the layers: one per z, x fastest then y; material 3 (CTE 0.01) active, 1 (CTE 0) passive
    for z, digits in enumerate(_layer_digits(path)):
        ids = np.array([int(c) for c in digits]).reshape(body.shape[:2], order="F")
        assert np.array_equal(body[:, :, z], np.select([ids == 0, ids == 3], [0, 2], 1))
    assert parsed.model == "voxcad-land-water" and scene["model_options"]["collision_horizon"] == 3
    assert parsed.actuation.amplitude == pytest.approx(0.14)  # (39 - 25) x 0.01
    assert parsed.environment.kind == ("land" if name in LAND else "water")
    assert parsed.dt_fraction == 0.7 and parsed.self_collisions
    assert (
        parsed.material.damping_bond,
        parsed.material.damping_collision,
        parsed.material.damping_global,
    ) == (1.0, 0.8, 0.01)
    assert parsed.voxel_size == 0.05 and parsed.material.density == 1200.0
    # phases: the offsets are in cycles; radians here
    offsets = _phase_offsets(path)
    for z in range(body.shape[2]):
        expected = 2 * math.pi * offsets[z].reshape(body.shape[:2], order="F")
        assert np.allclose(parsed.phase[:, :, z], expected, rtol=1e-12, atol=0)


def test_land_samples_settle_then_run_to_the_stop_time():
    parsed = sim.parse_scene(read_vxa(SAMPLES / "hopper.vxa").scene)
    assert parsed.settle_seconds == 0.5
    assert parsed.total_seconds == pytest.approx(17.1462744618)
    assert parsed.actuation.frequency == pytest.approx(1 / 0.332925489237)
    assert parsed.environment.gravity == pytest.approx(9.81)
    assert parsed.material.youngs_modulus == pytest.approx(1e5) and parsed.youngs_modulus_field is None


def test_water_samples_have_no_gravity_and_the_forks_drag():
    parsed = sim.parse_scene(read_vxa(SAMPLES / "hexapus.vxa").scene)
    assert parsed.environment.gravity == 0.0  # the fork: neutral buoyancy, floor off in a fluid
    drag = 0.5 * parsed.environment.fluid_density * parsed.environment.drag_coefficient
    assert drag == pytest.approx(750.0)  # AggregateDragCoefficient
    assert parsed.settle_seconds == 0.0 and parsed.duration_seconds == pytest.approx(13.183127027)


def test_the_stiffness_layers_become_a_youngs_modulus_field():
    parsed = sim.parse_scene(read_vxa(SAMPLES / "land_stiffness_phaseoffset.vxa").scene)
    field = parsed.youngs_modulus_field
    assert field is not None
    assert field[0, 0, 0] == pytest.approx(4334608.63888)
    present = parsed.body > 0
    assert np.all(field[present] > 1e3) and np.all(field[~present] == 0)


def test_the_facade_and_the_cli_give_the_same_scene(capsys, tmp_path):
    out = tmp_path / "hopper.json"
    code, stdout, err = run_cli(capsys, "import-vxa", str(SAMPLES / "hopper.vxa"), "--out", str(out))
    assert code == 0, err
    assert stdout.strip() == str(out) and err == ""
    assert json.loads(out.read_text()) == softevo.import_vxa(SAMPLES / "hopper.vxa")


# ---- export -> import -----------------------------------------------------------------------

BODY = np.array([[[1, 0], [2, 1], [0, 2]], [[2, 2], [0, 1], [1, 0]], [[2, 1], [1, 1], [2, 2]]])
RNG = np.random.default_rng(7)
PHASE = RNG.uniform(-math.pi, math.pi, BODY.shape)
MODULI = np.where(BODY > 0, RNG.uniform(1e4, 1e7, BODY.shape), 0.0)
DENSITIES = np.where(BODY > 0, RNG.choice([900.0, 1200.0, 1500.0], BODY.shape), 0.0)
BASE = {
    "model": "voxcad-land-water",
    "body": BODY.tolist(),
    "actuation": {"frequency": 2.5},
    "duration": {"seconds": 3.0},
    "settle_seconds": 0.5,
}
ROUND_TRIPS = {
    "land": {**BASE, "environment": {"kind": "land"}},
    "water": {**BASE, "environment": {"kind": "water", "drag_coefficient": 2.0}, "settle_seconds": 0.0},
    "void": {**BASE, "environment": {"kind": "void", "gravity": 3.0}},
    "phases": {**BASE, "phase": PHASE.tolist(), "actuation": {"frequency": 3.7, "amplitude": 0.21}},
    "moduli": {**BASE, "phase": PHASE.tolist(), "youngs_modulus_field": MODULI.tolist()},
    "densities": {**BASE, "density_field": DENSITIES.tolist(), "material": {"density": 1000.0}},
    "amplitude 0.39": {**BASE, "actuation": {"frequency": 1.0, "amplitude": 0.39}},
    "settings": {
        **BASE,
        "material": {
            "youngs_modulus": 3e6,
            "poisson_ratio": 0.3,
            "friction_static": 0.7,
            "friction_kinetic": 0.2,
            "damping_bond": 0.5,
            "damping_global": 0.02,
            "damping_collision": 0.3,
        },
        "voxel_size": 0.01,
        "dt_fraction": 0.4,
        "self_collisions": False,
        "model_options": {"collision_horizon": 5},
    },
}


def _close(a, b) -> bool:
    return np.allclose(np.asarray(a, float), np.asarray(b, float), rtol=1e-9, atol=1e-12)


def _effective(scene: sim.Scene, name: str, scalar: float) -> np.ndarray:
    field = getattr(scene, name)
    return np.where(scene.body > 0, scalar if field is None else field, 0.0)


@pytest.mark.parametrize("name", sorted(ROUND_TRIPS))
def test_export_then_import_gives_the_scene_back(name):
    original = sim.parse_scene(ROUND_TRIPS[name])
    imported = vxa_to_scene(scene_to_vxa(ROUND_TRIPS[name]).encode("iso-8859-1"), "x.vxa")
    assert imported.warnings == ()
    back = sim.parse_scene(imported.scene)
    assert np.array_equal(back.body, original.body)
    assert _close(back.phase, original.phase)
    assert _close(
        _effective(back, "youngs_modulus_field", back.material.youngs_modulus),
        _effective(original, "youngs_modulus_field", original.material.youngs_modulus),
    )
    assert _close(
        _effective(back, "density_field", back.material.density),
        _effective(original, "density_field", original.material.density),
    )
    for part in (
        "poisson_ratio",
        "friction_static",
        "friction_kinetic",
        "damping_bond",
        "damping_global",
        "damping_collision",
    ):
        assert _close(getattr(back.material, part), getattr(original.material, part)), part
    assert back.environment.kind == original.environment.kind
    assert _close(back.environment.gravity, original.environment.gravity)
    if original.environment.kind == "water":
        assert _close(
            back.environment.fluid_density * back.environment.drag_coefficient,
            original.environment.fluid_density * original.environment.drag_coefficient,
        )
    assert back.actuation.waveform == "sine"
    assert _close(
        [back.actuation.frequency, back.actuation.amplitude],
        [original.actuation.frequency, original.actuation.amplitude],
    )
    assert _close(
        [back.settle_seconds, back.duration_seconds, back.voxel_size, back.dt_fraction],
        [original.settle_seconds, original.duration_seconds, original.voxel_size, original.dt_fraction],
    )
    assert back.self_collisions == original.self_collisions
    assert back.model == original.model and back.options == original.options


def test_a_negative_cte_is_the_opposite_phase_and_unequal_ctes_warn():
    text = scene_to_vxa(ROUND_TRIPS["land"])
    # a third material, active with CTE -0.02: voxels of it swing twice as far, half a cycle late
    extra = (
        text.split('<Material ID="2">')[1]
        .split("</Material>")[0]
        .replace("<CTE>0.01</CTE>", "<CTE>-0.02</CTE>")
    )
    text = text.replace("</Palette>", f'<Material ID="3">{extra}</Material></Palette>')
    assert "<![CDATA[122201012]]>" in text  # layer z = 0, x fastest then y
    text = text.replace("<![CDATA[122201012]]>", "<![CDATA[132201012]]>")  # voxel [1, 0, 0]: 2 -> 3
    with pytest.warns(VxaWarning, match=r"differ in \|CTE\|.*using the largest, 0.28"):
        scene = softevo.import_vxa(_write(text))
    parsed = sim.parse_scene(scene)
    assert parsed.actuation.amplitude == pytest.approx(2 * 0.14)  # the model's amplitude, twice
    assert parsed.body[1, 0, 0] == 2 and parsed.phase[1, 0, 0] == pytest.approx(math.pi)
    assert parsed.body[2, 0, 0] == 2 and parsed.phase[2, 0, 0] == 0.0


def _write(text: str, name: str = "robot.vxa") -> Path:
    import tempfile

    path = Path(tempfile.mkdtemp()) / name
    path.write_text(text, encoding="iso-8859-1")
    return path


@pytest.mark.parametrize("compression", ["BASE64", "ZLIB", "QT_ZLIB"])
def test_the_compressed_encodings_read_as_ascii_does(compression):
    text = (SAMPLES / "hopper.vxa").read_text(encoding="iso-8859-1")
    for digits in _layer_digits(SAMPLES / "hopper.vxa"):
        raw = bytes(int(c) for c in digits)
        packed = {
            "BASE64": raw,
            "ZLIB": zlib.compress(raw),
            "QT_ZLIB": len(raw).to_bytes(4, "big") + zlib.compress(raw),
        }[compression]
        text = text.replace(f"<![CDATA[{digits}]]>", f"<![CDATA[{base64.b64encode(packed).decode()}]]>", 1)
    text = text.replace('Compression="ASCII_READABLE"', f'Compression="{compression}"')
    assert (
        vxa_to_scene(text.encode("iso-8859-1"), "hopper.vxa").scene == read_vxa(SAMPLES / "hopper.vxa").scene
    )


def test_unknown_tags_are_one_warning_that_lists_them_all(capsys, tmp_path):
    text = (SAMPLES / "hopper.vxa").read_text(encoding="iso-8859-1")
    text = text.replace("<DtFrac>", "<Wobble>1</Wobble><DtFrac>").replace(
        "</Environment>", "<Sky>blue</Sky></Environment>"
    )
    path = _write(text)
    out = tmp_path / "scene.json"
    code, _, err = run_cli(capsys, "import-vxa", str(path), "--out", str(out))
    assert code == 0
    lines = err.splitlines()
    assert len(lines) == 1 and lines[0].startswith("warning: ")
    assert "Simulator/Integration/Wobble" in lines[0] and "Environment/Sky" in lines[0]
    assert json.loads(out.read_text())["dt_fraction"] == 0.7


def test_stop_after_temperature_cycles_is_cycles_of_temp_period():
    text = (
        scene_to_vxa(ROUND_TRIPS["land"])
        .replace("<StopConditionType>2</StopConditionType>", "<StopConditionType>3</StopConditionType>")
        .replace(
            "<StopConditionValue>3.5</StopConditionValue>", "<StopConditionValue>10</StopConditionValue>"
        )
    )
    parsed = sim.parse_scene(vxa_to_scene(text.encode()).scene)
    assert parsed.total_seconds == pytest.approx(10 / 2.5)


# ---- malformed and hostile files: one line, exit 2 ------------------------------------------

HOPPER = (SAMPLES / "hopper.vxa").read_text(encoding="iso-8859-1")
BILLION_LAUGHS = """<?xml version="1.0"?>
<!DOCTYPE lolz [
 <!ENTITY lol "lol">
 <!ENTITY lol2 "&lol;&lol;&lol;&lol;&lol;&lol;&lol;&lol;&lol;&lol;">
 <!ENTITY lol3 "&lol2;&lol2;&lol2;&lol2;&lol2;&lol2;&lol2;&lol2;&lol2;&lol2;">
 <!ENTITY lol4 "&lol3;&lol3;&lol3;&lol3;&lol3;&lol3;&lol3;&lol3;&lol3;&lol3;">
 <!ENTITY lol5 "&lol4;&lol4;&lol4;&lol4;&lol4;&lol4;&lol4;&lol4;&lol4;&lol4;">
 <!ENTITY lol6 "&lol5;&lol5;&lol5;&lol5;&lol5;&lol5;&lol5;&lol5;&lol5;&lol5;">
 <!ENTITY lol7 "&lol6;&lol6;&lol6;&lol6;&lol6;&lol6;&lol6;&lol6;&lol6;&lol6;">
 <!ENTITY lol8 "&lol7;&lol7;&lol7;&lol7;&lol7;&lol7;&lol7;&lol7;&lol7;&lol7;">
 <!ENTITY lol9 "&lol8;&lol8;&lol8;&lol8;&lol8;&lol8;&lol8;&lol8;&lol8;&lol8;">
]>
<VXA Version="1.0"><Simulator><GA><FitnessFileName>&lol9;</FitnessFileName></GA></Simulator></VXA>
"""
EXTERNAL_ENTITY = """<?xml version="1.0"?>
<!DOCTYPE VXA [<!ENTITY secret SYSTEM "file:///etc/passwd">]>
<VXA Version="1.0"><Simulator><GA><FitnessFileName>&secret;</FitnessFileName></GA></Simulator></VXA>
"""


@pytest.mark.parametrize(
    ("text", "message"),
    [
        (BILLION_LAUGHS, "refused: the file declares a DTD or entities"),
        (EXTERNAL_ENTITY, "refused: the file declares a DTD or entities"),
        ("this is not XML", "not an XML file"),
        ("<VXC Version='0.94'/>", "the root element is <VXC>, not <VXA>"),
        (HOPPER.split("<Structure")[0] + "</VXC></VXA>", "VXC/Structure: missing"),
        (
            HOPPER.replace(
                "<Layer><![CDATA[0033333003333300033330003333000333300333330033333]]></Layer>",
                "<Layer><![CDATA[003333300333330003333000333300033330033333003333]]></Layer>",
                1,
            ),
            "VXC/Structure/Data layer 0: 48 voxels, X_Voxels x Y_Voxels is 49",
        ),
        (
            HOPPER.replace(
                "<Layer><![CDATA[1111111011111101111110011111011111101111111111111]]></Layer>", "", 1
            ),
            "VXC/Structure/Data: 6 <Layer>s, Z_Voxels is 7",
        ),
        (
            HOPPER.replace(
                "<Layer><![CDATA[0033333003333300033330003333000333300333330033333]]></Layer>",
                "<Layer><![CDATA[0033333003333300033330003333000333300333330033338]]></Layer>",
                1,
            ),
            "material 8 is not in the palette (5 materials)",
        ),
        (
            HOPPER.replace("<DtFrac>0.7</DtFrac>", "<DtFrac>fast</DtFrac>"),
            "Simulator/Integration/DtFrac: not a number ('fast')",
        ),
        (
            HOPPER.replace("-0.448395255395,", "-0.44x,", 1),
            "VXC/Structure/PhaseOffset layer 0: not a number ('-0.44x')",
        ),
        (
            HOPPER.replace("<X_Voxels>7</X_Voxels>", "<X_Voxels>100000</X_Voxels>"),
            "VXC/Structure/X_Voxels: must be a whole number 1..64 (got 100000)",
        ),
        (HOPPER.replace('Compression="ASCII_READABLE"', 'Compression="LZMA"'), "Compression must be one of"),
        (
            HOPPER.replace(
                "<StopConditionType>2</StopConditionType>", "<StopConditionType>5</StopConditionType>"
            ),
            "StopConditionType 5 (minimum kinetic energy): only 2 (simulated seconds) and 3",
        ),
        (
            HOPPER.replace("<TempAmp>39</TempAmp>", "<TempAmp>200</TempAmp>"),
            "actuation.amplitude: must be <= 0.9",
        ),
    ],
)
def test_a_bad_file_is_one_line_and_exit_2(capsys, tmp_path, text, message):
    path = _write(text)
    code, stdout, err = run_cli(capsys, "import-vxa", str(path), "--out", str(tmp_path / "s.json"))
    assert code == 2, err
    assert err.startswith("error: ") and err.count("\n") == 1 and message in err, err
    assert stdout == "" and not (tmp_path / "s.json").exists()
    with pytest.raises(VxaError):
        softevo.import_vxa(path)


def test_too_large_files_are_refused_unread(capsys, tmp_path):
    path = tmp_path / "huge.vxa"
    with path.open("wb") as handle:
        handle.truncate(MAX_FILE_BYTES + 1)
    code, _, err = run_cli(capsys, "import-vxa", str(path), "--out", str(tmp_path / "s.json"))
    assert code == 2 and "larger than 20 MB" in err and err.count("\n") == 1


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["missing.vxa", "--out", "s.json"], "cannot read"),
        (["hopper", "--out", "s.txt"], "--out must end in .json"),
    ],
)
def test_cli_mistakes_are_one_line_and_exit_2(capsys, tmp_path, args, message):
    args = [
        str(SAMPLES / "hopper.vxa") if a == "hopper" else str(tmp_path / a) if "." in a else a for a in args
    ]
    code, _, err = run_cli(capsys, "import-vxa", *args)
    assert code == 2 and err.startswith("error: ") and err.count("\n") == 1 and message in err, err
