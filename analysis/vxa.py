"""Export robots as VoxCAD ``.vxa`` files (the XML format VoxCAD, Voxelyze and evosoro read).

Layout of the document written here::

    <VXA Version="1.1">
      <Simulator>   integration (DtFrac), damping, collisions, stop condition (simulated time
                    in seconds; InitCmTime: the settling time before distance is measured)
      <Environment> gravity and floor (land), thermal actuation (sine of period
                    1 / frequency), and a <Fluid> block for water (drag on a quadratic model,
                    the paper's extension; plain VoxCAD ignores it)
      <VXC Version="0.94">
        <Lattice>   Lattice_Dim: the voxel edge in metres
        <Palette>   Material 1 "Passive" (cyan), Material 2 "Active" (red); both with the
                    scene's Young's modulus (Pa), density (kg/m^3), Poisson ratio, friction
        <Structure Compression="ASCII_READABLE">
          <X_Voxels>, <Y_Voxels>, <Z_Voxels>
          <Data>    one <Layer> per z (bottom first), each the material digits of that
                    layer, x fastest, then y (0 empty, 1 passive, 2 active)
          <PhaseOffset> the same layers of per-voxel phase offsets in radians,
                    comma-separated
    </VXA>

Actuation as VoxCAD models it: the temperature oscillates by ``TEMP_AMPLITUDE`` degrees about
``TEMP_BASE`` and the active material's thermal expansion coefficient is
``amplitude / TEMP_AMPLITUDE``, so an active voxel's linear strain swings by the scene's
actuation amplitude (0.39 by default: evosoro's CTE 0.01 at 39 degrees). Only the sine
waveform exists in VoxCAD. Fixed voxels, forces and initial velocities are not exported, nor
are per-voxel fields (``youngs_modulus_field``, ``density_field``, ``frequency_field``): the
palette holds the scene's scalar material and frequency.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any
from xml.sax.saxutils import escape

import numpy as np

TEMP_AMPLITUDE = 39.0
TEMP_BASE = 25.0
MATERIALS = {1: ("Passive", (0, 1, 1)), 2: ("Active", (1, 0, 0))}


def _number(value: float) -> str:
    """A compact, exact-enough decimal (up to 10 significant digits)."""
    return f"{float(value):.10g}"


def _tags(indent: str, pairs: list[tuple[str, Any]]) -> list[str]:
    return [f"{indent}<{tag}>{value}</{tag}>" for tag, value in pairs]


def _block(indent: str, tag: str, body: list[str], attributes: str = "") -> list[str]:
    return [f"{indent}<{tag}{attributes}>", *body, f"{indent}</{tag}>"]


def data_layers(body: np.ndarray) -> list[str]:
    """Material digits per z layer (bottom first), x fastest then y: one string per layer."""
    body = np.asarray(body, dtype=int)
    if body.min(initial=0) < 0 or body.max(initial=0) > 9:
        raise ValueError("material ids must be single digits 0-9")
    # body[x, y, z]; a layer read x fastest then y is body[:, :, z] in Fortran order
    return ["".join(str(v) for v in body[:, :, z].ravel(order="F")) for z in range(body.shape[2])]


def phase_layers(phase: np.ndarray) -> list[str]:
    """Phase offsets (radians) per z layer, same order as ``data_layers``, comma-separated."""
    phase = np.asarray(phase, dtype=float)
    return [", ".join(_number(v) for v in phase[:, :, z].ravel(order="F")) for z in range(phase.shape[2])]


def _simulator(scene, indent: str) -> list[str]:
    i2, i3 = indent + "  ", indent + "    "
    m = scene.material
    return _block(
        indent,
        "Simulator",
        [
            *_block(
                i2, "Integration", _tags(i3, [("Integrator", 0), ("DtFrac", _number(scene.dt_fraction))])
            ),
            *_block(
                i2,
                "Damping",
                _tags(
                    i3,
                    [
                        ("BondDampingZ", _number(m.damping_bond)),
                        ("ColDampingZ", _number(m.damping_collision)),
                        ("SlowDampingZ", _number(m.damping_global)),
                    ],
                ),
            ),
            *_block(
                i2,
                "Collisions",
                _tags(
                    i3,
                    [
                        ("SelfColEnabled", int(scene.self_collisions)),
                        ("ColSystem", 3),
                        ("CollisionHorizon", 2),
                    ],
                ),
            ),
            *_block(
                i2,
                "Features",
                _tags(
                    i3, [("FluidDampEnabled", 0), ("PoissonKickBackEnabled", 0), ("EnforceLatticeEnabled", 0)]
                ),
            ),
            *_block(
                i2,
                "StopCondition",
                _tags(
                    i3,
                    [
                        ("StopConditionType", 2),
                        ("StopConditionValue", _number(scene.total_seconds)),
                        ("InitCmTime", _number(scene.settle_seconds)),
                        ("ActuationStartTime", 0),
                    ],
                ),
            ),
            *_block(i2, "EquilibriumMode", _tags(i3, [("EquilibriumModeEnabled", 0)])),
        ],
    )


def _environment(scene, indent: str) -> list[str]:
    i2, i3 = indent + "  ", indent + "    "
    env, act = scene.environment, scene.actuation
    water = env.kind == "water"
    return _block(
        indent,
        "Environment",
        [
            *_block(i2, "Fixed_Regions", _tags(i3, [("NumFixed", 0)])),
            *_block(i2, "Forced_Regions", _tags(i3, [("NumForced", 0)])),
            *_block(
                i2,
                "Gravity",
                _tags(
                    i3,
                    [
                        ("GravEnabled", int(env.gravity > 0)),
                        ("GravAcc", _number(-env.gravity)),
                        ("FloorEnabled", int(env.kind == "land")),
                    ],
                ),
            ),
            *_block(
                i2,
                "Thermal",
                _tags(
                    i3,
                    [
                        ("TempEnabled", 1),
                        ("TempAmp", _number(TEMP_AMPLITUDE)),
                        ("TempBase", _number(TEMP_BASE)),
                        ("VaryTempEnabled", 1),
                        ("TempPeriod", _number(1.0 / act.frequency)),
                    ],
                ),
            ),
            *_block(
                i2,
                "Fluid",
                _tags(
                    i3,
                    [
                        ("FluidEnvironment", int(water)),
                        ("FluidDensity", _number(env.fluid_density)),
                        ("DragCoefficient", _number(env.drag_coefficient)),
                    ],
                ),
            ),
        ],
    )


def _material(scene, material_id: int, indent: str) -> list[str]:
    i2, i3 = indent + "  ", indent + "    "
    name, (red, green, blue) = MATERIALS[material_id]
    m = scene.material
    expansion = scene.actuation.amplitude / TEMP_AMPLITUDE if material_id == 2 else 0.0
    mechanical = _tags(
        i3,
        [
            ("MatModel", 0),
            ("Elastic_Mod", _number(m.youngs_modulus)),
            ("Plastic_Mod", 0),
            ("Yield_Stress", 0),
            ("FailModel", 0),
            ("Fail_Stress", 0),
            ("Fail_Strain", 0),
            ("Density", _number(m.density)),
            ("Poissons_Ratio", _number(m.poisson_ratio)),
            ("CTE", _number(expansion)),
            ("uStatic", _number(m.friction_static)),
            ("uDynamic", _number(m.friction_kinetic)),
        ],
    )
    return _block(
        indent,
        "Material",
        [
            *_tags(i2, [("MatType", 0), ("Name", escape(name))]),
            *_block(i2, "Display", _tags(i3, [("Red", red), ("Green", green), ("Blue", blue), ("Alpha", 1)])),
            *_block(i2, "Mechanical", mechanical),
        ],
        f' ID="{material_id}"',
    )


def _structure(scene, indent: str) -> list[str]:
    i2, i3 = indent + "  ", indent + "    "
    nx, ny, nz = scene.body.shape
    layers = [f"{i3}<Layer><![CDATA[{text}]]></Layer>" for text in data_layers(scene.body)]
    phases = [f"{i3}<Layer><![CDATA[{text}]]></Layer>" for text in phase_layers(scene.phase)]
    return _block(
        indent,
        "Structure",
        [
            *_tags(i2, [("X_Voxels", nx), ("Y_Voxels", ny), ("Z_Voxels", nz)]),
            *_block(i2, "Data", layers),
            *_block(i2, "PhaseOffset", phases),
        ],
        ' Compression="ASCII_READABLE"',
    )


def _vxc(scene, indent: str) -> list[str]:
    i2, i3 = indent + "  ", indent + "    "
    lattice = _tags(
        i3,
        [
            ("Lattice_Dim", _number(scene.voxel_size)),
            ("X_Dim_Adj", 1),
            ("Y_Dim_Adj", 1),
            ("Z_Dim_Adj", 1),
            ("X_Line_Offset", 0),
            ("Y_Line_Offset", 0),
            ("X_Layer_Offset", 0),
            ("Y_Layer_Offset", 0),
        ],
    )
    voxel = _tags(i3, [("Vox_Name", "BOX"), ("X_Squeeze", 1), ("Y_Squeeze", 1), ("Z_Squeeze", 1)])
    palette = [line for k in sorted(MATERIALS) for line in _material(scene, k, i3)]
    return _block(
        indent,
        "VXC",
        [
            *_block(i2, "Lattice", lattice),
            *_block(i2, "Voxel", voxel),
            *_block(i2, "Palette", palette),
            *_structure(scene, i2),
        ],
        ' Version="0.94"',
    )


def scene_to_vxa(scene: dict[str, Any]) -> str:
    """The ``.vxa`` document of a simulator scene (SPEC.md section 1 schema)."""
    from softevo import sim

    parsed = sim.parse_scene(scene)
    lines = [
        '<?xml version="1.0" encoding="ISO-8859-1"?>',
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
    """The ``.vxa`` document of a stored record (``service.db.individuals.individual_record``), in
    the environment of its latest evaluation unless ``environment`` is given."""
    from softevo.analysis.robots import record_scene

    scene, _ = record_scene(record, environment)
    return scene_to_vxa(scene)
