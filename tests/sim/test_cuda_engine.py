"""The cuda engine (``sim.cuda_engine``) against the numba engine and physics.

By default it runs on numba-cuda's simulator (``NUMBA_ENABLE_CUDASIM=1``, set by
tests/conftest.py unless a GPU is asked for): the same kernel source, executed as Python
threads, so robots are small and runs short. ``SOFTEVO_CUDA_TEST_DEVICE=cuda:0`` runs the
module on a GPU (``bench/gpu_device_check.sh``), ``SOFTEVO_CUDA_RANDOM_ROBOTS`` sets how many
random robots run whole evaluations there (default 100 on a GPU, 4 short ones on the
simulator).

- Short trajectories in every world and both models (voxelyze-2, and the paper's
  voxcad-land-water: mesh drag, the fork's friction and contact), through both link frames,
  with self-collisions, per-voxel fields, fixed voxels and external forces: every voxel's
  position agrees with the numba engine to 1e-9 of the body's size (the same physics code;
  only the order of a few sums differs).
- The shared-memory and global-memory paths give identical runs.
- Robots that finish at different steps, or diverge, share a batch.
- Analytic tests of ``test_mechanics`` on small bodies, with ``_support.ENGINE`` switched.

The physics tests run in both precisions (the ``precision`` fixture). In "mixed" the two
engines round the links' float32 arithmetic differently (the simulator's fma rounds twice,
the numba engine's once), so positions agree to ``AGREEMENT["mixed"]`` of the body's size.
"""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys

import numpy as np
import pytest

from softevo import sim
from softevo.sim import cuda_engine
from softevo.sim.engines import EngineUnavailable
from softevo.sim.scene import parse_scene
from softevo.sim.system import build_robot
from tests.sim import _support, test_mechanics
from tests.sim._support import report
from tests.sim.test_fuzz import check_results, random_scene

DEVICE = os.environ.get("SOFTEVO_CUDA_TEST_DEVICE", "cuda:0")
ON_GPU = "SOFTEVO_CUDA_TEST_DEVICE" in os.environ
RANDOM_ROBOTS = int(os.environ.get("SOFTEVO_CUDA_RANDOM_ROBOTS", "100" if ON_GPU else "4"))
# the largest position difference from the numba engine, as a fraction of the body's size
AGREEMENT = {"float64": 1e-9, "mixed": 1e-5}


@pytest.fixture(autouse=True)
def on_cuda(monkeypatch):
    """Every test of this module, the borrowed analytic ones included, runs on the cuda
    engine."""
    monkeypatch.setattr(_support, "ENGINE", {"engine": "cuda", "device": DEVICE})


def _robot(seed: int, env: str, amplitude: float, waveform: str, fields: bool,
           model: str = "voxelyze-2", size: int = 3, seconds: float = 0.006) -> dict:
    rng = np.random.default_rng(seed)
    body = test_mechanics._random_body(rng, size, 0.7)
    scene = {
        "model": model,
        "voxel_size": 0.01,
        "material": {"youngs_modulus": 1e5 if amplitude > 0.3 else 1e6, "density": 1000.0},
        "environment": {"kind": env},
        "body": body.tolist(),
        "phase": rng.uniform(-math.pi, math.pi, body.shape).tolist(),
        "actuation": {"frequency": 40.0, "amplitude": amplitude, "waveform": waveform},
        "duration": {"seconds": seconds},
        "settle_seconds": 0.001,
        "self_collisions": True,
        "initial_offset": [0.0, 0.0, 0.002] if env == "land" else [0.0, 0.0, 0.0],
        "initial_angular_velocity": [0.0, 0.0, 3.0],
        "record": {"every": 25},
    }
    if model != "voxelyze-2":
        scene["dt_fraction"] = 0.5
    if fields:  # per-voxel stiffness, density and frequency
        scene["youngs_modulus_field"] = (rng.uniform(0.5, 2.0, body.shape) * 1e5).tolist()
        scene["density_field"] = rng.uniform(800.0, 1200.0, body.shape).tolist()
        scene["frequency_field"] = rng.uniform(30.0, 50.0, body.shape).tolist()
    return _support.with_precision(scene)


TRAJECTORIES = {  # name: (seed, world, amplitude, waveform, per-voxel fields, model)
    "land_small_angle": (1, "land", 0.1, "sine", False, "voxelyze-2"),
    "land_large_angle_collisions": (2, "land", 0.6, "square", False, "voxelyze-2"),
    "water_fields": (3, "water", 0.6, "sine", True, "voxelyze-2"),
    "void_impulse_fields": (5, "void", 0.6, "impulse", True, "voxelyze-2"),
    "paper_model_land": (6, "land", 0.4, "sine", False, "voxcad-land-water"),
    "paper_model_water_mesh_drag": (7, "water", 0.4, "sine", True, "voxcad-land-water"),
}

BAR = {  # a cantilever pushed far past the small-angle frame's bend: fixed voxels, a tip force
    "voxel_size": 0.01,
    "material": {"youngs_modulus": 2e4},
    "environment": {"kind": "void"},
    "body": _support.line(4),
    "fixed": [[0, 0, 0]],
    "forces": [{"voxel": [3, 0, 0], "force": [0.0, 0.02, 0.03]}],
    "duration": {"seconds": 0.03},
    "record": {"every": 25},
    "self_collisions": True,
}


def _scenes() -> tuple[list[str], list[dict]]:
    names = [*TRAJECTORIES, "void_cantilever_large_bend"]
    seconds = {"voxelyze-2": 0.006, "voxcad-land-water": 0.015}  # a few hundred steps each
    return names, [_robot(*args[:5], model=args[5], seconds=seconds[args[5]])
                   for args in TRAJECTORIES.values()] + [_support.with_precision(BAR)]


def _worst(names, ours, theirs, label: str) -> float:
    worst = 0.0
    for name, a, b in zip(names, ours, theirs, strict=True):
        assert a.stable and b.stable, name
        assert a.steps == b.steps and a.steps >= 100, name
        pa, pb = np.asarray(a.frames["positions"]), np.asarray(b.frames["positions"])
        assert pa.shape == pb.shape, name
        scale = np.ptp(pb[0], axis=0).max() + 0.01
        rel = np.abs(pa - pb).max() / scale
        moved = np.abs(pb[-1] - pb[0]).max() / 0.01
        worst = max(worst, rel)
        report(f"cuda.{label}.{_support.PRECISION}.{name}", steps=a.steps, voxels=len(a.voxels),
               max_rel_position_diff=rel, motion_L=moved)
        assert rel < AGREEMENT[_support.PRECISION], name
        assert moved > 0.01, name  # something happened
        np.testing.assert_allclose(a.com_trajectory["com"], b.com_trajectory["com"], rtol=0,
                                   atol=AGREEMENT[_support.PRECISION] * scale)
        # the distance (voxel lengths) moves with the positions: within twice their bound
        slack = 1e-9 if _support.PRECISION == "float64" else 2 * AGREEMENT["mixed"] * scale / 0.01
        assert a.distance == pytest.approx(b.distance, rel=1e-6, abs=slack)
    return worst


@pytest.mark.usefixtures("precision")
def test_short_trajectories_agree_with_numba_to_round_off():
    names, scenes = _scenes()
    ours = cuda_engine.simulate_many(scenes, device=DEVICE)
    theirs = sim.simulate_many(scenes)
    worst = _worst(names, ours, theirs, "trajectory")
    # the bar bent far beyond the small-angle frame (so the large-angle one and its
    # hysteresis ran): its tip segment turned by more than 0.3 rad
    tip = np.asarray(ours[-1].final_positions)
    seg = tip[-1] - tip[-2]
    assert math.acos(seg[0] / np.linalg.norm(seg)) > 0.3
    report(f"cuda.trajectory.{_support.PRECISION}.worst", max_rel_position_diff=worst)


@pytest.mark.usefixtures("precision")
def test_shared_and_global_memory_paths_are_identical():
    scenes = [_robot(2, "land", 0.6, "square", False, seconds=0.003),
              _robot(7, "water", 0.4, "sine", True, "voxcad-land-water", seconds=0.003)]
    robots = [build_robot(parse_scene(s)) for s in scenes]
    dev = cuda_engine.device_of(DEVICE)
    shared = cuda_engine.run_batch(robots, dev, _support.PRECISION)
    global_ = cuda_engine.run_batch(robots, dev, _support.PRECISION, memory="global")
    np.testing.assert_array_equal(shared.pos, global_.pos)
    np.testing.assert_array_equal(shared.com_traj, global_.com_traj)
    assert shared.voxel_steps == global_.voxel_steps > 0


@pytest.mark.usefixtures("precision")
def test_launches_of_any_length_give_the_same_run():
    scene = _robot(5, "void", 0.6, "impulse", True, seconds=0.003)
    one = cuda_engine.simulate_many([scene], device=DEVICE)[0]
    many = cuda_engine.simulate_many([scene], device=DEVICE, chunk=37)[0]
    np.testing.assert_array_equal(one.final_positions, many.final_positions)
    np.testing.assert_array_equal(one.com_trajectory["com"], many.com_trajectory["com"])


@pytest.mark.usefixtures("precision")
def test_robots_finishing_at_different_steps_share_a_batch():
    """Robots of different step counts and an unstable one in one batch: each stops when
    done, and each result equals the one it gets alone."""
    fast = _robot(8, "land", 0.2, "sine", False, size=2, seconds=0.002)
    slow = {**fast, "duration": {"seconds": 0.005}}
    broken = {**fast, "dt_fraction": 6.0, "duration": {"seconds": 0.2},  # 6x the stable step
              "actuation": {**fast["actuation"], "frequency": 0.5}}
    together = cuda_engine.simulate_many([fast, slow, broken], device=DEVICE)
    alone = [cuda_engine.simulate_many([s], device=DEVICE)[0] for s in (fast, slow)]
    assert together[1].steps > together[0].steps
    for a, b in zip(together[:2], alone, strict=True):
        np.testing.assert_array_equal(a.final_positions, b.final_positions)
    assert not together[2].stable and together[2].reason.startswith("diverged")
    assert together[2].distance == 0.0
    reference = sim.simulate(broken)
    assert together[2].steps == reference.steps and together[2].reason == reference.reason


@pytest.mark.usefixtures("precision")
def test_random_robots_agree_with_numba():
    """Random robots of ``test_fuzz`` (every world, waveform and stiffness, a few past the
    stable step). On a GPU: whole evaluations, the same stability flags, distances within 1%
    (median). On the simulator: small bodies and a tenth of a cycle, positions to 1e-9."""
    rng = np.random.default_rng(20261201)
    scenes = [_support.with_precision(random_scene(rng, k)) for k in range(RANDOM_ROBOTS)]
    if not ON_GPU:
        for scene in scenes:
            body = np.asarray(scene["body"])[:3, :2, :2]
            body.flat[0] = max(body.flat[0], 1)
            scene["body"] = body.tolist()
            scene["phase"] = np.asarray(scene["phase"])[:3, :2, :2].tolist()
            scene["duration"] = {"cycles": 0.05}
    ours = cuda_engine.simulate_many(scenes, device=DEVICE)
    theirs = sim.simulate_many(scenes)
    check_results(scenes, ours)
    flags = [(a.stable, b.stable) for a, b in zip(ours, theirs, strict=True)]
    mismatched = sum(x != y for x, y in flags)
    both = [(a, b) for a, b in zip(ours, theirs, strict=True) if a.stable and b.stable]
    rel = np.array([abs(a.distance - b.distance) / max(abs(b.distance), 1e-3) for a, b in both])
    report("cuda.random_robots", robots=len(scenes), stable_both=len(both),
           stability_mismatches=mismatched, median_rel_distance_diff=float(np.median(rel)),
           max_rel_distance_diff=float(rel.max()))
    assert mismatched == 0
    assert len(both) >= RANDOM_ROBOTS // 2
    assert np.median(rel) < 0.01
    for a, b in zip(ours, theirs, strict=True):
        if not b.stable:
            assert a.reason.split(":")[0] == b.reason.split(":")[0]
        elif not ON_GPU:
            scale = np.ptp(b.final_positions, axis=0).max() + 0.01
            worst = np.abs(np.asarray(a.final_positions) - b.final_positions).max()
            assert worst < AGREEMENT[_support.PRECISION] * scale


# ---------------------------------------------------------------- analytic tests, on cuda
in_both_precisions = pytest.mark.usefixtures("precision")
test_free_fall_is_g_t2_over_2 = in_both_precisions(test_mechanics.test_free_fall_is_g_t2_over_2)
test_energy_conserved_fixed_oscillator = in_both_precisions(
    test_mechanics.test_energy_conserved_fixed_oscillator)
test_energy_conserved_free_pair_and_newton_second_law = in_both_precisions(
    test_mechanics.test_energy_conserved_free_pair_and_newton_second_law)


# ---------------------------------------------------------------- selection and errors
def test_simulate_many_selects_the_engine():
    scene = _robot(9, "water", 0.2, "sine", False, size=2, seconds=0.002)
    via_sim = sim.simulate_many([scene], engine="cuda", device=DEVICE)[0]
    direct = cuda_engine.simulate_many([scene], device=DEVICE)[0]
    np.testing.assert_array_equal(via_sim.final_positions, direct.final_positions)
    assert set(via_sim.to_dict()) == set(sim.simulate(scene).to_dict())
    with pytest.raises(EngineUnavailable, match="engine: must be one of numba, cuda, sleep"):
        sim.simulate_many([scene], engine="warp")
    with pytest.raises(EngineUnavailable, match="precision: must be one of float64, mixed"):
        cuda_engine.run_batch([build_robot(parse_scene(scene))], cuda_engine.device_of(DEVICE),
                              "float32")


def test_the_numba_engine_never_imports_numba_cuda():
    code = (
        "import sys; from softevo import sim; sim.simulate({'body': [[[1]]], "
        "'duration': {'seconds': 0.001}}); assert 'numba.cuda' not in sys.modules, 'imported'"
    )
    env = {k: v for k, v in os.environ.items() if k != "NUMBA_ENABLE_CUDASIM"}
    subprocess.run([sys.executable, "-c", code], check=True, env=env)


def test_missing_device_gpu_and_package_are_one_line_errors(monkeypatch):
    with pytest.raises(EngineUnavailable, match=r"no CUDA device 'cuda:7' here; there are: cuda:0"):
        cuda_engine.device_of("cuda:7")
    with pytest.raises(EngineUnavailable, match=r"takes cuda:N \(got 'cpu'\)"):
        cuda_engine.device_of("cpu")
    code = ("from softevo.sim import cuda_engine\n"
            "try:\n    cuda_engine.device_of('cuda:0')\n"
            "except Exception as e:\n    print(type(e).__name__, e)\n")
    env = {k: v for k, v in os.environ.items() if k != "NUMBA_ENABLE_CUDASIM"}
    if not ON_GPU:  # no GPU and no simulator: one line that names the simulator
        out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True)
        assert "EngineUnavailable device: no CUDA GPU here" in out.stdout, out
        assert "NUMBA_ENABLE_CUDASIM=1" in out.stdout
    monkeypatch.setitem(sys.modules, "numba.cuda", None)  # as if numba-cuda were not installed
    with pytest.raises(EngineUnavailable, match=r"pip install 'softevo\[gpu\]'"):
        cuda_engine.simulate_many([{"body": [[[1]]]}], device=DEVICE)


def test_cli_simulates_on_cuda_and_refuses_a_missing_device(tmp_path, capsys):
    pytest.importorskip("pydantic_settings", reason="the CLI's settings (a GPU image may lack them)")
    from tests.sim.test_cli_sim import assert_user_error, softevo_here, write

    tiny = _robot(10, "land", 0.3, "sine", False, size=2, seconds=0.002)
    tiny.pop("record")
    path = write(tmp_path, tiny)
    proc = softevo_here(capsys, "simulate", str(path), "--json", "--engine", "cuda", "--device", DEVICE)
    assert proc.returncode == 0, proc.stderr
    ours = json.loads(proc.stdout)
    theirs = sim.simulate(tiny).to_dict()
    assert ours["steps"] == theirs["steps"] and ours["stable"]
    assert ours["distance"] == pytest.approx(theirs["distance"], rel=1e-9, abs=1e-12)
    assert_user_error(
        softevo_here(capsys, "simulate", str(path), "--engine", "cuda", "--device", "cuda:7"),
        "no CUDA device 'cuda:7'",
    )
    assert_user_error(
        softevo_here(capsys, "simulate", str(path), "--engine", "gpu"), "engine: must be one of numba, cuda"
    )
    assert_user_error(
        softevo_here(capsys, "simulate", str(path), "--device", "cuda:0"),
        "--device: only the cuda and sleep engines",
    )


def test_workers_evaluate_on_the_engine_of_their_environment(monkeypatch):
    from softevo.worker.evaluate import DEVICE_ENV, ENGINE_ENV, engine_options, warm_up

    monkeypatch.delenv(ENGINE_ENV, raising=False)
    monkeypatch.setenv(DEVICE_ENV, "cuda:0")
    assert engine_options() == {}  # the numba engine: calls exactly as without the variables
    monkeypatch.setenv(ENGINE_ENV, "cuda")
    monkeypatch.setenv(DEVICE_ENV, DEVICE)
    assert engine_options() == {"engine": "cuda", "device": DEVICE}
    monkeypatch.setenv(DEVICE_ENV, "cuda:7")
    with pytest.raises(EngineUnavailable, match="cuda:7"):  # a GPU worker without its GPU
        warm_up()


def test_a_collapsed_body_stops_with_the_same_reason_as_on_numba():
    """The contact policy is the engines' one (``sim.physics``): the body of
    ``test_contact_policy`` collapses past MAX_CONTACTS candidates at the same step."""
    from tests.sim.test_contact_policy import collapsing

    scene = {**collapsing("voxcad-land-water"), "duration": {"seconds": 0.012}}
    gpu = sim.simulate(scene, engine="cuda", device=DEVICE)
    cpu = sim.simulate(scene)
    assert not gpu.stable and gpu.reason == cpu.reason and gpu.steps == cpu.steps
    assert gpu.reason.startswith("self-contact: a voxel had more than")
