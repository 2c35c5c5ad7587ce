"""Simulator throughput: voxel-steps per second, single robot and simulate_many (all cores).

Usage: python bench/sim_throughput.py [--seconds 0.5] [--repeats 5] [--fields none,uniform,mixed]
                                     [--collisions on|off|both] [--single]
Prints compile time apart, then voxel-steps/s (medians of ``--repeats`` runs) with
self-collisions on and off, for actuated solid cubes of 4^3, 7^3, 10^3 on land and for random
7^3 robots, with the ratio to a fixed Voxelyze figure (2.8 M voxel-steps/s
on one core, once measured idle; ``bench/voxelyze_paired.py`` measures the ratio properly,
both engines in turn on the same host).
``--fields uniform`` gives every scene Young's modulus, density and frequency fields holding the
scalars (the same run, through the per-voxel path); ``mixed`` random ones (Young's modulus
0.1..1 MPa, density 600..1800 kg/m^3, frequency 2..4 Hz).
"""

from __future__ import annotations

import argparse
import os
import statistics
import time

import numba
import numpy as np

from softevo import sim
from softevo.sim.worlds import LAND

VOXELYZE = 2.8e6


def cube(n: int, rng: np.random.Generator, seconds: float) -> dict:
    return {
        "body": np.full((n, n, n), 2).tolist(),
        "phase": rng.uniform(0, 2 * np.pi, (n, n, n)).tolist(),
        "material": {"youngs_modulus": 1e6},
        "environment": {"kind": LAND.name},
        "actuation": {"frequency": 3.0},
        "duration": {"seconds": seconds},
    }


def random_robot(n: int, rng: np.random.Generator, seconds: float) -> dict:
    body = rng.choice([0, 1, 2], size=(n, n, n), p=[0.3, 0.35, 0.35])
    body[n // 2, n // 2, n // 2] = 2
    scene = cube(n, rng, seconds)
    scene["body"] = body.tolist()
    return scene


def with_fields(scene: dict, kind: str, rng: np.random.Generator) -> dict:
    """``scene`` with per-voxel material and frequency fields (``kind``: none, uniform, mixed)."""
    if kind == "none":
        return scene
    shape = np.asarray(scene["body"]).shape
    if kind == "uniform":
        e, rho, f = np.full(shape, 1e6), np.full(shape, 1200.0), np.full(shape, 3.0)
    else:
        e = 10 ** rng.uniform(5, 6, shape)
        rho, f = rng.uniform(600, 1800, shape), rng.uniform(2, 4, shape)
    return dict(scene, youngs_modulus_field=e.tolist(), density_field=rho.tolist(),
                frequency_field=f.tolist())


def voxel_steps(results) -> float:
    return float(sum(r.steps * len(r.voxels) for r in results))


def timed(scenes, threads, repeats: int):
    """Median voxel-steps/s of ``repeats`` runs (the host is noisy: medians, as the docs
    report)."""
    rates = []
    for _ in range(repeats):
        start = time.perf_counter()
        results = sim.simulate_many(scenes, threads=threads)
        rates.append(voxel_steps(results) / (time.perf_counter() - start))
    return statistics.median(rates), results


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--seconds", type=float, default=0.5, help="simulated seconds per robot")
    parser.add_argument("--repeats", type=int, default=5, help="runs per case; the median counts")
    parser.add_argument("--fields", default="none", help="per-voxel fields in every scene: "
                        "none, uniform or mixed, or several (comma-separated), one table row each")
    parser.add_argument("--collisions", choices=("on", "off", "both"), default="both",
                        help="self-collisions (on is the scenes' default)")
    parser.add_argument("--single", action="store_true", help="one core only (no simulate_many)")
    args = parser.parse_args()
    fields = [f for f in args.fields.split(",") if f]
    if not fields or any(f not in ("none", "uniform", "mixed") for f in fields):
        parser.error("--fields: none, uniform or mixed (comma-separated)")
    collisions = {"on": [True], "off": [False], "both": [True, False]}[args.collisions]
    rng = np.random.default_rng(0)
    cores = numba.config.NUMBA_NUM_THREADS
    print(f"cores: {cores} (os: {os.cpu_count()}), numba {numba.__version__}; "
          f"medians of {args.repeats} runs")

    start = time.perf_counter()
    sim.simulate(cube(2, rng, 0.001))
    print(f"compile / cache load: {time.perf_counter() - start:.2f} s (not counted below)")

    print(f"{'case':<20}{'fields':>8}{'collide':>8}{'voxels':>7}{'1 core Mvs/s':>14}"
          f"{'x Voxelyze':>11}{'many, all cores':>17}{'x 1 core':>9}")
    cases = [(f"solid cube {n}^3", [cube(n, rng, args.seconds) for _ in range(2 * cores)])
             for n in (4, 7, 10)]
    cases.append(("random 7^3 robots", [random_robot(7, rng, args.seconds) for _ in range(4 * cores)]))
    for name, base in cases:
        for kind in fields:
            with_kind = [with_fields(s, kind, rng) for s in base]
            for collide in collisions:
                scenes = [dict(s, self_collisions=collide) for s in with_kind]
                single, res = timed(scenes[:1], threads=1, repeats=args.repeats)
                many = single if args.single else timed(scenes, threads=cores, repeats=args.repeats)[0]
                voxels = np.mean([len(r.voxels) for r in res])
                print(f"{name:<20}{kind:>8}{'on' if collide else 'off':>8}{voxels:>7.0f}"
                      f"{single / 1e6:>14.2f}{single / VOXELYZE:>11.2f}{many / 1e6:>17.2f}"
                      f"{many / single:>9.2f}", flush=True)


if __name__ == "__main__":
    main()
