"""The sim contract (docs/spec.md section 1, docs/contracts.md) as seen from outside.

Result fields and JSON, initial placement, distance conventions, largest component, the
step budget, unstable robots, determinism of ``simulate_many``, and the waveforms.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from softevo import sim
from tests.sim._support import frames, report, simulate, voxel_index

SPEC_FIELDS = {"stable", "reason", "dt", "steps", "simulated_seconds", "voxels",
               "final_positions", "com_start", "com_end", "displacement", "distance",
               "com_trajectory"}


def _block(kind="void", seconds=0.1, **extra) -> dict:
    return {"voxel_size": 0.05, "environment": {"kind": kind},
            "body": np.ones((2, 2, 2), int).tolist(), "duration": {"seconds": seconds}} | extra


def test_public_api():
    for name in ("simulate", "simulate_many", "parse_scene", "Scene", "SceneError", "Result"):
        assert hasattr(sim, name), name


def test_result_fields_and_strict_json():
    result = simulate(_block(record={"every": 10}))
    d = result.to_dict()
    assert SPEC_FIELDS <= set(d)
    assert set(d["com_trajectory"]) == {"t", "com"}
    assert set(d["frames"]) == {"t", "positions"}
    text = json.dumps(d, allow_nan=False)
    assert json.loads(text) == d  # plain JSON types only
    assert "frames" not in simulate(_block()).to_dict()  # frames only when record is set
    np.testing.assert_allclose(d["displacement"],
                               np.subtract(d["com_end"], d["com_start"]), atol=1e-15)
    assert d["simulated_seconds"] == pytest.approx(d["steps"] * d["dt"])
    assert d["simulated_seconds"] >= 0.1 - d["dt"]


def test_initial_placement_and_dt():
    """Voxel (i, j, k) starts centred at ((i, j, k) + 1/2) L; dt = f L sqrt(rho/E) / 2 pi with
    f the default dt_fraction (here below the actuation-period cap)."""
    body = np.zeros((3, 2, 2), int)
    body[:, 0, 0] = 1
    body[0, 1, 0] = 2
    body[0, 0, 1] = 1
    result = simulate({"voxel_size": 0.04, "environment": {"kind": "void"},
                       "body": body.tolist(), "actuation": {"amplitude": 0.0},
                       "duration": {"seconds": 0.01}, "record": {"every": 1000}})
    t, pos = frames(result)
    expected = (np.asarray(result.voxels) + 0.5) * 0.04
    np.testing.assert_allclose(pos[0], expected, atol=1e-15)
    assert [tuple(v) for v in result.voxels] == [tuple(v) for v in np.argwhere(body > 0)]
    fraction = sim.Scene.dt_fraction
    assert result.dt == pytest.approx(fraction * 0.04 * math.sqrt(1200 / 1e6) / (2 * math.pi))


def test_distance_is_horizontal_on_land():
    """A block dropped onto the floor moves only vertically: distance ~0 on land."""
    result = simulate(_block("land", 0.5, initial_offset=[0.0, 0.0, 0.05]))
    assert abs(result.displacement[2]) > 0.01
    assert result.distance == pytest.approx(np.hypot(*result.displacement[:2]) / 0.05, abs=1e-12)
    assert result.distance < 1e-6


def test_settle_seconds_moves_com_start():
    """com_start is taken after settling: a block coasting in void at v covers v * duration."""
    v = 0.2
    result = simulate(_block("void", 0.5, settle_seconds=0.5, initial_velocity=[v, 0, 0],
                             material={"damping_global": 0.0}))
    assert result.com_start[0] == pytest.approx(0.05 + v * 0.5, rel=1e-3)
    assert result.distance == pytest.approx(v * 0.5 / 0.05, rel=1e-3)


def test_only_the_largest_component_is_simulated():
    body = np.zeros((5, 1, 1), int)
    body[0:3] = 1
    body[4] = 2
    result = simulate({"environment": {"kind": "void"}, "body": body.tolist(),
                       "duration": {"seconds": 0.01}})
    assert sorted(tuple(v) for v in result.voxels) == [(0, 0, 0), (1, 0, 0), (2, 0, 0)]


def test_body_without_active_voxels_stays_put():
    result = simulate(_block("land", 1.0) | {"settle_seconds": 0.5})
    assert result.distance < 1e-6


def test_step_budget_returns_unstable_not_hang():
    result = sim.simulate(_block("land", 10.0, max_steps=100))
    assert not result.stable
    assert "max_steps" in result.reason or "budget" in result.reason
    assert result.distance == 0.0


def test_unstable_robot_is_flagged_with_strict_json():
    """Far past the stable step the robot blows up: stable false, a reason, distance 0, and
    its to_dict still valid JSON (no NaN: the CLI prints it and the database stores it)."""
    # passive voxels: the actuation-period cap on the step does not apply
    result = sim.simulate(_block("land", 0.5, dt_fraction=8.0,
                                 body=np.full((3, 3, 3), 1).tolist(),
                                 initial_velocity=[0.0, 0.0, -0.5]))
    assert not result.stable
    assert result.reason
    assert result.distance == 0.0
    json.dumps(result.to_dict(), allow_nan=False)


def test_simulate_many_matches_simulate_exactly():
    """Parallel batches give each robot exactly what it gets alone (no shared scratch)."""
    rng = np.random.default_rng(5)
    scenes = []
    for k in range(6):
        body = (rng.random((3, 3, 2)) < 0.8).astype(int) * 2
        body[1, 1, 0] = 2
        scenes.append({"environment": {"kind": ("land", "water", "void")[k % 3]},
                       "body": body.tolist(),
                       "phase": rng.uniform(-3, 3, body.shape).tolist(),
                       "material": {"youngs_modulus": float(10 ** rng.uniform(4, 6))},
                       "duration": {"cycles": 1}})
    many = sim.simulate_many(scenes, threads=2)
    for scene, res in zip(scenes, many, strict=True):
        alone = sim.simulate(scene)
        assert res.stable and alone.stable
        np.testing.assert_array_equal(res.final_positions, alone.final_positions)


@pytest.mark.parametrize("waveform", ["sine", "square", "impulse"])
def test_waveforms_drive_the_rest_length(waveform):
    """Two active voxels with the same phase in void: their centre distance follows the
    rest length L (1 + a w(2 pi f t)) quasi-statically (drive 1 Hz vs link ~100 Hz).
    Extremes within 2% of the amplitude; the impulse contracts in ~20% of the cycle and
    releases over ~80%; the square wave sits on its two plateaus most of the time."""
    L, amp = 0.05, 0.3
    result = simulate({
        "voxel_size": L, "environment": {"kind": "void"}, "body": np.full((2, 1, 1), 2).tolist(),
        "actuation": {"frequency": 1.0, "amplitude": amp, "waveform": waveform},
        "duration": {"cycles": 2}, "self_collisions": False, "record": {"every": 10},
    })
    t, pos = frames(result)
    idx = voxel_index(result)
    strain = (pos[:, idx[(1, 0, 0)], 0] - pos[:, idx[(0, 0, 0)], 0]) / L - 1.0
    late = t >= 1.0  # second cycle
    s = strain[late]
    report(f"actuation.{waveform}", strain_max=s.max(), strain_min=s.min(), amplitude=amp)
    assert s.max() == pytest.approx(amp, abs=0.02 * amp)
    assert s.min() == pytest.approx(-amp, abs=0.02 * amp)
    if waveform == "sine":
        np.testing.assert_allclose(strain, amp * np.sin(2 * np.pi * t), atol=0.03 * amp)
    elif waveform == "square":
        assert np.mean(np.abs(np.abs(s) - amp) < 0.05 * amp) > 0.8
    else:
        falling = np.mean(np.diff(s) < 0)
        assert falling == pytest.approx(0.2, abs=0.05)
