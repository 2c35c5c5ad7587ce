"""How large may the step be? Distance error against a small-step reference, per stiffness.

For a walker (land) and a swimmer (water), each of the paper's five stiffnesses, run 10
actuation cycles at several ``dt_fraction`` values and compare the travelled distance with a
reference at ``--reference`` (default 0.1). Prints the error table and, per stiffness, the
largest fraction within 1%. Then evaluations per second of the paper-like robot (7^3 workspace,
50 cycles) at each stiffness with the default fraction, one core.

With ``--caps``, the other limit on the step instead: at the soft stiffnesses the step is set
by the actuation cap (at least ``sim.system.STEPS_PER_CYCLE`` steps per actuation cycle), so
the travelled distance is compared at several caps against a reference of 8000 steps per
cycle, and the smallest cap within 1% (with every larger one) is printed.

Usage: python bench/dt_accuracy.py [--cycles 10] [--reference 0.1] [--skip-speed]
       [--skip-accuracy] [--caps]
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from softevo import sim
from softevo.sim import system
from softevo.sim.scene import Scene
from softevo.sim.worlds import LAND, WATER

STIFFNESS_MPA = (0.001, 0.01, 0.1, 1.0, 10.0)
FRACTIONS = (0.15, 0.2, 0.3, 0.5, 0.7, 0.9, 1.2)
CAPS = (4000, 2000, 1000, 500, 250, 125)  # steps per cycle, against CAP_REFERENCE
CAP_REFERENCE = 8000


def walker() -> tuple[np.ndarray, np.ndarray]:
    """A four-legged 6x4x3 body, active legs, phase travelling along x."""
    body = np.zeros((6, 4, 3), int)
    body[:, :, 1:] = 1
    for x in (0, 1, 4, 5):
        for y in (0, 3):
            body[x, y, 0] = 2
    body[:, :, 2] = 2
    phase = np.broadcast_to(np.arange(6)[:, None, None] * 0.9, body.shape).copy()
    return body, phase


def swimmer() -> tuple[np.ndarray, np.ndarray]:
    """A 5x5x2 plate with two active flaps beating out of phase."""
    body = np.ones((5, 5, 2), int)
    body[:2] = 2
    body[3:] = 2
    phase = np.zeros(body.shape)
    phase[3:] = np.pi
    return body, phase


def scene(kind: str, mpa: float, fraction: float, cycles: float) -> dict:
    body, phase = walker() if kind == LAND.name else swimmer()
    return {
        "body": body.tolist(), "phase": phase.tolist(),
        "material": {"youngs_modulus": mpa * 1e6},
        "environment": {"kind": kind},
        "actuation": {"frequency": 2.0},
        "duration": {"cycles": cycles},
        "settle_seconds": 0.5 if kind == LAND.name else 0.0,
        "dt_fraction": fraction,
    }


def accuracy(cycles: float, reference: float) -> None:
    print(f"relative distance error vs dt_fraction {reference} ({cycles:g} cycles)")
    print(f"{'world':<7}{'MPa':>7}{'ref dist':>10}" + "".join(f"{f:>8}" for f in FRACTIONS)
          + "   largest safe")
    safe_all = []
    for kind in (LAND.name, WATER.name):
        for mpa in STIFFNESS_MPA:
            fractions = (reference, *FRACTIONS)
            results = sim.simulate_many([scene(kind, mpa, f, cycles) for f in fractions])
            base = results[0].distance
            errors = [abs(r.distance - base) / max(abs(base), 1e-9) if r.stable else np.inf
                      for r in results[1:]]
            largest = None  # the largest fraction with it and every smaller one within 1%
            for f, e in zip(FRACTIONS, errors, strict=True):
                if e > 0.01:
                    break
                largest = f
            safe_all.append(largest or 0.0)
            print(f"{kind:<7}{mpa:>7g}{base:>10.3f}" + "".join(f"{e:>8.2%}" for e in errors)
                  + f"   {largest}")
    print(f"largest fraction safe at every stiffness and world: {min(safe_all)}")


def caps(cycles: float) -> None:
    """Distance error at each cap of steps per cycle, for the stiffnesses it binds."""
    default = system.STEPS_PER_CYCLE
    print(f"relative distance error vs {CAP_REFERENCE} steps per cycle ({cycles:g} cycles, "
          f"default cap {default})")
    print(f"{'world':<7}{'MPa':>7}{'ref dist':>10}" + "".join(f"{c:>8}" for c in CAPS)
          + "   smallest safe")
    safe_all = []
    for kind in (LAND.name, WATER.name):
        for mpa in STIFFNESS_MPA[:3]:
            distances, stable = [], []
            for cap in (CAP_REFERENCE, *CAPS):
                r = sim.simulate({**scene(kind, mpa, 0.5, cycles),
                                  "model_options": {"min_steps_per_cycle": cap}})
                distances.append(r.distance)
                stable.append(r.stable)
            base = distances[0]
            errors = [abs(d - base) / max(abs(base), 1e-9) if ok else np.inf
                      for d, ok in zip(distances[1:], stable[1:], strict=True)]
            smallest = None  # the smallest cap with it and every larger one within 1%
            for cap, e in zip(CAPS, errors, strict=True):
                if e > 0.01:
                    break
                smallest = cap
            safe_all.append(smallest or CAP_REFERENCE)
            print(f"{kind:<7}{mpa:>7g}{base:>10.3f}" + "".join(f"{e:>8.2%}" for e in errors)
                  + f"   {smallest}")
    print(f"smallest cap safe at every soft stiffness and world: {max(safe_all)} steps per cycle")


def speed() -> None:
    rng = np.random.default_rng(1)
    body = rng.choice([0, 1, 2], size=(7, 7, 7), p=[0.4, 0.3, 0.3])
    base = {"body": body.tolist(), "phase": rng.uniform(0, 6.28, body.shape).tolist(),
            "actuation": {"frequency": 2.0}, "duration": {"cycles": 50}}
    default = Scene.__dataclass_fields__["dt_fraction"].default
    print(f"\npaper-like robot ({int((body > 0).sum())} voxels before pruning, 7^3 workspace, "
          f"50 cycles at 2 Hz, dt_fraction {default}), one core:")
    print(f"{'world':<7}{'MPa':>7}{'steps':>10}{'seconds':>9}{'evals/s':>9}{'Mvs/s':>8}")
    sim.simulate(dict(base, duration={"seconds": 0.001}))
    for kind in (LAND.name, WATER.name):
        for mpa in STIFFNESS_MPA:
            s = dict(base, environment={"kind": kind}, material={"youngs_modulus": mpa * 1e6},
                     settle_seconds=0.5 if kind == LAND.name else 0.0)
            start = time.perf_counter()
            r = sim.simulate(s)
            el = time.perf_counter() - start
            print(f"{kind:<7}{mpa:>7g}{r.steps:>10}{el:>9.2f}{1 / el:>9.3f}"
                  f"{r.steps * len(r.voxels) / el / 1e6:>8.2f}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--cycles", type=float, default=10)
    parser.add_argument("--reference", type=float, default=0.1)
    parser.add_argument("--skip-speed", action="store_true")
    parser.add_argument("--skip-accuracy", action="store_true")
    parser.add_argument("--caps", action="store_true", help="the actuation cap's table instead")
    args = parser.parse_args()
    if args.caps:
        caps(args.cycles)
        return
    if not args.skip_accuracy:
        accuracy(args.cycles, args.reference)
    if not args.skip_speed:
        speed()


if __name__ == "__main__":
    main()
