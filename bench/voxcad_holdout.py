"""Robots the repo has never seen, through both engines, as a new user would run them.

New random CPPN robots (seeds from ``--seed``, none of tests/sim/reference/voxcad's), of the
paper's 7 x 7 x 7 workspace by default, at stiffness S1..S5, land and water, self-collisions
on and off, are written as VXA files in the paper's layout (``bench/voxcad_reference.py``'s
``make_vxa``) and run

- by the paper's engine, built from source by ``bench/voxcad_reference.py`` (its driver; the
  build is reused when present), and
- by ours exactly as a user would: ``softevo import-vxa FILE.vxa --out SCENE.json`` then
  ``softevo simulate SCENE.json --json --precision P`` (its ``distance``), once per precision
  of ``--precisions``.

It prints each robot's normAbsoluteDisplacement and ours in each precision with the ratio,
then per precision the median |log ratio|, the rank correlation and the shares within 10% and
30%, to set beside the spread of tests/sim/test_voxcad_reference.py (docs/fidelity.md), and
how far the precisions are from each other (median and largest |log ratio|).

    python bench/voxcad_holdout.py [--robots 20] [--seed 7000] [--workspace 7] [--cycles 8]
           [--precisions float64,mixed]
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import math
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
from scipy import stats

from softevo.evolution.environments import PAPER, WATER

HERE = Path(__file__).resolve().parent
SPEC = importlib.util.spec_from_file_location("voxcad_reference", HERE / "voxcad_reference.py")
reference = importlib.util.module_from_spec(SPEC)
SPEC.loader.exec_module(reference)

LEVELS = list(reference.STIFFNESS.items())


def softevo_cli() -> list[str]:
    found = shutil.which("softevo")
    if found:
        return [found]
    return [sys.executable, "-c", "from softevo.service.cli import main; main()"]


def ours(cli: list[str], vxa_path: Path, precision: str) -> dict:
    scene = vxa_path.with_suffix(".json")
    if not scene.exists():
        subprocess.run([*cli, "import-vxa", str(vxa_path), "--out", str(scene)], check=True,
                       capture_output=True, text=True)
    out = subprocess.run([*cli, "simulate", str(scene), "--json", "--precision", precision],
                         check=True, capture_output=True, text=True).stdout
    return json.loads(out)


def summary(label: str, theirs: list[float], mine: list[float]) -> None:
    log = np.abs(np.log(np.asarray(mine) / np.asarray(theirs)))
    rho = stats.spearmanr(theirs, mine)[0]
    print(f"{label}: robots {len(mine)}, median |log ratio| {np.median(log):.3f}, Spearman "
          f"{rho:.3f}, within 10% {np.mean(log < math.log(1.1)):.0%}, within 30% "
          f"{np.mean(log < math.log(1.3)):.0%}, worst ratio {math.exp(log.max()):.2f}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--robots", type=int, default=20)
    parser.add_argument("--seed", type=int, default=7000)
    parser.add_argument("--workspace", type=int, default=7)
    parser.add_argument("--cycles", type=float, default=8.0)
    parser.add_argument("--evosoro", type=Path, default=reference.MIRROR)
    parser.add_argument("--build", type=Path, default=Path("/tmp/voxcad-build"))
    parser.add_argument("--precisions", default="float64",
                        help="comma-separated: ours in each (simulate --precision)")
    args = parser.parse_args()
    precisions = args.precisions.split(",")
    info = reference.build(args.evosoro, args.build / "O3")  # reused when built
    cli = softevo_cli()
    rng = np.random.default_rng(args.seed)
    rows = []
    seed = args.seed
    work = Path(tempfile.mkdtemp(prefix="softevo-holdout-"))
    print(f"{'robot':<28}{'vox':>5}{'steps':>8}{'paper engine':>14}"
          + "".join(f"{p:>10}{'ratio':>8}" for p in precisions))
    for k in range(args.robots):
        level, youngs = LEVELS[k % len(LEVELS)]
        env = PAPER[(k // len(LEVELS)) % 2]
        collisions = bool(rng.random() < 0.5)
        seed, pheno = reference.cppn_robot(seed, (args.workspace,) * 3)
        period = 1.0 / pheno.frequency
        stop = args.cycles * period + (0.0 if env == WATER.name else 0.5)
        vxa = reference.make_vxa(pheno.body, pheno.phase / (2 * np.pi), period, youngs,
                                 env == WATER.name, collisions, stop)
        name = f"{level}_{env}_{'col' if collisions else 'nocol'}_{seed}"
        seed += 1
        fork = reference.run_driver(info["driver"], vxa, work, name, every=0)
        theirs = fork["fitness_file"]["normAbsoluteDisplacement"]
        path = work / f"{name}.vxa"
        mine = [ours(cli, path, p)["distance"] for p in precisions]
        rows.append((name, theirs, mine))
        print(f"{name:<28}{fork['result']['voxels']:>5}{fork['result']['steps']:>8}{theirs:>14.4f}"
              + "".join(f"{d:>10.4f}{d / theirs if theirs > 0 else math.inf:>8.3f}" for d in mine),
              flush=True)
    for q, precision in enumerate(precisions):
        summary(precision, [r[1] for r in rows], [r[2][q] for r in rows])
    for q in range(1, len(precisions)):
        between = np.abs(np.log([r[2][q] / r[2][0] for r in rows]))
        print(f"{precisions[q]} against {precisions[0]}: median |log ratio| "
              f"{np.median(between):.2e}, largest {between.max():.2e}")


if __name__ == "__main__":
    main()
