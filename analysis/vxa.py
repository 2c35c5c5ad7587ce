"""VoxCAD ``.vxa`` files (the XML format VoxCAD, Voxelyze and evosoro read): the format's
constants, and the export of scenes. ``analysis.vxa_import`` reads the files back.

The reader this module writes for is the paper's engine, the VoxCAD land/water fork in
evosoro (``_voxcad_land_water``), so each value sits where that fork looks for it::

    <VXA Version="1.1">
      <Simulator>   DtFrac; the damping ratios; SelfColEnabled and CollisionHorizon
                    (= collision_horizon / 1.5: the fork ignores pairs within
                    int(CollisionHorizon * 1.5) bond hops); StopConditionType 2 (simulated
                    seconds) with StopConditionValue = settle + duration, and InitCmTime =
                    settle_seconds (the fork measures distance, and actuates, from then on)
      <Environment> FluidEnvironment and AggregateDragCoefficient (= 0.5 fluid_density
                    drag_coefficient), directly under <Environment> where the fork reads them;
                    gravity and floor (land); the thermal actuation (below)
      <VXC Version="0.94">
        <Lattice>   Lattice_Dim: the voxel edge in metres
        <Palette>   Material 1 "Passive" (cyan), Material 2 "Active" (red), with the scene's
                    Young's modulus (Pa), density (kg/m^3), Poisson ratio, friction; with a
                    ``density_field`` one material per distinct density of each kind
        <Structure Compression="ASCII_READABLE"> (BASE64 when the palette passes 9 materials)
          <X_Voxels>, <Y_Voxels>, <Z_Voxels>
          <Data>    one <Layer> per z (bottom first), each the material ids of that layer,
                    x fastest, then y (0 empty)
          <PhaseOffset> the same layers of per-voxel phase offsets in CYCLES (phase / 2 pi),
                    comma-separated: the fork actuates sin(2 pi (t / TempPeriod + offset))
          <Stiffness> with a ``youngs_modulus_field``: the same layers of per-voxel Young's
                    moduli (Pa), which the fork puts in place of the material's
    </VXA>

Actuation as the fork models it: an active voxel's size is
``L (1 + TempAmplitude sin(2 pi (t / TempPeriod + offset)) CTE)``, where TempAmplitude is
``TempAmp - TempBase`` (a file without <TempAmplitude>). The active material's CTE is
``ACTIVE_CTE`` (0.01) and TempBase ``TEMP_BASE`` (25), so ``TempAmp = TempBase + amplitude /
CTE`` makes the strain the scene's amplitude (the paper's files: TempAmp 39, amplitude 0.14).
TempPeriod is 1 / frequency. Only the sine waveform exists there, and one period: with a
``frequency_field`` of several values the file has their mean (a ``VxaWarning`` says so).
Fixed voxels, forces and initial velocities are not exported (a warning names them), nor
are the model's other switches (rotation damping, drag model, ...): the fork runs its own
physics, which is ``"model": "voxcad-land-water"``. A scene of another model (``voxelyze-2``,
``softevo run``'s default) is written all the same, with a ``VxaWarning`` and an XML comment
saying so, which ``softevo import-vxa`` turns into a warning again: re-imported, such a robot
runs the paper's physics and its distance differs from the stored one.
"""

from __future__ import annotations

import base64
import math
import warnings
from pathlib import Path
from typing import Any
from xml.sax.saxutils import escape

import numpy as np

from softevo.errors import UserError
from softevo.sim import worlds

TEMP_BASE = 25.0  # degrees: the temperature the sine swings about
ACTIVE_CTE = 0.01  # the active material's thermal expansion coefficient (1 / degree)
COLLISION_HORIZON_FACTOR = 1.5  # the fork's CalcNearby(int(CollisionHorizon * 1.5))
FLUID_DENSITY = 1000.0  # kg / m^3: what an imported water scene assumes (the file has only the product)
STOP_SIMULATED_TIME, STOP_TEMPERATURE_CYCLES = 2, 3  # VX_Enums.h StopCondition
STOP_TYPES = {
    0: "none: runs forever",
    1: "time steps",
    2: "simulated seconds",
    3: "temperature cycles",
    4: "constant energy",
    5: "minimum kinetic energy",
    6: "minimum motion",
}
COMPRESSIONS = ("ASCII_READABLE", "BASE64", "ZLIB", "QT_ZLIB")  # what the fork decodes
VXC_VERSIONS = ("", "0.93", "0.94")  # the fork reads <Data> layers only in these
MAX_ASCII_MATERIAL = 9  # material ids one digit holds
MAX_MATERIAL = 127  # the fork keeps material ids in a (signed) char
MATERIAL_COLOURS = {1: ("Passive", (0, 1, 1)), 2: ("Active", (1, 0, 0))}


class VxaError(UserError):
    """A VXA file that cannot be read, or a scene that cannot be written as one."""


class VxaWarning(UserWarning):
    """Something a VXA file holds that a scene cannot (or the reverse): said, then skipped."""


def aggregate_drag(fluid_density: float, drag_coefficient: float) -> float:
    """The fork's AggregateDragCoefficient (drag = ADC x facet area x speed^2, N s^2 / m^4)."""
    return 0.5 * fluid_density * drag_coefficient


def _number(value: float) -> str:
    """A compact decimal, exact to 12 significant digits."""
    return f"{float(value):.12g}"


def _tags(indent: str, pairs: list[tuple[str, Any]]) -> list[str]:
    return [f"{indent}<{tag}>{value}</{tag}>" for tag, value in pairs]


def _block(indent: str, tag: str, body: list[str], attributes: str = "") -> list[str]:
    return [f"{indent}<{tag}{attributes}>", *body, f"{indent}</{tag}>"]


def data_layers(materials: np.ndarray) -> list[str]:
    """Material digits per z layer (bottom first), x fastest then y: one string per layer."""
    materials = np.asarray(materials, dtype=int)
    if materials.min(initial=0) < 0 or materials.max(initial=0) > MAX_ASCII_MATERIAL:
        raise ValueError("material ids must be single digits 0-9")
    # materials[x, y, z]; a layer read x fastest then y is [:, :, z] in Fortran order
    return ["".join(str(v) for v in materials[:, :, z].ravel(order="F")) for z in range(materials.shape[2])]


def base64_layers(materials: np.ndarray) -> list[str]:
    """Material ids per z layer as base64 bytes (Compression BASE64), same order as ``data_layers``."""
    materials = np.asarray(materials, dtype=np.uint8)
    return [
        base64.b64encode(materials[:, :, z].ravel(order="F").tobytes()).decode("ascii")
        for z in range(materials.shape[2])
    ]


def value_layers(values: np.ndarray) -> list[str]:
    """Numbers per z layer (bottom first), x fastest then y, comma-separated: <PhaseOffset>
    and <Stiffness> layers."""
    values = np.asarray(values, dtype=float)
    return [", ".join(_number(v) for v in values[:, :, z].ravel(order="F")) for z in range(values.shape[2])]


def collision_horizon_value(horizon: int) -> str:
    """The CollisionHorizon text the fork reads back as ``horizon`` bond hops:
    int(value * 1.5) == horizon, the value as near horizon / 1.5 as 12 digits allow."""
    for nudge in (0.0, 1e-11, 1e-10):
        text = _number(horizon / COLLISION_HORIZON_FACTOR * (1 + nudge))
        if int(float(text) * COLLISION_HORIZON_FACTOR) == horizon:
            return text
    raise AssertionError(f"no CollisionHorizon reads back as {horizon}")  # pragma: no cover


def _palette(scene) -> tuple[list[tuple[int, float]], np.ndarray]:
    """The materials ``[(kind, density), ...]`` (ids 1, 2, ... in order) and each voxel's id:
    passive then active, one per distinct density of that kind (one each without a field)."""
    body, densities = scene.body, scene.density_field
    materials: list[tuple[int, float]] = []
    ids = np.zeros(body.shape, dtype=int)
    for kind in (1, 2):
        mine = body == kind
        values = (
            [scene.material.density] if densities is None or not mine.any() else np.unique(densities[mine])
        )
        for density in values:
            materials.append((kind, float(density)))
            ids[mine if densities is None else mine & (densities == density)] = len(materials)
    if len(materials) > MAX_MATERIAL:
        raise VxaError(
            f"density_field: {len(materials)} distinct materials; a VoxCAD palette holds {MAX_MATERIAL}"
        )
    return materials, ids


def _frequency(scene) -> float:
    """The one actuation frequency the file can hold (the mean over active voxels of a field)."""
    from softevo.sim.scene import mean_active_frequency

    if scene.frequency_field is None:
        return scene.actuation.frequency
    frequency = mean_active_frequency(scene.body, scene.frequency_field, scene.actuation.frequency)
    if len(np.unique(scene.frequency_field[scene.body == 2])) > 1:
        warnings.warn(
            f"frequency_field: VoxCAD has one actuation period; the file has the mean "
            f"active frequency, {frequency:.6g} Hz",
            VxaWarning,
            stacklevel=4,
        )
    return frequency


def _simulator(scene, indent: str) -> list[str]:
    i2, i3 = indent + "  ", indent + "    "
    m = scene.material
    damping = [
        ("BondDampingZ", _number(m.damping_bond)),
        ("ColDampingZ", _number(m.damping_collision)),
        ("SlowDampingZ", _number(m.damping_global)),
    ]
    collisions = [
        ("SelfColEnabled", int(scene.self_collisions)),
        ("ColSystem", 3),
        ("CollisionHorizon", collision_horizon_value(scene.options.collision_horizon)),
    ]
    features = [("FluidDampEnabled", 0), ("PoissonKickBackEnabled", 0), ("EnforceLatticeEnabled", 0)]
    stop = [
        ("StopConditionType", STOP_SIMULATED_TIME),
        ("StopConditionValue", _number(scene.total_seconds)),
        ("InitCmTime", _number(scene.settle_seconds)),
    ]
    return _block(
        indent,
        "Simulator",
        [
            *_block(
                i2, "Integration", _tags(i3, [("Integrator", 0), ("DtFrac", _number(scene.dt_fraction))])
            ),
            *_block(i2, "Damping", _tags(i3, damping)),
            *_block(i2, "Collisions", _tags(i3, collisions)),
            *_block(i2, "Features", _tags(i3, features)),
            *_block(i2, "StopCondition", _tags(i3, stop)),
            *_block(i2, "EquilibriumMode", _tags(i3, [("EquilibriumModeEnabled", 0)])),
        ],
    )


def _environment(scene, indent: str) -> list[str]:
    i2, i3 = indent + "  ", indent + "    "
    env, act = scene.environment, scene.actuation
    water = worlds.get(env.kind).drag
    if water and env.gravity != 0:
        warnings.warn(
            "environment.gravity: the fork has no gravity in water (neutral buoyancy)",
            VxaWarning,
            stacklevel=4,
        )
    frequency = _frequency(scene)
    thermal = [
        ("TempEnabled", int(frequency > 0)),
        ("TempAmp", _number(TEMP_BASE + act.amplitude / ACTIVE_CTE)),
        ("TempBase", _number(TEMP_BASE)),
        ("VaryTempEnabled", 1),
        ("TempPeriod", _number(1.0 / frequency if frequency > 0 else 1.0)),
    ]
    gravity = [
        ("GravEnabled", int(env.gravity != 0)),
        ("GravAcc", _number(-env.gravity)),
        ("FloorEnabled", int(worlds.get(env.kind).floor)),
    ]
    return _block(
        indent,
        "Environment",
        [
            *_tags(
                i2,
                [
                    ("FluidEnvironment", int(water)),
                    (
                        "AggregateDragCoefficient",
                        _number(aggregate_drag(env.fluid_density, env.drag_coefficient)),
                    ),
                ],
            ),
            *_block(i2, "Fixed_Regions", _tags(i3, [("NumFixed", 0)])),
            *_block(i2, "Forced_Regions", _tags(i3, [("NumForced", 0)])),
            *_block(i2, "Gravity", _tags(i3, gravity)),
            *_block(i2, "Thermal", _tags(i3, thermal)),
        ],
    )


def _material(scene, material_id: int, kind: int, density: float, indent: str) -> list[str]:
    i2, i3 = indent + "  ", indent + "    "
    name, (red, green, blue) = MATERIAL_COLOURS[kind]
    if scene.density_field is not None:
        name = f"{name} {_number(density)}"
    m = scene.material
    mechanical = [
        ("MatModel", 0),
        ("Elastic_Mod", _number(m.youngs_modulus)),
        ("Plastic_Mod", 0),
        ("Yield_Stress", 0),
        ("FailModel", 0),
        ("Fail_Stress", 0),
        ("Fail_Strain", 0),
        ("Density", _number(density)),
        ("Poissons_Ratio", _number(m.poisson_ratio)),
        ("CTE", _number(ACTIVE_CTE if kind == 2 else 0.0)),
        ("uStatic", _number(m.friction_static)),
        ("uDynamic", _number(m.friction_kinetic)),
    ]
    return _block(
        indent,
        "Material",
        [
            *_tags(i2, [("MatType", 0), ("Name", escape(name))]),
            *_block(i2, "Display", _tags(i3, [("Red", red), ("Green", green), ("Blue", blue), ("Alpha", 1)])),
            *_block(i2, "Mechanical", _tags(i3, mechanical)),
        ],
        f' ID="{material_id}"',
    )


def _layers(indent: str, tag: str, texts: list[str], head: list[str] | None = None) -> list[str]:
    return _block(indent, tag, [*(head or []), *(f"{indent}  <Layer><![CDATA[{t}]]></Layer>" for t in texts)])


def _structure(scene, ids: np.ndarray, indent: str) -> list[str]:
    i2 = indent + "  "
    nx, ny, nz = scene.body.shape
    ascii_ids = ids.max() <= MAX_ASCII_MATERIAL
    body = [
        *_tags(i2, [("X_Voxels", nx), ("Y_Voxels", ny), ("Z_Voxels", nz)]),
        *_layers(i2, "Data", data_layers(ids) if ascii_ids else base64_layers(ids)),
        *_layers(i2, "PhaseOffset", value_layers(scene.phase / (2 * math.pi))),
    ]
    stiffness = scene.youngs_modulus_field
    if stiffness is not None:
        present = stiffness[scene.body > 0]
        bounds = _tags(
            i2 + "  ", [("MinElasticMod", _number(present.min())), ("MaxElasticMod", _number(present.max()))]
        )
        body += _layers(i2, "Stiffness", value_layers(stiffness), bounds)
    compression = "ASCII_READABLE" if ascii_ids else "BASE64"
    return _block(indent, "Structure", body, f' Compression="{compression}"')


def _vxc(scene, indent: str) -> list[str]:
    i2, i3 = indent + "  ", indent + "    "
    lattice = [
        ("Lattice_Dim", _number(scene.voxel_size)),
        ("X_Dim_Adj", 1),
        ("Y_Dim_Adj", 1),
        ("Z_Dim_Adj", 1),
        ("X_Line_Offset", 0),
        ("Y_Line_Offset", 0),
        ("X_Layer_Offset", 0),
        ("Y_Layer_Offset", 0),
    ]
    voxel = _tags(i3, [("Vox_Name", "BOX"), ("X_Squeeze", 1), ("Y_Squeeze", 1), ("Z_Squeeze", 1)])
    materials, ids = _palette(scene)
    palette = [
        line
        for k, (kind, density) in enumerate(materials, 1)
        for line in _material(scene, k, kind, density, i3)
    ]
    return _block(
        indent,
        "VXC",
        [
            *_block(i2, "Lattice", _tags(i3, lattice)),
            *_block(i2, "Voxel", voxel),
            *_block(i2, "Palette", palette),
            *_structure(scene, ids, i2),
        ],
        ' Version="0.94"',
    )


def _warn_unexported(scene) -> None:
    left_out = [
        name
        for name, present in (
            ("fixed", len(scene.fixed)),
            ("forces", len(scene.force_voxels)),
            ("initial_velocity", any(scene.initial_velocity)),
            ("initial_angular_velocity", any(scene.initial_angular_velocity)),
            ("initial_offset", any(scene.initial_offset)),
        )
        if present
    ]
    if left_out:
        warnings.warn(f"not in the VXA file: {', '.join(left_out)}", VxaWarning, stacklevel=3)


EXPORTED_FROM = "softevo: written from a "  # the comment that names another model's scene
VXA_MODEL = "voxcad-land-water"  # the physics a .vxa file holds: the paper's engine


def _other_model_note(scene) -> str | None:
    """What a reader must know when ``scene``'s model is not the one a VXA file holds (a
    ``VxaWarning`` now, a comment in the file that ``softevo import-vxa`` warns about), or None."""
    if scene.model == VXA_MODEL:
        return None
    note = (f"a .vxa file holds the paper's engine ({VXA_MODEL}), so VoxCAD, evosoro and softevo "
            f"import-vxa simulate this {scene.model} robot with other physics: its distance differs")
    warnings.warn(f"the robot's model is {scene.model}: {note}", VxaWarning, stacklevel=3)
    return note


def scene_to_vxa(scene: dict[str, Any]) -> str:
    """The ``.vxa`` document of a simulator scene (docs/spec.md section 1 schema)."""
    from softevo import sim

    parsed = sim.parse_scene(scene)
    _warn_unexported(parsed)
    other_model = _other_model_note(parsed)
    lines = [
        '<?xml version="1.0" encoding="ISO-8859-1"?>',
        *([f"<!-- {EXPORTED_FROM}{parsed.model} scene: {other_model} -->"] if other_model else []),
        '<VXA Version="1.1">',
        *_simulator(parsed, "  "),
        *_environment(parsed, "  "),
        *_vxc(parsed, "  "),
        "</VXA>",
    ]
    return "\n".join(lines) + "\n"


def write_vxa(scene: dict[str, Any], out: str | Path) -> Path:
    """Write ``scene_to_vxa(scene)`` to ``out``."""
    out = Path(out)
    out.write_text(scene_to_vxa(scene), encoding="iso-8859-1")
    return out


def record_vxa(record: dict[str, Any], environment: str | None = None) -> str:
    """The ``.vxa`` document of a stored record (``service.storage.individuals.individual_record``), in
    the environment of its latest evaluation unless ``environment`` is given."""
    from softevo.analysis.robots import record_scene

    scene, _ = record_scene(record, environment)
    return scene_to_vxa(scene)
