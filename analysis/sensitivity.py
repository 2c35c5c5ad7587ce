"""How much do the stiffness findings depend on the model's choices?

Reruns the land and the water stiffness series (in memory, no database) with one modelling
choice changed at a time and reports, per variant and world, the best distance per stiffness
(one value per run: its best at the last generation; mean over repetitions), the best
stiffness and whether distance rises or falls from S1 to S5. The choices:

- ``damping``: global damping ``damping_global`` 0.01 -> 0.002 (it grows with sqrt(E), so it
  brakes stiff robots hardest);
- ``cycles``: the evaluation length, the study's 8 cycles -> 16;
- ``frequency``: the evolvable actuation frequency range, 1-5 Hz -> 1-3 Hz.

Usage: python -m softevo.analysis.sensitivity [--stiffness 0.001,0.1,10] [--repetitions 3]
           [--generations 10] [--population 8] [--workspace 6] [--cycles 8]
           [--variants default,damping,cycles,frequency] [--csv OUT]
The defaults are the ``study`` scale's sizes (docs/results), with 3 repetitions (seeds 0..2)
at S1, S3 and S5.
"""

from __future__ import annotations

import argparse
import csv
import sys
import time
from dataclasses import replace
from functools import partial

from softevo import sim
from softevo.evolution import environments
from softevo.evolution.algorithm import EvolutionConfig
from softevo.evolution.evaluation import EvaluationSpec
from softevo.evolution.genotype import EncodingConfig
from softevo.evolution.outcome import Outcome
from softevo.evolution.runner import best_distance, run
from softevo.worker.evaluate import evaluate_generation

VARIANTS = {
    "default": "the study's settings",
    "damping": "global damping 0.002 (default 0.01)",
    "cycles": "16 cycles per evaluation (study: 8)",
    "frequency": "frequency range 1-3 Hz (default 1-5)",
}
LOW_DAMPING = 0.002


def with_damping(damping: float):
    """A simulator for the workers' evaluation (``worker.evaluate.Simulate``): the outcomes
    of ``sim.simulate_many`` on scenes whose global damping is ``damping``."""

    def simulate(scenes):
        changed = [dict(s, material={**s["material"], "damping_global": damping}) for s in scenes]
        return [Outcome.of_result(result) for result in sim.simulate_many(changed)]

    return simulate


def one_run(variant: str, environment: str, mpa: float, seed: int, args) -> float:
    """The best distance after ``args.generations`` generations of one run."""
    config = EvolutionConfig(
        population_size=args.population, seed=seed,
        evaluation=EvaluationSpec(environment, mpa * 1e6, cycles=args.cycles,
                                  encoding=EncodingConfig(workspace=(args.workspace,) * 3)),
    )  # fmt: skip
    simulator = None  # the engine's, as every run's
    if variant == "damping":
        simulator = with_damping(LOW_DAMPING)
    elif variant == "cycles":
        config = replace(config, evaluation=replace(config.evaluation, cycles=2 * args.cycles))
    elif variant == "frequency":
        config = replace(config, evaluation=replace(config.evaluation, encoding=replace(
            config.encoding, frequency_range=(1.0, 3.0))))
    evaluate = partial(evaluate_generation, simulator=simulator)
    return best_distance(run(config, evaluate, args.generations))


def trend(means: list[float]) -> str:
    return "rises" if means[-1] > means[0] else "falls"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--stiffness", default="0.001,0.1,10", help="MPa, comma-separated")
    parser.add_argument("--repetitions", type=int, default=3)
    parser.add_argument("--generations", type=int, default=10)
    parser.add_argument("--population", type=int, default=8)
    parser.add_argument("--workspace", type=int, default=6)
    parser.add_argument("--cycles", type=int, default=8)
    parser.add_argument("--variants", default=",".join(VARIANTS))
    parser.add_argument("--csv", default=None, help="write one row per run here")
    args = parser.parse_args(argv)
    try:
        stiffnesses = [float(x) for x in args.stiffness.split(",") if x]
    except ValueError:
        print(f"error: --stiffness takes MPa values separated by commas (got {args.stiffness!r})",
              file=sys.stderr)
        return 2
    variants = [v for v in args.variants.split(",") if v]
    unknown = [v for v in variants if v not in VARIANTS]
    if unknown or not stiffnesses or args.repetitions < 1 or args.generations < 1:
        print(f"error: variants are {', '.join(VARIANTS)}; stiffness, repetitions and "
              "generations must be given", file=sys.stderr)
        return 2
    rows, started = [], time.monotonic()
    total = len(variants) * 2 * len(stiffnesses) * args.repetitions
    for variant in variants:
        for environment in environments.PAPER:
            for mpa in stiffnesses:
                for seed in range(args.repetitions):
                    d = one_run(variant, environment, mpa, seed, args)
                    rows.append({"variant": variant, "environment": environment,
                                 "stiffness_mpa": mpa, "seed": seed, "best_distance": d})
                    print(f"[{len(rows)}/{total}, {time.monotonic() - started:.0f} s] {variant} "
                          f"{environment} {mpa:g} MPa seed {seed}: {d:.3f}", file=sys.stderr)
    if args.csv:
        with open(args.csv, "w", newline="") as out:
            writer = csv.DictWriter(out, fieldnames=list(rows[0]))
            writer.writeheader()
            writer.writerows(rows)
    print(f"best distance (voxel lengths), mean of {args.repetitions} runs, after "
          f"{args.generations} generations; wall time {time.monotonic() - started:.0f} s")
    print("| variant | world | " + " | ".join(f"{m:g} MPa" for m in stiffnesses)
          + " | best stiffness | S-first to S-last |")
    print("| --- | --- | " + " | ".join("---:" for _ in stiffnesses) + " | --- | --- |")
    for variant in variants:
        for environment in environments.PAPER:
            means = []
            for mpa in stiffnesses:
                values = [r["best_distance"] for r in rows if r["variant"] == variant
                          and r["environment"] == environment and r["stiffness_mpa"] == mpa]
                means.append(sum(values) / len(values))
            best = stiffnesses[means.index(max(means))]
            print(f"| {variant} | {environment} | " + " | ".join(f"{m:.2f}" for m in means)
                  + f" | {best:g} MPa | {trend(means)} |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
