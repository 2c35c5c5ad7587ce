"""The Warp engine (``sim.warp_engine``) on Warp's CPU device, against physics and numba.

- The analytic and conservation tests of ``test_mechanics`` and ``test_materials`` and the
  Voxelyze reference tests of ``test_voxelyze_reference`` run again here, unchanged, with
  ``_support.ENGINE`` switched to the Warp engine (the numba engine's own run of them is in
  their modules).
- Short trajectories (a few hundred steps) in every world, through both link frames, with
  self-collisions on: every voxel's position agrees with the numba engine to 1e-9 of the
  body's size (both engines do the same arithmetic; only the order of a few sums and libm
  differ, so round-off is all that separates them).
- Random robots (``test_fuzz.random_scene``: every world, waveform and stiffness, a few
  deliberately unstable steps) over whole evaluations: the same stability flags and reasons'
  kind, distances within 1% (median relative difference).

``SOFTEVO_WARP_TEST_DEVICE`` picks the device (default ``cpu``; ``bench/gpu_device_check.sh``
sets ``cuda:0``), ``SOFTEVO_WARP_RANDOM_ROBOTS`` the number of random robots (default 100).
Every test shares one compiled Warp module (``warp_device``: compiled once per session, then
loaded from Warp's kernel cache).
"""

from __future__ import annotations

import json
import math
import os

import numpy as np
import pytest

from softevo import sim
from softevo.sim import warp_engine
from softevo.sim.engines import EngineUnavailable
from tests.sim import _support, test_materials, test_mechanics, test_voxelyze_reference
from tests.sim._support import report
from tests.sim.test_fuzz import check_results, random_scene

DEVICE = os.environ.get("SOFTEVO_WARP_TEST_DEVICE", "cpu")
RANDOM_ROBOTS = int(os.environ.get("SOFTEVO_WARP_RANDOM_ROBOTS", "100"))


@pytest.fixture(scope="session")
def warp_device():
    """The device under test, with the float64 kernels compiled (or loaded) once."""
    warp_engine.simulate_many([{"body": [[[2]], [[1]]], "duration": {"seconds": 0.001}}], device=DEVICE)
    return DEVICE


@pytest.fixture(autouse=True)
def on_warp(warp_device, monkeypatch):
    """Every test of this module, the borrowed analytic ones included, runs on Warp."""
    monkeypatch.setattr(_support, "ENGINE", {"engine": "warp", "device": warp_device})


# ---------------------------------------------------------------- the analytic tests, on Warp
test_cantilever_under_gravity_matches_lumped_euler_bernoulli = (
    test_mechanics.test_cantilever_under_gravity_matches_lumped_euler_bernoulli
)
test_cantilever_tip_load_is_PL3_over_3EI = test_mechanics.test_cantilever_tip_load_is_PL3_over_3EI
test_axial_stretch_is_F_L_over_EA = test_mechanics.test_axial_stretch_is_F_L_over_EA
test_free_fall_is_g_t2_over_2 = test_mechanics.test_free_fall_is_g_t2_over_2
test_drag_decay_of_a_coasting_voxel = test_mechanics.test_drag_decay_of_a_coasting_voxel
test_energy_conserved_fixed_oscillator = test_mechanics.test_energy_conserved_fixed_oscillator
test_energy_conserved_free_pair_and_newton_second_law = (
    test_mechanics.test_energy_conserved_free_pair_and_newton_second_law
)
test_centre_of_mass_fixed_in_void_under_actuation = (
    test_mechanics.test_centre_of_mass_fixed_in_void_under_actuation
)
test_resting_block_does_not_creep = test_mechanics.test_resting_block_does_not_creep
test_resting_column_sag_matches_springs_in_series = (
    test_mechanics.test_resting_column_sag_matches_springs_in_series
)
test_friction_threshold_from_equilibrium = test_mechanics.test_friction_threshold_from_equilibrium
test_friction_holds_after_touchdown = test_mechanics.test_friction_holds_after_touchdown
test_friction_slides_above_static_threshold = test_mechanics.test_friction_slides_above_static_threshold
test_axial_stretch_of_two_material_bar_is_sum_of_series_links = (
    test_materials.test_axial_stretch_of_two_material_bar_is_sum_of_series_links
)
test_cantilever_of_two_materials_matches_euler_bernoulli_with_per_link_ei = (
    test_materials.test_cantilever_of_two_materials_matches_euler_bernoulli_with_per_link_ei
)
test_two_mass_oscillator_with_combined_link = test_materials.test_two_mass_oscillator_with_combined_link
test_each_active_voxel_follows_its_own_frequency = (
    test_materials.test_each_active_voxel_follows_its_own_frequency
)
test_mixed_materials_keep_the_mass_weighted_centre_of_mass_in_void = (
    test_materials.test_mixed_materials_keep_the_mass_weighted_centre_of_mass_in_void
)

test_cantilever_tip_matches_voxelyze = test_voxelyze_reference.test_cantilever_tip_matches_voxelyze
test_cube_drop_matches_voxelyze = test_voxelyze_reference.test_cube_drop_matches_voxelyze
test_actuated_beam_crawls_like_voxelyze = test_voxelyze_reference.test_actuated_beam_crawls_like_voxelyze
test_tumbling_plate_spins_rigidly_like_voxelyze = (
    test_voxelyze_reference.test_tumbling_plate_spins_rigidly_like_voxelyze
)


# ---------------------------------------------------------------- short trajectories vs numba
def _robot(seed: int, env: str, amplitude: float, waveform: str, fields: bool) -> dict:
    rng = np.random.default_rng(seed)
    body = test_mechanics._random_body(rng, 4, 0.7)
    scene = {
        "voxel_size": 0.01,
        "material": {"youngs_modulus": 1e5 if amplitude > 0.3 else 1e6, "density": 1000.0},
        "environment": {"kind": env},
        "body": body.tolist(),
        "phase": rng.uniform(-math.pi, math.pi, body.shape).tolist(),
        "actuation": {"frequency": 20.0, "amplitude": amplitude, "waveform": waveform},
        "duration": {"seconds": 0.012},
        "settle_seconds": 0.001,
        "self_collisions": True,
        "initial_offset": [0.0, 0.0, 0.002] if env == "land" else [0.0, 0.0, 0.0],
        "initial_angular_velocity": [0.0, 0.0, 3.0],
        "fixed": [],
        "record": {"every": 25},
    }
    if fields:  # per-voxel stiffness, density and frequency
        scene["youngs_modulus_field"] = (rng.uniform(0.5, 2.0, body.shape) * 1e5).tolist()
        scene["density_field"] = rng.uniform(800.0, 1200.0, body.shape).tolist()
        scene["frequency_field"] = rng.uniform(15.0, 25.0, body.shape).tolist()
    return scene


TRAJECTORIES = {  # name: (seed, world, amplitude, waveform, per-voxel fields)
    "land_small_angle": (1, "land", 0.1, "sine", False),
    "land_large_angle": (2, "land", 0.6, "square", False),
    "water_large_angle": (3, "water", 0.6, "sine", True),
    "water_impulse": (4, "water", 0.3, "impulse", False),
    "void_large_angle": (5, "void", 0.6, "impulse", True),
}


def test_short_trajectories_agree_with_numba_to_round_off(warp_device):
    scenes = [_robot(*args) for args in TRAJECTORIES.values()]
    # a stiff cantilever pushed far past the small-angle frame's 0.05 rad bend, and a tip
    # force: fixed voxels and external forces
    bar = {
        "voxel_size": 0.01,
        "material": {"youngs_modulus": 2e4},
        "environment": {"kind": "void"},
        "body": _support.line(6),
        "fixed": [[0, 0, 0]],
        "forces": [{"voxel": [5, 0, 0], "force": [0.0, 0.02, 0.03]}],
        "duration": {"seconds": 0.06},
        "record": {"every": 25},
        "self_collisions": True,
    }
    scenes.append(bar)
    names = [*TRAJECTORIES, "void_cantilever_large_bend"]
    ours = warp_engine.simulate_many(scenes, device=warp_device)
    theirs = sim.simulate_many(scenes)
    worst = 0.0
    for name, a, b in zip(names, ours, theirs, strict=True):
        assert a.stable and b.stable, name
        assert a.steps == b.steps and 200 <= a.steps <= 1000, name
        pa, pb = np.asarray(a.frames["positions"]), np.asarray(b.frames["positions"])
        assert pa.shape == pb.shape, name
        scale = np.ptp(pb[0], axis=0).max() + 0.01
        rel = np.abs(pa - pb).max() / scale
        moved = np.abs(pb[-1] - pb[0]).max() / 0.01
        worst = max(worst, rel)
        report(f"warp.trajectory.{name}", steps=a.steps, max_rel_position_diff=rel, motion_L=moved)
        assert rel < 1e-9, name
        assert moved > 0.02, name  # something happened
        np.testing.assert_allclose(
            a.com_trajectory["com"], b.com_trajectory["com"], rtol=0, atol=1e-9 * scale
        )
        assert a.distance == pytest.approx(b.distance, rel=1e-6, abs=1e-9)
    # the bar bent far beyond the small-angle frame (so the large-angle one and its
    # hysteresis ran): its tip segment turned by more than 0.3 rad
    tip = np.asarray(ours[-1].final_positions)
    seg = tip[-1] - tip[-2]
    assert math.acos(seg[0] / np.linalg.norm(seg)) > 0.3
    report("warp.trajectory.worst", max_rel_position_diff=worst)


def test_robots_finishing_at_different_steps_share_a_batch(warp_device):
    """Robots of different step counts and an unstable one in one batch: each is masked when
    done, and each result equals the one it gets alone."""
    fast = _robot(7, "land", 0.2, "sine", False)
    slow = {**fast, "duration": {"seconds": 0.08}}
    broken = {
        **fast,
        "dt_fraction": 6.0,
        "duration": {"seconds": 0.2},  # 6x the stable step
        "actuation": {**fast["actuation"], "frequency": 0.5},
    }
    together = warp_engine.simulate_many([fast, slow, broken], device=warp_device)
    alone = [warp_engine.simulate_many([s], device=warp_device)[0] for s in (fast, slow)]
    assert together[1].steps > together[0].steps
    for a, b in zip(together[:2], alone, strict=True):
        np.testing.assert_array_equal(a.final_positions, b.final_positions)
    assert not together[2].stable and together[2].reason.startswith("diverged")
    assert together[2].distance == 0.0


# ---------------------------------------------------------------- whole evaluations vs numba
def test_random_robots_over_whole_evaluations_agree_with_numba(warp_device):
    rng = np.random.default_rng(20261201)
    scenes = [random_scene(rng, k) for k in range(RANDOM_ROBOTS)]
    ours = warp_engine.simulate_many(scenes, device=warp_device)
    theirs = sim.simulate_many(scenes)
    check_results(scenes, ours)
    flags = [(a.stable, b.stable) for a, b in zip(ours, theirs, strict=True)]
    mismatched = sum(x != y for x, y in flags)
    both = [(a.distance, b.distance) for a, b in zip(ours, theirs, strict=True) if a.stable and b.stable]
    rel = np.array([abs(x - y) / max(abs(y), 1e-3) for x, y in both])
    report(
        "warp.random_robots",
        robots=len(scenes),
        stable_both=len(both),
        flagged=sum(not b for _, b in flags),
        stability_mismatches=mismatched,
        median_rel_distance_diff=float(np.median(rel)),
        max_rel_distance_diff=float(rel.max()),
    )
    assert mismatched == 0
    assert len(both) >= RANDOM_ROBOTS // 2
    assert np.median(rel) < 0.01
    for a, b in zip(ours, theirs, strict=True):
        if not b.stable:
            assert a.reason.split(":")[0] == b.reason.split(":")[0]


# ---------------------------------------------------------------- selection and errors
def test_simulate_many_selects_the_engine(warp_device):
    scene = _robot(8, "water", 0.2, "sine", False)
    via_sim = sim.simulate_many([scene], engine="warp", device=warp_device)[0]
    direct = warp_engine.simulate_many([scene], device=warp_device)[0]
    np.testing.assert_array_equal(via_sim.final_positions, direct.final_positions)
    assert set(via_sim.to_dict()) == set(sim.simulate(scene).to_dict())
    with pytest.raises(EngineUnavailable, match="engine: must be one of numba, warp"):
        sim.simulate_many([scene], engine="cuda")


def test_the_numba_engine_never_imports_warp():
    import subprocess
    import sys

    code = (
        "import sys; from softevo import sim; sim.simulate({'body': [[[1]]], "
        "'duration': {'seconds': 0.001}}); assert 'warp' not in sys.modules"
    )
    subprocess.run([sys.executable, "-c", code], check=True)


def test_missing_device_and_missing_warp_are_one_line_errors(monkeypatch):
    import sys

    with pytest.raises(EngineUnavailable, match=r"no Warp device 'cuda:7' here; there are: .*cpu"):
        warp_engine.device_of("cuda:7")
    monkeypatch.setitem(sys.modules, "warp", None)  # as if warp-lang were not installed
    with pytest.raises(EngineUnavailable, match=r"pip install 'softevo\[gpu\]'"):
        warp_engine.simulate_many([{"body": [[[1]]]}], device="cpu")


def test_cli_simulates_on_warp_and_refuses_a_missing_device(warp_device, tmp_path, capsys):
    from tests.sim.test_cli_sim import TINY, assert_user_error, softevo_here, write

    path = write(tmp_path, TINY)
    proc = softevo_here(capsys, "simulate", str(path), "--json", "--engine", "warp", "--device", warp_device)
    assert proc.returncode == 0, proc.stderr
    ours = json.loads(proc.stdout)
    theirs = sim.simulate(TINY).to_dict()
    assert ours["steps"] == theirs["steps"] and ours["stable"]
    assert ours["distance"] == pytest.approx(theirs["distance"], rel=1e-9)
    assert_user_error(
        softevo_here(capsys, "simulate", str(path), "--engine", "warp", "--device", "cuda:7"),
        "no Warp device 'cuda:7'",
    )
    assert_user_error(
        softevo_here(capsys, "simulate", str(path), "--engine", "gpu"), "engine: must be one of numba, warp"
    )
    assert_user_error(
        softevo_here(capsys, "simulate", str(path), "--device", "cpu"),
        "--device: only the warp and sleep engines",
    )


def test_workers_evaluate_on_the_engine_of_their_environment(warp_device, monkeypatch):
    from softevo.worker.evaluate import DEVICE_ENV, ENGINE_ENV, engine_options

    monkeypatch.delenv(ENGINE_ENV, raising=False)
    monkeypatch.setenv(DEVICE_ENV, "cpu")
    assert engine_options() == {}  # the numba engine: calls exactly as without the variables
    monkeypatch.setenv(ENGINE_ENV, "warp")
    monkeypatch.setenv(DEVICE_ENV, warp_device)
    assert engine_options() == {"engine": "warp", "device": warp_device}
    monkeypatch.setenv(DEVICE_ENV, "cuda:7")
    from softevo.worker.evaluate import warm_up

    with pytest.raises(EngineUnavailable, match="cuda:7"):  # a GPU worker without its GPU
        warm_up()
