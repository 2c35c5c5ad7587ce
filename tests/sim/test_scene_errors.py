"""Bad input: a malformed scene is a ``SceneError`` whose message starts with the field path.

Unit tests of ``sim.parse_scene`` (docs/contracts.md): wrong shape, unknown field, negative
modulus, empty body, bad waveform, and the other ways a scene document can be wrong.
"""

from __future__ import annotations

import copy

import numpy as np
import pytest

from softevo.sim.scene import SceneError, parse_scene

GOOD = {
    "voxel_size": 0.05,
    "material": {"youngs_modulus": 1e6, "density": 1200.0},
    "environment": {"kind": "land"},
    "body": [[[1, 2]], [[2, 1]]],
    "phase": [[[0.0, 1.0]], [[2.0, 3.0]]],
    "actuation": {"frequency": 3.0, "amplitude": 0.39, "waveform": "sine"},
    "fixed": [[0, 0, 0]],
    "forces": [{"voxel": [1, 0, 1], "force": [0.0, 0.0, -1.0]}],
    "duration": {"cycles": 2},
}


def _with(path: str, value):
    """GOOD with the (dotted) field ``path`` replaced by ``value`` (``...`` deletes it)."""
    scene = copy.deepcopy(GOOD)
    *parents, leaf = path.split(".")
    node = scene
    for key in parents:
        node = node.setdefault(key, {})
    if value is ...:
        node.pop(leaf, None)
    else:
        node[leaf] = value
    return scene


def test_good_scene_parses_with_defaults():
    scene = parse_scene(GOOD)
    assert scene.body.shape == (2, 1, 2)
    assert scene.material.poisson_ratio == pytest.approx(0.4)
    assert scene.environment.gravity == pytest.approx(9.81)
    assert scene.duration_seconds == pytest.approx(2 / 3.0)
    np.testing.assert_array_equal(scene.fixed, [[0, 0, 0]])


@pytest.mark.parametrize(
    ("kind", "gravity"), [("land", 9.81), ("water", 0.0), ("void", 0.0)]
)
def test_gravity_defaults_per_world(kind, gravity):
    assert parse_scene(_with("environment.kind", kind)).environment.gravity == gravity


@pytest.mark.parametrize(
    ("path", "value", "field"),
    [
        # wrong shapes
        ("body", [1, 2, 1], "body"),
        ("body", [[1, 2], [2, 1]], "body"),
        ("body", [[[1, 2]], [[2]]], "body"),
        ("body", [[[1, 3]], [[2, 1]]], "body"),
        ("body", [[["a", 1]], [[2, 1]]], "body"),
        ("body", ..., "body"),
        ("phase", [[[0.0]], [[1.0]]], "phase"),
        ("phase", [[[0.0, float("nan")]], [[1.0, 1.0]]], "phase"),
        ("initial_velocity", [1.0, 2.0], "initial_velocity"),
        ("initial_angular_velocity", "fast", "initial_angular_velocity"),
        ("fixed", [[0, 0]], "fixed[0]"),
        ("fixed", [[5, 0, 0]], "fixed[0]"),
        ("forces", [{"voxel": [1, 0, 1], "force": [1.0]}], "forces[0].force"),
        ("forces", [{"voxel": [1, 0, 1]}], "forces[0]"),
        # unknown fields, at every level
        ("colour", "red", "colour"),
        ("material.stiffness", 1e6, "material.stiffness"),
        ("environment.viscosity", 1e-3, "environment.viscosity"),
        ("actuation.freq", 2.0, "actuation.freq"),
        ("duration.minutes", 2, "duration.minutes"),
        # bad values
        ("material.youngs_modulus", -1.0, "material.youngs_modulus"),
        ("material.youngs_modulus", 0.0, "material.youngs_modulus"),
        ("material.youngs_modulus", "1e6", "material.youngs_modulus"),
        ("material.density", -1200.0, "material.density"),
        ("material.poisson_ratio", 0.5, "material.poisson_ratio"),
        ("material.damping_bond", -0.1, "material.damping_bond"),
        ("voxel_size", 0.0, "voxel_size"),
        ("environment.kind", "space", "environment.kind"),
        ("actuation.waveform", "triangle", "actuation.waveform"),
        ("actuation.waveform", 3, "actuation.waveform"),
        ("actuation.amplitude", -0.1, "actuation.amplitude"),
        ("actuation.frequency", -3.0, "actuation.frequency"),
        ("dt_fraction", 0.0, "dt_fraction"),
        ("self_collisions", "yes", "self_collisions"),
        ("record.every", 0, "record.every"),
        ("max_steps", 0, "max_steps"),
        ("duration", {"cycles": 2, "seconds": 1.0}, "duration"),
        ("duration.cycles", -1, "duration.cycles"),
        ("duration", {"seconds": 1.0, "max_seconds": 0.5}, "duration.max_seconds"),
        ("duration", {"max_seconds": 0.5}, "duration.max_seconds"),
        ("duration.max_seconds", 0.0, "duration.max_seconds"),
        ("duration.max_seconds", -1.0, "duration.max_seconds"),
        ("duration.max_seconds", "4.5", "duration.max_seconds"),
    ],
)
def test_malformed_scene_names_the_field(path, value, field):
    with pytest.raises(SceneError) as info:
        parse_scene(_with(path, value))
    message = str(info.value)
    assert message.startswith(field), message
    assert "\n" not in message  # one line for the CLI


def test_empty_body_is_an_error():
    with pytest.raises(SceneError, match=r"^body: "):
        parse_scene(_with("body", [[[0, 0]], [[0, 0]]]) | {"phase": None, "fixed": [],
                                                             "forces": []})


def test_fixed_voxel_must_be_full():
    scene = _with("body", [[[1, 0]], [[2, 1]]])
    scene["fixed"] = [[0, 0, 1]]
    with pytest.raises(SceneError, match=r"^fixed\[0\]: .*empty"):
        parse_scene(scene)


def test_scene_must_be_an_object():
    with pytest.raises(SceneError, match=r"^scene: "):
        parse_scene([GOOD])


def test_scene_error_is_a_value_error():
    assert issubclass(SceneError, ValueError)


def test_notes_are_allowed():
    assert parse_scene(GOOD | {"notes": "from the reference set"}).body.sum() == 6


def test_max_seconds_caps_the_cycles():
    """2 cycles at 3 Hz last 2/3 s: a cap above that changes nothing, one below it wins; at
    0.01 Hz the cycles alone would last 200 s."""
    assert parse_scene(_with("duration.max_seconds", 1.0)).duration_seconds == pytest.approx(2 / 3)
    assert parse_scene(_with("duration.max_seconds", 0.25)).duration_seconds == pytest.approx(0.25)
    slow = _with("actuation.frequency", 0.01)
    assert parse_scene(slow).duration_seconds == pytest.approx(200.0)
    slow["duration"]["max_seconds"] = 4.5
    assert parse_scene(slow).duration_seconds == pytest.approx(4.5)
