"""Read VoxCAD / evosoro ``.vxa`` files as scenes (``softevo import-vxa``, ``softevo.import_vxa``).

The reading follows the paper's engine, the VoxCAD land/water fork in evosoro
(``_voxcad_land_water/Voxelyze``): each value is looked for where that fork looks, with the
fork's default where the file is silent (a tag missing from its block, or the block missing),
and the scene is the fork's physics, ``"model": "voxcad-land-water"``, with every
``model_options`` switch written out. The constants and the export are in ``analysis.vxa``.

=============================================  =============================================
VXA                                            scene
=============================================  =============================================
Structure Data layers (one per z, x fastest,   ``body``: 2 where the voxel's material has
then y; ASCII_READABLE, BASE64, ZLIB, QT_ZLIB)  CTE != 0 (active), else 1
PhaseOffset layers (cycles)                    ``phase`` = 2 pi offset (+ pi where the strain
                                               TempAmplitude x CTE is negative)
Stiffness layers, else each Elastic_Mod        ``material.youngs_modulus``, or
                                               ``youngs_modulus_field`` when voxels differ
Density                                        ``material.density`` or ``density_field``
Poissons_Ratio, uStatic, uDynamic              ``material`` (one value: that of most voxels)
TempAmplitude (TempAmp - TempBase) x |CTE|     ``actuation.amplitude`` (several: the largest)
TempPeriod                                     ``actuation.frequency`` = 1 / TempPeriod
FluidEnvironment 1, AggregateDragCoefficient   ``environment`` water (no gravity, no floor, as
                                               in the fork), fluid_density 1000,
                                               drag_coefficient = ADC / (0.5 x 1000)
FloorEnabled 1 / neither                       land / void, gravity -GravAcc if GravEnabled
BondDampingZ, ColDampingZ, SlowDampingZ        ``material.damping_bond``, ``_collision``,
                                               ``_global``
SelfColEnabled                                 ``self_collisions``
CollisionHorizon                               ``model_options.collision_horizon`` =
                                               int(CollisionHorizon x 1.5)
DtFrac                                         ``dt_fraction``
InitCmTime                                     ``settle_seconds``
StopConditionType 2 (seconds) or 3 (cycles of  ``duration.seconds`` = stop time - InitCmTime
TempPeriod), StopConditionValue
Lattice_Dim                                    ``voxel_size``
=============================================  =============================================

A ``VxaWarning`` (``Imported.warnings``: one line each) says what the file holds and the scene
cannot: tags the fork does not read or a scene has no place for (one warning lists them all),
fixed and forced regions, non-linear or failing materials, unequal CTE magnitudes, Poisson
ratios or friction, velocity limits, blending, non-cubic lattices. A file that cannot be read
raises ``VxaError`` (a ``UserError``: the CLI prints one line and exits 2): not XML, a DTD or
entities (refused outright: no entity expansion, no external entities), larger than
``MAX_FILE_BYTES``, a workspace side beyond ``sim.scene.MAX_SIDE``, no Structure, layers of
the wrong count or length, numbers that are not numbers, a stop condition that is not a time.
"""

from __future__ import annotations

import base64
import binascii
import math
import re
import warnings
import zlib
from dataclasses import dataclass
from pathlib import Path
from typing import Any
from xml.etree.ElementTree import Element, ParseError

import numpy as np

from softevo.analysis.vxa import (
    COLLISION_HORIZON_FACTOR,
    COMPRESSIONS,
    FLUID_DENSITY,
    STOP_SIMULATED_TIME,
    STOP_TEMPERATURE_CYCLES,
    STOP_TYPES,
    VXC_VERSIONS,
    VxaError,
    VxaWarning,
    aggregate_drag,
)
from softevo.sim import worlds

__all__ = ["MAX_FILE_BYTES", "Imported", "VxaError", "VxaWarning", "import_vxa", "read_vxa", "vxa_to_scene"]

MAX_FILE_BYTES = 20 * 1024 * 1024  # the paper's files are ~12 KB; a 64^3 robot with phases ~10 MB


def _leaves(*names: str) -> dict[str, None]:
    return dict.fromkeys(names)


ANY = "any"  # a block whose contents are not looked into
_MATERIAL = {
    "MatType": None,
    "Name": None,
    "Display": _leaves("Red", "Green", "Blue", "Alpha"),
    "Mechanical": {
        **_leaves(
            "MatModel",
            "Elastic_Mod",
            "Plastic_Mod",
            "Yield_Stress",
            "FailModel",
            "Fail_Stress",
            "Fail_Strain",
            "Density",
            "Poissons_Ratio",
            "CTE",
            "MaterialTempPhase",
            "uStatic",
            "uDynamic",
        ),
        "SSData": ANY,
    },
}
# Every tag the fork reads, where it reads it (plus PoissonKickBackEnabled and FloorSlope,
# which evosoro writes and nothing reads); anything else is listed in one warning.
KNOWN: dict[str, Any] = {
    "Simulator": {
        "Integration": _leaves("Integrator", "DtFrac"),
        "Damping": _leaves("BondDampingZ", "ColDampingZ", "SlowDampingZ"),
        "Collisions": _leaves("SelfColEnabled", "ColSystem", "CollisionHorizon"),
        "Features": _leaves(
            "MaxVelLimitEnabled",
            "MaxVoxVelLimit",
            "BlendingEnabled",
            "MixRadius",
            "XMixRadius",
            "YMixRadius",
            "ZMixRadius",
            "BlendModel",
            "PolyExp",
            "FluidDampEnabled",
            "VolumeEffectsEnabled",
            "EnforceLatticeEnabled",
            "PoissonKickBackEnabled",
        ),
        "StopCondition": _leaves("StopConditionType", "StopConditionValue", "InitCmTime"),
        "EquilibriumMode": _leaves("EquilibriumModeEnabled"),
        "SurfMesh": ANY,
        "GA": _leaves(
            "Fitness",
            "FitnessType",
            "TrackVoxel",
            "FitnessFileName",
            "QhullTmpFile",
            "CurvaturesTmpFile",
            "WriteFitnessFile",
        ),
    },
    "Environment": {
        "FluidEnvironment": None,
        "AggregateDragCoefficient": None,
        "Boundary_Conditions": ANY,
        "Fixed_Regions": ANY,
        "Forced_Regions": ANY,
        "NeuralNet": ANY,
        "Gravity": _leaves("GravEnabled", "GravAcc", "FloorEnabled", "FloorSlope"),
        "Thermal": _leaves(
            "TempEnabled", "TempAmplitude", "TempAmp", "TempBase", "VaryTempEnabled", "TempPeriod"
        ),
    },
    "VXC": {
        "Lattice": _leaves(
            "Lattice_Dim",
            "X_Dim_Adj",
            "Y_Dim_Adj",
            "Z_Dim_Adj",
            "X_Line_Offset",
            "Y_Line_Offset",
            "X_Layer_Offset",
            "Y_Layer_Offset",
        ),
        "Voxel": _leaves("Vox_Name", "X_Squeeze", "Y_Squeeze", "Z_Squeeze"),
        "Palette": {"Material": _MATERIAL},
        "Structure": {
            **_leaves("X_Voxels", "Y_Voxels", "Z_Voxels"),
            "Data": _leaves("Layer"),
            "PhaseOffset": _leaves("Layer"),
            "Stiffness": _leaves("MinElasticMod", "MaxElasticMod", "Layer"),
        },
    },
}
# (tag, default when the tag is missing from its block, default when the block is missing):
# the fork's ReadXML and constructor defaults (VX_Sim.cpp, VX_Environment.cpp)
_SIMULATOR = {
    "dt_fraction": ("Integration/DtFrac", 0.9, 0.9),
    "damping_bond": ("Damping/BondDampingZ", 0.1, 0.1),
    "damping_collision": ("Damping/ColDampingZ", 1.0, 1.0),
    "damping_global": ("Damping/SlowDampingZ", 1.0, 0.001),
    "self_collisions": ("Collisions/SelfColEnabled", 0, 0),
    "col_system": ("Collisions/ColSystem", 3, 3),
    "collision_horizon": ("Collisions/CollisionHorizon", 2.0, 3.0),
    "max_velocity": ("Features/MaxVelLimitEnabled", 0, 0),
    "blending": ("Features/BlendingEnabled", 0, 0),
    "volume_effects": ("Features/VolumeEffectsEnabled", 0, 0),
    "stop_type": ("StopCondition/StopConditionType", 0, 0),
    "stop_value": ("StopCondition/StopConditionValue", 0.0, 0.0),
    "init_cm_time": ("StopCondition/InitCmTime", 0.0, 0.0),
    "equilibrium": ("EquilibriumMode/EquilibriumModeEnabled", 0, 0),
}
_ENVIRONMENT = {
    "fluid": ("FluidEnvironment", 0, 0),
    "aggregate_drag": ("AggregateDragCoefficient", 0.0, 0.0),
    "gravity_enabled": ("Gravity/GravEnabled", 0, 1),
    "gravity_acceleration": ("Gravity/GravAcc", -9.81, -9.81),
    "floor": ("Gravity/FloorEnabled", 0, 1),
    "floor_slope": ("Gravity/FloorSlope", 0.0, 0.0),
    "temp_enabled": ("Thermal/TempEnabled", 0, 1),
    "temp_base": ("Thermal/TempBase", 25.0, 25.0),
    "temp_period": ("Thermal/TempPeriod", 0.1, 0.1),
    "num_fixed": ("Fixed_Regions/NumFixed", 0, 0),
    "num_forced": ("Forced_Regions/NumForced", 0, 0),
    "num_bcs": ("Boundary_Conditions/NumBCs", 0, 0),
}
_LATTICE = {
    "voxel_size": ("Lattice/Lattice_Dim", 0.001, 0.001),
    **{name: (f"Lattice/{name}", 1.0, 1.0) for name in ("X_Dim_Adj", "Y_Dim_Adj", "Z_Dim_Adj")},
    **{
        name: (f"Lattice/{name}", 0.0, 0.0)
        for name in ("X_Line_Offset", "Y_Line_Offset", "X_Layer_Offset", "Y_Layer_Offset")
    },
}
_MECHANICAL = (
    "MatModel",
    "Elastic_Mod",
    "Density",
    "Poissons_Ratio",
    "CTE",
    "uStatic",
    "uDynamic",
    "Fail_Stress",
    "Fail_Strain",
)


@dataclass(frozen=True)
class Imported:
    """A scene read from a VXA file, and what the file held that the scene does not (one line each)."""

    scene: dict[str, Any]
    warnings: tuple[str, ...]


def import_vxa(path: str | Path) -> dict[str, Any]:
    """The scene of a VoxCAD / evosoro ``.vxa`` file (our schema, ``"model": "voxcad-land-water"``);
    what it could not map is said with ``warnings.warn(..., VxaWarning)``. Raises ``VxaError``."""
    imported = read_vxa(path)
    for message in imported.warnings:
        warnings.warn(message, VxaWarning, stacklevel=2)
    return imported.scene


def read_vxa(path: str | Path) -> Imported:
    """``vxa_to_scene`` of the file at ``path`` (at most ``MAX_FILE_BYTES``)."""
    path = Path(path)
    try:
        with path.open("rb") as handle:
            data = handle.read(MAX_FILE_BYTES + 1)
    except OSError as exc:
        raise VxaError(f"cannot read {path}: {exc.strerror or exc}") from None
    if len(data) > MAX_FILE_BYTES:
        raise VxaError(f"{path.name}: larger than {MAX_FILE_BYTES // 2**20} MB, the most a VXA file may be")
    return vxa_to_scene(data, path.name)


def vxa_to_scene(data: bytes, name: str = "VXA") -> Imported:
    """The scene (a dict, validated) of a VXA document; ``name`` prefixes error messages."""
    root = _parse_xml(data, name)
    file = _File(root, name)
    unknown = _unknown(root, KNOWN, "")
    if unknown:
        file.warn(
            f"tags not imported (the fork does not read them, or a scene has no place for them): "
            f"{', '.join(unknown)}"
        )
    scene = _scene(file)
    exported = re.search(rb"<!-- softevo: written from a ([\w.-]+) scene", data)
    if exported is not None:
        file.warn(f"this file was written from a {exported.group(1).decode()} robot: imported, it runs the "
                  f"paper's engine ({scene.get('model', 'voxcad-land-water')}), so its distance differs "
                  f"from the stored one")
    from softevo.sim import SceneError, parse_scene

    try:
        parse_scene(scene)
    except SceneError as exc:
        raise VxaError(f"{name}: the file makes an invalid scene: {exc}") from None
    return Imported(scene, tuple(file.notes))


def _parse_xml(data: bytes, name: str) -> Element:
    """The root element, parsed by defusedxml with DTDs (so entities, internal or external) refused."""
    from defusedxml import DefusedXmlException
    from defusedxml.ElementTree import fromstring

    try:
        root = fromstring(data, forbid_dtd=True, forbid_entities=True, forbid_external=True)
    except DefusedXmlException:
        raise VxaError(
            f"{name}: refused: the file declares a DTD or entities, which a VXA file never needs "
            f"(entity expansion and external entities are not read)"
        ) from None
    except ParseError as exc:
        raise VxaError(f"{name}: not an XML file ({exc})") from None
    if root.tag != "VXA":
        raise VxaError(f"{name}: the root element is <{root.tag}>, not <VXA>")
    return root


def _unknown(element: Element, schema: dict[str, Any], path: str) -> list[str]:
    """Paths of the child tags of ``element`` (recursively) that ``schema`` does not know."""
    found: list[str] = []
    for child in element:
        where = f"{path}{child.tag}"
        if child.tag not in schema:
            found.append(where)
        elif isinstance(schema[child.tag], dict):
            found += _unknown(child, schema[child.tag], where + "/")
    return list(dict.fromkeys(found))


class _File:
    """One VXA document being read: numbers with the fork's defaults, and the warnings so far."""

    def __init__(self, root: Element, name: str):
        self.root, self.name, self.notes = root, name, []

    def warn(self, message: str) -> None:
        self.notes.append(message)

    def fail(self, message: str) -> VxaError:
        return VxaError(f"{self.name}: {message}")

    def number(self, parent: Element | None, tag: str, default: float, where: str) -> float:
        """The number in ``parent``'s child ``tag`` (``default`` if absent)."""
        element = None if parent is None else parent.find(tag)
        if element is None:
            return default
        text = (element.text or "").strip()
        try:
            value = float(text)
        except ValueError:
            raise self.fail(f"{where}/{tag}: not a number ({text[:40]!r})") from None
        if not math.isfinite(value):
            raise self.fail(f"{where}/{tag}: must be finite (got {text!r})")
        return value

    def values(self, section: str, table: dict[str, tuple[str, float, float]]) -> dict[str, float]:
        """Each entry of ``table`` under the element ``section``, with its defaults."""
        base = self.root.find(section)
        out = {}
        for key, (path, tag_default, block_default) in table.items():
            block_path, _, tag = path.rpartition("/")
            block = base if not block_path or base is None else base.find(block_path)
            where = "/".join(p for p in (section, block_path) if p)
            out[key] = block_default if block is None else self.number(block, tag, tag_default, where)
        return out

    def thermal_amplitude(self) -> float:
        """TempAmplitude, or TempAmp - TempBase when it is absent (VX_Environment.cpp)."""
        thermal = self.root.find("Environment/Thermal")
        where = "Environment/Thermal"
        if thermal is None:
            return 0.0
        if thermal.find("TempAmplitude") is not None:
            return self.number(thermal, "TempAmplitude", 0.0, where)
        if thermal.find("TempAmp") is None:
            return 0.0
        return self.number(thermal, "TempAmp", 0.0, where) - self.number(thermal, "TempBase", 25.0, where)


def _palette(file: _File, vxc: Element) -> list[dict[str, Any]]:
    """The materials in file order (the fork numbers them 1, 2, ... whatever their ID says)."""
    materials = []
    for k, element in enumerate(vxc.findall("Palette/Material"), 1):
        where = f"VXC/Palette/Material[{k}]"
        mechanical = element.find("Mechanical")
        material = {tag: file.number(mechanical, tag, 0.0, f"{where}/Mechanical") for tag in _MECHANICAL}
        material["MatType"] = file.number(element, "MatType", 0, where)
        material["Name"] = (element.findtext("Name") or "Default").strip()
        materials.append(material)
    return materials


def _layers(file: _File, block: Element, count: int, where: str) -> list[str]:
    layers = block.findall("Layer")
    if len(layers) != count:
        raise file.fail(f"{where}: {len(layers)} <Layer>s, Z_Voxels is {count}")
    return [(layer.text or "").strip() for layer in layers]


def _decode(file: _File, text: str, compression: str, size: int, where: str) -> np.ndarray:
    """One <Data> layer's material ids, (size,) ints, as the fork decodes ``compression``."""
    try:
        if compression == "ASCII_READABLE":
            return np.frombuffer(text.encode("latin-1"), np.uint8).astype(int) - ord("0")
        raw = base64.b64decode(text, validate=True)
        if compression in ("ZLIB", "QT_ZLIB"):
            raw = zlib.decompressobj().decompress(raw[4:] if compression == "QT_ZLIB" else raw, size + 1)
    except (UnicodeEncodeError, binascii.Error, zlib.error) as exc:
        raise file.fail(f"{where}: not {compression} data ({exc})") from None
    return np.frombuffer(raw, np.uint8).astype(int)


def _numbers(file: _File, text: str, size: int, where: str) -> np.ndarray:
    """One <PhaseOffset> or <Stiffness> layer: ``size`` comma-separated numbers (a trailing comma allowed)."""
    parts = text.split(",")
    if parts and not parts[-1].strip():
        parts = parts[:-1]
    if len(parts) != size:
        raise file.fail(f"{where}: {len(parts)} numbers, X_Voxels x Y_Voxels is {size}")
    try:
        values = np.array([float(p) for p in parts])
    except ValueError:
        bad = next(p for p in parts if not _is_number(p))
        raise file.fail(f"{where}: not a number ({bad.strip()[:40]!r})") from None
    if not np.all(np.isfinite(values)):
        raise file.fail(f"{where}: numbers must be finite")
    return values


def _is_number(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


def _structure(file: _File, vxc: Element, n_materials: int) -> dict[str, np.ndarray | None]:
    """Material ids, phase offsets (cycles) and stiffness (Pa) of each voxel, (X, Y, Z) arrays
    (the last two None where the file has none)."""
    from softevo.sim.scene import MAX_SIDE

    structure = vxc.find("Structure")
    if structure is None:
        raise file.fail("VXC/Structure: missing (the file has no robot)")
    version = vxc.get("Version", "")
    if version not in VXC_VERSIONS:
        raise file.fail(
            f"VXC Version {version!r}: the fork reads voxel layers only in versions 0.93 and 0.94"
        )
    compression = structure.get("Compression")
    if compression not in COMPRESSIONS:
        raise file.fail(
            f"VXC/Structure Compression must be one of {', '.join(COMPRESSIONS)} (got {compression!r})"
        )
    shape = []
    for tag in ("X_Voxels", "Y_Voxels", "Z_Voxels"):
        side = file.number(structure, tag, 1, "VXC/Structure")
        if side != int(side) or not 1 <= side <= MAX_SIDE:
            raise file.fail(f"VXC/Structure/{tag}: must be a whole number 1..{MAX_SIDE} (got {side:g})")
        shape.append(int(side))
    nx, ny, nz = shape
    size = nx * ny

    def grid(layers: list[np.ndarray]) -> np.ndarray:  # layer index x + X y -> [x, y, z]
        return np.stack([layer.reshape((nx, ny), order="F") for layer in layers], axis=-1)

    data = structure.find("Data")
    if data is None:
        raise file.fail("VXC/Structure/Data: missing (the file has no voxels)")
    ids = []
    for z, text in enumerate(_layers(file, data, nz, "VXC/Structure/Data")):
        where = f"VXC/Structure/Data layer {z}"
        layer = _decode(file, text, compression, size, where)
        if len(layer) != size:
            raise file.fail(f"{where}: {len(layer)} voxels, X_Voxels x Y_Voxels is {size}")
        if layer.min() < 0 or layer.max() > n_materials:
            bad = int(layer[(layer < 0) | (layer > n_materials)][0])
            raise file.fail(f"{where}: material {bad} is not in the palette ({n_materials} materials)")
        ids.append(layer)
    out: dict[str, np.ndarray | None] = {"ids": grid(ids)}
    for key, tag in (("offsets", "PhaseOffset"), ("stiffness", "Stiffness")):
        block = structure.find(tag)
        where = f"VXC/Structure/{tag}"
        out[key] = (
            None
            if block is None
            else grid(
                [
                    _numbers(file, text, size, f"{where} layer {z}")
                    for z, text in enumerate(_layers(file, block, nz, where))
                ]
            )
        )
    return out


def _mode(values: np.ndarray, present: np.ndarray) -> float:
    """The value of most present voxels (the smallest of a tie)."""
    unique, counts = np.unique(values[present], return_counts=True)
    return float(unique[np.argmax(counts)])


def _one_value(file: _File, values: np.ndarray, present: np.ndarray, what: str) -> float:
    """The value of most present voxels; a warning when they differ."""
    unique = np.unique(values[present])
    value = _mode(values, present)
    if len(unique) > 1:
        listed = ", ".join(f"{v:g}" for v in unique[:6])
        file.warn(
            f"materials differ in {what} ({listed}); a scene has one value: "
            f"using {value:g}, that of most voxels"
        )
    return value


def _scalar_or_field(values: np.ndarray, present: np.ndarray, scalar: float) -> tuple[float, list | None]:
    """(scalar, None) if the present voxels share one value, else (``scalar``, the field as lists)."""
    unique = np.unique(values[present])
    if len(unique) == 1:
        return float(unique[0]), None
    return scalar, np.where(present, values, 0.0).tolist()


def _check_materials(file: _File, palette: list[dict[str, Any]], used: list[int], stiffness: bool) -> None:
    for k in used:
        material = palette[k - 1]
        label = f"VXC/Palette/Material[{k}] {material['Name']!r}"
        if material["MatType"] != 0:
            raise file.fail(
                f"{label}: MatType {material['MatType']:g} (internal, external or dithered "
                f"materials) cannot be imported; only single materials (0)"
            )
        for tag, needed in (("Elastic_Mod", not stiffness), ("Density", True)):
            if needed and not material[tag] > 0:
                raise file.fail(f"{label}: {tag} must be > 0 (got {material[tag]:g})")
        if material["MatModel"] != 0:
            file.warn(
                f"{label}: MatModel {material['MatModel']:g} (non-linear) is read as linear, Elastic_Mod"
            )
        if material["Fail_Stress"] or material["Fail_Strain"]:
            file.warn(f"{label}: material failure (Fail_Stress, Fail_Strain) is not modelled")


def _warn_unmodelled(
    file: _File, sim: dict[str, float], env: dict[str, float], lattice: dict[str, float]
) -> None:
    checks = [
        (sim["max_velocity"], "Simulator/Features/MaxVelLimitEnabled: the velocity limit is not modelled"),
        (sim["blending"], "Simulator/Features/BlendingEnabled: material blending is not modelled"),
        (sim["volume_effects"], "Simulator/Features/VolumeEffectsEnabled: volume effects are not modelled"),
        (sim["equilibrium"], "Simulator/EquilibriumMode: equilibrium mode is not modelled"),
        (
            sim["self_collisions"] and sim["col_system"] != 3,
            f"Simulator/Collisions/ColSystem {sim['col_system']:g}: collisions are between surface voxels "
            f"beyond the horizon, as ColSystem 3 has them",
        ),
        (
            env["num_fixed"] or env["num_forced"] or env["num_bcs"],
            "Environment: fixed and forced regions are not imported",
        ),
        (file.root.find("Environment/NeuralNet") is not None, "Environment/NeuralNet: not imported"),
        (
            env["floor_slope"],
            "Environment/Gravity/FloorSlope: the floor is flat (the fork ignores the slope too)",
        ),
        (
            any(lattice[k] != 1 for k in ("X_Dim_Adj", "Y_Dim_Adj", "Z_Dim_Adj"))
            or any(
                lattice[k] != 0
                for k in ("X_Line_Offset", "Y_Line_Offset", "X_Layer_Offset", "Y_Layer_Offset")
            ),
            "VXC/Lattice: voxels are cubes on a plain lattice "
            "(dimension adjustments and offsets are not modelled)",
        ),
    ]
    for condition, message in checks:
        if condition:
            file.warn(message)


def _stop_seconds(file: _File, sim: dict[str, float], period: float) -> float:
    """The simulated time the run stops at (the fork's StopConditionMet)."""
    kind = int(sim["stop_type"])
    if kind == STOP_SIMULATED_TIME:
        return sim["stop_value"]
    if kind == STOP_TEMPERATURE_CYCLES:
        return sim["stop_value"] * period
    raise file.fail(
        f"Simulator/StopCondition/StopConditionType {kind} ({STOP_TYPES.get(kind, 'unknown')}): "
        f"only {STOP_SIMULATED_TIME} (simulated seconds) and {STOP_TEMPERATURE_CYCLES} "
        f"(temperature cycles) give a duration"
    )


def _environment(env: dict[str, float]) -> dict[str, Any]:
    if env["fluid"]:  # the fork: neutral buoyancy (no gravity) and no floor in a fluid
        return {
            "kind": worlds.WATER.name,
            "gravity": 0.0,
            "fluid_density": FLUID_DENSITY,
            "drag_coefficient": env["aggregate_drag"] / aggregate_drag(FLUID_DENSITY, 1.0),
        }
    gravity = -env["gravity_acceleration"] if env["gravity_enabled"] else 0.0
    return {"kind": worlds.LAND.name if env["floor"] else worlds.VOID.name, "gravity": gravity}


def _scene(file: _File) -> dict[str, Any]:
    from softevo.sim.models import defaults as model_defaults

    vxc = file.root.find("VXC")
    if vxc is None:
        raise file.fail("no <VXC> element (the robot)")
    sim = file.values("Simulator", _SIMULATOR)
    env = file.values("Environment", _ENVIRONMENT)
    lattice = file.values("VXC", _LATTICE)
    palette = _palette(file, vxc)
    voxels = _structure(file, vxc, len(palette))
    ids = voxels["ids"]
    present = ids > 0
    if not present.any():
        raise file.fail("VXC/Structure/Data: no voxels (every material id is 0)")
    used = sorted(int(k) for k in np.unique(ids[present]))
    _check_materials(file, palette, used, voxels["stiffness"] is not None)
    _warn_unmodelled(file, sim, env, lattice)

    def per_voxel(tag: str) -> np.ndarray:
        return np.array([0.0] + [m[tag] for m in palette])[ids]

    cte = per_voxel("CTE")
    body = np.where(present, np.where(cte != 0, 2, 1), 0)
    strain = (file.thermal_amplitude() if env["temp_enabled"] else 0.0) * cte  # signed, per voxel
    active = body == 2
    magnitudes = np.unique(np.abs(strain[active]))
    amplitude = float(magnitudes.max()) if len(magnitudes) else 0.0
    if len(magnitudes) > 1:
        file.warn(
            f"active materials differ in |CTE| (strains {', '.join(f'{m:g}' for m in magnitudes)}); "
            f"a scene has one amplitude: using the largest, {amplitude:g}"
        )
    offsets = voxels["offsets"] if voxels["offsets"] is not None else np.zeros(ids.shape)
    phase = 2 * math.pi * offsets + np.where(strain < 0, math.pi, 0.0)

    period = env["temp_period"]
    if not period > 0:
        raise file.fail(f"Environment/Thermal/TempPeriod: must be > 0 (got {period:g})")
    stop = _stop_seconds(file, sim, period)
    if stop < sim["init_cm_time"]:
        raise file.fail(
            f"Simulator/StopCondition: the run stops at {stop:g} s, "
            f"before InitCmTime {sim['init_cm_time']:g} s"
        )
    horizon = int(sim["collision_horizon"] * COLLISION_HORIZON_FACTOR)
    if horizon < 1:
        file.warn(
            f"Simulator/Collisions/CollisionHorizon {sim['collision_horizon']:g}: int(x 1.5) < 1; "
            f"bonded voxels never collide here: using 1"
        )
        horizon = 1

    palette_modulus = per_voxel("Elastic_Mod")
    modulus = voxels["stiffness"] if voxels["stiffness"] is not None else palette_modulus
    youngs_modulus, modulus_field = _scalar_or_field(modulus, present, _mode(palette_modulus, present))
    density = per_voxel("Density")
    scalar_density, density_field = _scalar_or_field(density, present, _mode(density, present))
    material = {
        "youngs_modulus": youngs_modulus,
        "density": scalar_density,
        "poisson_ratio": _one_value(file, per_voxel("Poissons_Ratio"), present, "Poissons_Ratio"),
        "friction_static": _one_value(file, per_voxel("uStatic"), present, "uStatic"),
        "friction_kinetic": _one_value(file, per_voxel("uDynamic"), present, "uDynamic"),
        "damping_bond": sim["damping_bond"],
        "damping_global": sim["damping_global"],
        "damping_collision": sim["damping_collision"],
    }
    options = model_defaults("voxcad-land-water")["model_options"]
    scene: dict[str, Any] = {
        "notes": f"imported from {file.name}",
        "model": "voxcad-land-water",
        "model_options": {**options, "collision_horizon": horizon},
        "voxel_size": lattice["voxel_size"],
        "body": body.tolist(),
        "phase": phase.tolist(),
        "material": material,
        "environment": _environment(env),
        "actuation": {"frequency": 1.0 / period, "amplitude": amplitude, "waveform": "sine"},
        "settle_seconds": sim["init_cm_time"],
        "duration": {"seconds": stop - sim["init_cm_time"]},
        "dt_fraction": sim["dt_fraction"],
        "self_collisions": bool(sim["self_collisions"]),
    }
    for key, field in (("youngs_modulus_field", modulus_field), ("density_field", density_field)):
        if field is not None:
            scene[key] = field
    return scene
