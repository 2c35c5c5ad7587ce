"""Shared helpers for the physics tests: running scenes, reading frames, reporting agreement.

Every agreement figure a test measures (ratio, percent) goes through ``report``: it is printed
(visible with ``pytest -s``), listed in pytest's terminal summary, and written to
``$SOFTEVO_AGREEMENT_JSON`` (default ``/tmp/softevo_sim_agreement.json``) so the figures can be
quoted without re-running.
"""

from __future__ import annotations

import json
import math
import os
from pathlib import Path
from typing import Any

import numpy as np

AGREEMENT: dict[str, dict[str, Any]] = {}
AGREEMENT_PATH = Path(os.environ.get("SOFTEVO_AGREEMENT_JSON", "/tmp/softevo_sim_agreement.json"))


def report(name: str, **figures: Any) -> None:
    """Record measured agreement figures for ``name`` (printed and saved as JSON)."""
    clean = {k: (float(v) if isinstance(v, (np.floating, np.integer)) else v)
             for k, v in figures.items()}
    AGREEMENT[name] = clean
    print(f"[agreement] {name}: " + ", ".join(f"{k}={_fmt(v)}" for k, v in clean.items()))
    try:
        old = json.loads(AGREEMENT_PATH.read_text()) if AGREEMENT_PATH.exists() else {}
    except (OSError, ValueError):
        old = {}
    old[name] = clean
    try:
        AGREEMENT_PATH.write_text(json.dumps(old, indent=1, sort_keys=True))
    except OSError:
        pass


def _fmt(v: Any) -> str:
    return f"{v:.5g}" if isinstance(v, float) else str(v)


# Keyword arguments of ``sim.simulate`` for the engine under test: empty is the default
# (numba) engine; ``test_cuda_engine`` runs some analytic tests again with the cuda engine.
ENGINE: dict[str, Any] = {}
# The precision under test (``sim.models.PRECISIONS``): the closed-form suite runs in each
# (the ``precision`` fixture of tests/sim/conftest.py sets it).
PRECISION = "float64"


def with_precision(scene: dict, precision: str | None = None) -> dict:
    """``scene`` with ``model_options.precision`` set (default: the one under test)."""
    options = {**scene.get("model_options", {}), "precision": precision or PRECISION}
    return {**scene, "model_options": options}


def simulate(scene: dict) -> Any:
    """Run ``scene`` on the engine under test (``ENGINE``) in the precision under test
    (``PRECISION``) and insist it stayed stable (a physics test never expects a blow-up)."""
    from softevo import sim

    result = sim.simulate(with_precision(scene), **ENGINE)
    assert result.stable, f"unstable: {result.reason}"
    return result


def frames(result: Any) -> tuple[np.ndarray, np.ndarray]:
    """(t (n_frames,) s, positions (n_frames, n_voxels, 3) m) of a recorded result."""
    assert result.frames, "the scene asked for frames (record.every) but none came back"
    t = np.asarray(result.frames["t"], dtype=float)
    pos = np.asarray(result.frames["positions"], dtype=float).reshape(len(t), -1, 3)
    return t, pos


def com_trajectory(result: Any) -> tuple[np.ndarray, np.ndarray]:
    """(t (n,) s, com (n, 3) m) from the result's sampled centre-of-mass trajectory."""
    traj = result.com_trajectory
    t = np.asarray(traj["t"], dtype=float)
    com = np.asarray(traj["com"], dtype=float).reshape(len(t), 3)
    return t, com


def voxel_index(result: Any) -> dict[tuple[int, int, int], int]:
    """Map body index (i, j, k) -> row of final_positions / frames."""
    return {tuple(int(c) for c in v): n for n, v in enumerate(result.voxels)}


def stable_dt(voxel_size: float, density: float, youngs_modulus: float, fraction: float) -> float:
    """docs/physics.md's step: dt = fraction * L * sqrt(rho / E) / (2 pi)."""
    return fraction * voxel_size * math.sqrt(density / youngs_modulus) / (2 * math.pi)


def line(n: int, axis: int = 0) -> list:
    """A straight bar of ``n`` passive voxels along ``axis`` as a body[x][y][z] list."""
    shape = [1, 1, 1]
    shape[axis] = n
    return np.ones(shape, dtype=int).tolist()


def period_of(t: np.ndarray, signal: np.ndarray, crossings: int) -> float:
    """Mean period from the upward crossings of ``signal``'s mid-range (linear
    interpolation); asserts at least ``crossings`` of them."""
    s = signal - 0.5 * (signal.max() + signal.min())
    up = np.nonzero((s[:-1] < 0) & (s[1:] >= 0))[0]
    times = t[up] - s[up] * (t[up + 1] - t[up]) / (s[up + 1] - s[up])
    assert len(times) >= crossings
    return float(np.diff(times).mean())
