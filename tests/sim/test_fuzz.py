"""Fuzz: random robots through ``sim.simulate_many`` never raise and never lie.

Random bodies (1 to 7^3 voxels), stiffness 1e3 to 1e7 Pa (log-uniform), every world, random
waveforms, amplitudes up to the schema's 0.9, a few deliberately oversized steps: every
result is either stable with finite numbers or flagged with a reason and distance 0. The
results must also come back in the order of the scenes (checked through each robot's
largest component size and dt, which differ from robot to robot).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import ndimage

from softevo import sim
from softevo.sim.system import STEPS_PER_CYCLE, largest_component

WORLDS = ("land", "water", "void")
WAVEFORMS = ("sine", "square", "impulse")


def random_scene(rng: np.random.Generator, index: int) -> dict:
    shape = rng.integers(1, 8, size=3)
    fill = rng.uniform(0.2, 1.0)
    body = (rng.random(shape) < fill).astype(int)
    if not body.any():
        body[tuple(rng.integers(0, s) for s in shape)] = 1
    active = rng.random(shape) < rng.uniform(0.0, 1.0)
    body[(body > 0) & active] = 2
    scene = {
        "voxel_size": float(rng.choice([0.01, 0.05])),
        "material": {"youngs_modulus": float(10 ** rng.uniform(3, 7)),
                     "density": float(rng.uniform(500, 2000))},
        "environment": {"kind": WORLDS[index % 3]},
        "body": body.tolist(),
        "phase": rng.uniform(-math.pi, math.pi, shape).tolist(),
        "actuation": {"frequency": float(rng.uniform(2.0, 8.0)),
                      "amplitude": float(rng.uniform(0.0, 0.9)),
                      "waveform": WAVEFORMS[int(rng.integers(0, 3))]},
        "duration": {"cycles": 2},
        "self_collisions": bool(rng.random() < 0.7),
    }
    if rng.random() < 0.1:  # far past the stable step: these should come back flagged
        scene["dt_fraction"] = float(rng.uniform(2.0, 6.0))
    if rng.random() < 0.2:
        scene["initial_velocity"] = rng.normal(0, 0.1, 3).tolist()
    return scene


def largest_component_size(body: np.ndarray) -> int:
    labels, n = ndimage.label(body > 0)  # default structure: face connectivity
    return int(np.bincount(labels.ravel())[1:].max()) if n else 0


def check_results(scenes: list[dict], results: list) -> tuple[int, int]:
    """Assert every result is sane; return (stable, flagged) counts."""
    assert len(results) == len(scenes)
    stable = flagged = 0
    for k, (scene, res) in enumerate(zip(scenes, results, strict=True)):
        body = np.asarray(scene["body"])
        m = scene["material"]
        dt = scene.get("dt_fraction", sim.Scene.dt_fraction) * scene["voxel_size"] * math.sqrt(
            m["density"] / m["youngs_modulus"]) / (2 * math.pi)
        frequency = scene.get("actuation", {}).get("frequency", 3.0)
        if frequency > 0 and (largest_component(body) == 2).any():
            dt = min(dt, 1.0 / (frequency * STEPS_PER_CYCLE))  # actuation-period cap
        where = f"robot {k} ({scene['environment']['kind']}, E={m['youngs_modulus']:.3g})"
        assert res.dt == pytest.approx(dt, rel=1e-9), where
        voxels = np.asarray(res.voxels)
        assert len(voxels) == largest_component_size(body), where
        assert np.all(body[tuple(voxels.T)] > 0), where
        assert np.asarray(res.final_positions).shape == (len(voxels), 3), where
        if res.stable:
            stable += 1
            assert res.reason is None, where
            assert np.all(np.isfinite(res.final_positions)), where
            assert math.isfinite(res.distance) and res.distance >= 0, where
        else:
            flagged += 1
            assert isinstance(res.reason, str) and res.reason, where
            assert res.distance == 0.0, where
    return stable, flagged


def _fuzz(n: int, seed: int) -> None:
    from softevo import sim

    rng = np.random.default_rng(seed)
    scenes = [random_scene(rng, k) for k in range(n)]
    results = sim.simulate_many(scenes)
    stable, flagged = check_results(scenes, results)
    print(f"[fuzz] {n} robots: {stable} stable, {flagged} flagged")
    # the checks above hold trivially if every robot is flagged: most robots at the default
    # step must run to the end (a simulator that fails them all fails here)
    regular = [res for scene, res in zip(scenes, results, strict=True) if "dt_fraction" not in scene]
    assert sum(res.stable for res in regular) >= 0.8 * len(regular), "most robots at the default step run"


def test_fuzz_30_random_robots():
    _fuzz(30, seed=20240611)


@pytest.mark.slow
def test_fuzz_500_random_robots():
    _fuzz(500, seed=7)
