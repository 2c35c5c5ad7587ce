"""CUDA engine throughput against batch size, side by side with the numba engine.

Usage: python bench/gpu_throughput.py [--device cuda:0] [--max-batch 10000] [--steps 2000]
           [--numba-max-batch 100] [--batches 1,10,100,1000,10000] [--precisions float64,mixed]
           [--side 7] [--accuracy 0]

Paper-like robots: random 7^3 bodies (about 2/3 full, half the voxels active), the scene
defaults of ``sim.scene`` (voxel size, density, actuation), 1 and 10 MPa, land and water.
Each case runs ``--steps`` steps of a batch of 1, 10, 100, 1,000, 10,000 robots (up to
``--max-batch``; ``--batches`` picks others) and prints voxel-steps/s, the evaluations/s that
means (an evaluation is the whole run ``evolution`` asks for: ``DEFAULT_CYCLES`` cycles plus
settling on land) and the ratio to the numba engine on all cores (``simulate_many``, timed up
to ``--numba-max-batch`` robots; its throughput no longer grows once every core has a robot,
so larger batches are compared with its last rate). The CUDA engine's rate is its step
loop's (``cuda_engine.run_batch``'s ``seconds``); "end-to-end" adds building the robots
(timed on the pool of up to 100 distinct robots a batch repeats, scaled to the batch),
packing, copying and the results (numba's rate is end-to-end: its building is a small part
of its time). Compilation is timed apart (one warm-up call per precision).

``--precisions float64,mixed`` times both precisions (``model_options.precision``; "mixed":
the links in float32); a precision the engine refuses is printed in one line and dropped.
``--accuracy N`` runs N whole evaluations per stiffness and world in float64 and mixed and
prints how far mixed's distances are from float64's (docs/gpu.md).

On numba-cuda's simulator (``NUMBA_ENABLE_CUDASIM=1``, pure Python) keep everything tiny:
``NUMBA_ENABLE_CUDASIM=1 python bench/gpu_throughput.py --max-batch 1 --steps 5
--numba-max-batch 1`` (``--side 3`` for 3^3 robots instead of 7^3).
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import time

import numba
import numpy as np

from softevo import sim
from softevo.evolution.environments import LAND, PAPER
from softevo.sim import cuda_engine
from softevo.sim.cost import voxel_steps as scene_voxel_steps
from softevo.sim.engines import EngineUnavailable
from softevo.sim.scene import DEFAULT_CYCLES, parse_scene
from softevo.sim.system import build_robot

BATCHES = (1, 10, 100, 1000, 10000)
POOL = 100  # distinct robots per case; a larger batch repeats them


def paper_robot(rng: np.random.Generator, world: str, modulus: float, side: int = 7) -> dict:
    """A random ``side``^3 robot (7: the paper's) in the evolution's evaluation scene
    (``DEFAULT_CYCLES`` cycles, 0.5 s settling on land)."""
    body = rng.choice([0, 1, 2], size=(side, side, side), p=[0.3, 0.35, 0.35])
    body[side // 2, side // 2, side // 2] = 2
    return {
        "body": body.tolist(),
        "phase": rng.uniform(-math.pi, math.pi, (side, side, side)).tolist(),
        "material": {"youngs_modulus": modulus},
        "environment": {"kind": world},
        "duration": {"cycles": DEFAULT_CYCLES},
        "settle_seconds": 0.5 if world == LAND.name else 0.0,
    }


def evaluation_cost(scene: dict) -> tuple[int, float]:
    """(voxels, steps) of the whole evaluation of ``scene``."""
    voxels, steps = scene_voxel_steps(parse_scene(scene))
    return voxels, float(steps)


def shortened(scene: dict, steps: int) -> dict:
    """``scene`` cut to ``steps`` steps of actuation (no settling)."""
    dt = sim.scene_dt(parse_scene(scene))
    return {**scene, "settle_seconds": 0.0, "duration": {"seconds": steps * dt}}


def voxel_steps(results) -> float:
    return float(sum(r.steps * len(r.voxels) for r in results))


def timed(run, scenes) -> tuple[float, list]:
    start = time.perf_counter()
    results = run(scenes)
    return time.perf_counter() - start, results


def device_name(dev) -> str:
    """A readable name of a numba-cuda device (the simulator's has none)."""
    name = getattr(dev, "name", None)
    if isinstance(name, bytes):
        name = name.decode()
    if numba.config.ENABLE_CUDASIM:
        return f"numba-cuda simulator{f' {name}' if name else ''}"
    return name or str(dev)


def in_precision(scene: dict, precision: str) -> dict:
    """``scene`` run in ``precision`` (its ``model_options.precision``)."""
    return {**scene, "model_options": {**scene.get("model_options", {}), "precision": precision}}


def usable_precisions(requested: list[str], device: str) -> list[str]:
    """The precisions the engine accepts (one tiny run each); a refusal is printed in one
    line, and the precision dropped."""
    warm = [{"body": [[[2]], [[1]]], "duration": {"seconds": 0.001}}]
    usable = []
    for precision in requested:
        try:
            seconds, _ = timed(lambda s, p=precision: cuda_engine.simulate_many(
                [in_precision(x, p) for x in s], device), warm)
        except EngineUnavailable as exc:
            print(f"{precision}: refused by the engine: {exc}")
            continue
        print(f"warm-up (compile or load from numba's cache) {precision}: {seconds:.1f} s")
        usable.append(precision)
    return usable


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument(
        "--device", default="cuda:0", help="CUDA device (default cuda:0; the simulator's too)"
    )
    parser.add_argument("--max-batch", type=int, default=10000)
    parser.add_argument("--numba-max-batch", type=int, default=100)
    parser.add_argument("--steps", type=int, default=2000, help="steps per robot per case")
    parser.add_argument(
        "--batches", default=",".join(map(str, BATCHES)), help="batch sizes (those up to --max-batch run)"
    )
    parser.add_argument("--precisions", default="float64,mixed", help="float64, mixed, or both")
    parser.add_argument("--side", type=int, default=7, help="robots' side in voxels (7: the paper's)")
    parser.add_argument("--worlds", default=",".join(PAPER))
    parser.add_argument("--moduli", default="1e6,1e7", help="Young's moduli, Pa")
    parser.add_argument(
        "--accuracy", type=int, default=0, help="whole evaluations per case for mixed vs float64"
    )
    args = parser.parse_args()

    try:
        dev = cuda_engine.device_of(args.device)
    except EngineUnavailable as exc:
        print(f"error: {exc}", file=sys.stderr)
        raise SystemExit(2) from None
    device = args.device
    print(
        f"device: {device} ({device_name(dev)}); numba on {numba.get_num_threads()} "
        f"threads of {os.cpu_count()} cores; {args.steps} steps per robot"
    )
    precisions = usable_precisions(args.precisions.split(","), device)
    if not precisions:
        print("error: the engine accepted none of the precisions asked for", file=sys.stderr)
        raise SystemExit(2)
    warm = [{"body": [[[2]], [[1]]], "duration": {"seconds": 0.001}}]
    seconds, _ = timed(sim.simulate_many, warm)
    print(f"warm-up numba engine: {seconds:.1f} s")
    batches = [b for b in (int(b) for b in args.batches.split(",")) if b <= args.max_batch]

    header = (
        f"{'world':6} {'E MPa':>5} {'batch':>6} {'engine':>13} {'voxel-steps/s':>14} "
        f"{'end-to-end':>14} {'eval/s':>9} {'robots/s':>9} {'x numba':>8}"
    )
    print(header)
    print("-" * len(header))
    for world in args.worlds.split(","):
        for modulus in (float(m) for m in args.moduli.split(",")):
            rng = np.random.default_rng(0)
            pool = [
                paper_robot(rng, world, modulus, args.side) for _ in range(min(max(batches, default=1), POOL))
            ]
            voxels, eval_steps = evaluation_cost(pool[0])
            eval_cost = voxels * eval_steps  # voxel-steps of one whole evaluation
            print(
                f"# {world}, {modulus / 1e6:g} MPa: an evaluation is {eval_steps:,.0f} steps of "
                f"{voxels} voxels ({eval_cost:.3g} voxel-steps)"
            )
            short = [shortened(scene, args.steps) for scene in pool]
            start = time.perf_counter()
            built = [build_robot(parse_scene(s)) for s in short]
            build_each = (time.perf_counter() - start) / len(built)
            numba_rate = None
            for batch in batches:
                scenes = [short[k % len(short)] for k in range(batch)]
                rows = []
                if batch <= args.numba_max_batch:
                    seconds, results = timed(sim.simulate_many, scenes)
                    numba_rate = voxel_steps(results) / seconds
                    rows.append(("numba", numba_rate, None, batch / seconds))
                robots = [built[k % len(built)] for k in range(batch)]
                for precision in precisions:
                    start = time.perf_counter()
                    out = cuda_engine.run_batch(robots, dev, precision)
                    total = build_each * batch + time.perf_counter() - start
                    rows.append(
                        (
                            f"cuda {precision}",
                            out.voxel_steps / out.seconds,
                            out.voxel_steps / total,
                            batch / out.seconds,
                        )
                    )
                for engine, rate, overall, robots_per_s in rows:
                    ratio = f"{rate / numba_rate:8.2f}" if numba_rate else f"{'':8}"
                    end = f"{overall:14.4g}" if overall else f"{'':14}"
                    print(
                        f"{world:6} {modulus / 1e6:5.0f} {batch:6d} {engine:>13} {rate:14.4g} "
                        f"{end} {rate / eval_cost:9.3g} {robots_per_s:9.4g} {ratio}",
                        flush=True,
                    )
            if args.accuracy:
                accuracy(rng, world, modulus, args.accuracy, device, args.side)


def accuracy(rng, world: str, modulus: float, n: int, device: str, side: int = 7) -> None:
    """mixed against float64 over ``n`` whole evaluations, or the engine's refusal."""
    scenes = [paper_robot(rng, world, modulus, side) for _ in range(n)]
    try:
        f32 = cuda_engine.simulate_many([in_precision(s, "mixed") for s in scenes], device)
    except EngineUnavailable as exc:
        print(f"accuracy {world} {modulus / 1e6:g} MPa: mixed refused by the engine: {exc}")
        return
    f64 = cuda_engine.simulate_many(scenes, device)
    rel = [
        abs(a.distance - b.distance) / max(a.distance, 1e-3)
        for a, b in zip(f64, f32, strict=True)
        if a.stable and b.stable
    ]
    flags = sum(a.stable != b.stable for a, b in zip(f64, f32, strict=True))
    print(
        f"accuracy {world} {modulus / 1e6:g} MPa: mixed vs float64 distance over "
        f"{len(rel)} robots: median {np.median(rel):.3g}, max {np.max(rel):.3g}; "
        f"stability mismatches {flags}"
    )


if __name__ == "__main__":
    main()
