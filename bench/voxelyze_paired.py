"""softevo against Voxelyze, like for like on one core, the two engines run in turn.

Usage: python bench/voxelyze_paired.py --voxelyze PATH [--pairs 5] [--seconds 0.5]
``PATH`` is a checkout of jonhiller/Voxelyze (commit 4287e36); its sources are built once
with ``g++ -O3`` together with ``bench/voxelyze/driver.cpp`` (into ``--build``). The scene is
the issue's: a 7^3 body of 5 cm voxels, E 1 MPa, rho 1200, nu 0.4, every other column active
at 3 Hz with amplitude 0.39 and a phase along x, on land. Each case runs ``--pairs`` pairs
(Voxelyze, then softevo, same scene and step count); the ratio is taken pair by pair, because
the host's speed drifts, and the table gives the median ratio with its range. Cases: self-
collisions on and off, one material (uniform fields in softevo's scene: the per-voxel path) and
mixed (every voxel its own E 0.1..1 MPa and rho 600..1800; one Voxelyze material per voxel).
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

from softevo import sim
from softevo.sim.scene import parse_scene
from softevo.sim.worlds import LAND

SOURCES = ("Voxelyze", "VX_Voxel", "VX_External", "VX_Link", "VX_Material", "VX_MaterialVoxel",
           "VX_MaterialLink", "VX_Collision", "VX_LinearSolver", "VX_MeshRender")
DRIVER = Path(__file__).with_name("voxelyze") / "driver.cpp"
G = 9.80665


def build(voxelyze: Path, out: Path) -> Path:
    """The driver binary, compiled once per source tree (rebuilt when driver.cpp changes)."""
    out.mkdir(parents=True, exist_ok=True)
    binary = out / "voxelyze-driver"
    if binary.exists() and binary.stat().st_mtime > DRIVER.stat().st_mtime:
        return binary
    sources = [str(voxelyze / "src" / f"{name}.cpp") for name in SOURCES]
    missing = [s for s in sources if not Path(s).exists()]
    if missing:
        sys.exit(f"error: {voxelyze} is not a Voxelyze checkout (no {missing[0]})")
    print(f"building Voxelyze with g++ -O3 into {binary} ...", flush=True)
    subprocess.run(["g++", "-O3", "-std=c++11", "-w", "-I", str(voxelyze / "include"), "-o",
                    str(binary), str(DRIVER), *sources], check=True)
    return binary


def scene(mixed: bool, collisions: bool, seconds: float, n: int = 7) -> dict:
    rng = np.random.default_rng(1)
    body = np.ones((n, n, n), int)
    x, y = np.meshgrid(np.arange(n), np.arange(n), indexing="ij")
    body[(x + y) % 2 == 0, :] = 2
    phase = np.broadcast_to(2 * np.pi * np.arange(n)[:, None, None] / n, body.shape)
    if mixed:
        e, rho = 10 ** rng.uniform(5, 6, body.shape), rng.uniform(600, 1800, body.shape)
    else:
        e, rho = np.full(body.shape, 1e6), np.full(body.shape, 1200.0)
    return {
        "body": body.tolist(), "phase": phase.tolist(), "voxel_size": 0.05,
        "material": {"youngs_modulus": 1e6, "density": 1200.0, "poisson_ratio": 0.4},
        "youngs_modulus_field": e.tolist(), "density_field": rho.tolist(),
        "environment": {"kind": LAND.name, "gravity": G},
        "actuation": {"frequency": 3.0, "amplitude": 0.39},
        "duration": {"seconds": seconds}, "self_collisions": collisions,
    }


def voxelyze_input(doc: dict, steps: int) -> str:
    """``doc`` in the driver's text format (one Voxelyze material per distinct E, rho)."""
    s = parse_scene(doc)
    m = s.material
    lines = [f"{s.voxel_size} {steps} {int(s.self_collisions)} {s.actuation.amplitude} "
             f"{m.poisson_ratio} {s.environment.gravity / G}",
             f"{m.damping_bond} {m.damping_global} {m.damping_collision} {m.friction_static} "
             f"{m.friction_kinetic}"]
    materials: dict[tuple[float, float], int] = {}
    voxels = []
    for i, j, k in np.argwhere(s.body > 0):
        key = (float(s.youngs_modulus_field[i, j, k]), float(s.density_field[i, j, k]))
        index = materials.setdefault(key, len(materials))
        voxels.append(f"{i} {j} {k} {index} {int(s.body[i, j, k] == 2)} "
                      f"{float(s.phase[i, j, k])!r} {s.actuation.frequency}")
    lines.append(str(len(materials)))
    lines += [f"{e!r} {rho!r}" for e, rho in materials]
    lines.append(str(len(voxels)))
    return "\n".join(lines + voxels) + "\n"


def run_voxelyze(binary: Path, text: str) -> float:
    out = subprocess.run([str(binary)], input=text, capture_output=True, text=True, check=True)
    r = json.loads(out.stdout)
    return r["voxels"] * r["steps"] / r["seconds"]


def run_softevo(doc: dict) -> tuple[float, int]:
    start = time.perf_counter()
    (r,) = sim.simulate_many([doc], threads=1)
    seconds = time.perf_counter() - start
    if not r.stable:
        sys.exit(f"error: softevo found the bench scene unstable ({r.reason})")
    return len(r.voxels) * r.steps / seconds, r.steps


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--voxelyze", type=Path, required=True, help="a jonhiller/Voxelyze checkout")
    parser.add_argument("--build", type=Path, default=Path("/tmp/softevo-voxelyze-build"))
    parser.add_argument("--pairs", type=int, default=5)
    parser.add_argument("--seconds", type=float, default=0.5, help="simulated seconds per run")
    args = parser.parse_args()
    binary = build(args.voxelyze, args.build)
    sim.simulate(scene(False, True, 0.001))  # compile / load the cache outside the timing
    print(f"pairs per case: {args.pairs}; M voxel-steps/s on one core, medians; ratio pair by pair")
    print(f"{'case':<26}{'softevo':>9}{'Voxelyze':>10}{'ratio':>8}{'ratio range':>16}")
    for collisions in (True, False):
        for mixed in (False, True):
            doc = scene(mixed, collisions, args.seconds)
            _, steps = run_softevo(doc)
            text = voxelyze_input(doc, steps)
            ours, theirs = [], []
            for _ in range(args.pairs):
                theirs.append(run_voxelyze(binary, text))
                ours.append(run_softevo(doc)[0])
            ratios = [a / b for a, b in zip(ours, theirs, strict=True)]
            name = f"{'collisions' if collisions else 'no collisions'}, {'mixed' if mixed else 'uniform'}"
            print(f"{name:<26}{statistics.median(ours) / 1e6:>9.2f}{statistics.median(theirs) / 1e6:>10.2f}"
                  f"{statistics.median(ratios):>8.2f}{f'{min(ratios):.2f}..{max(ratios):.2f}':>16}",
                  flush=True)


if __name__ == "__main__":
    main()
