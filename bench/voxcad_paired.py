"""softevo against the paper's engine (the VoxCAD fork in evosoro), paired on the same VXA robots.

Usage: python bench/voxcad_paired.py [--repeat 3] [--seconds S] [--only REGEX] [--profile]
       [--precision float64|mixed] [--holdout SEED]

The robots are the fork's 8 sample robots (their VXA text in tests/sim/reference/voxcad/
sample_*.json), each in its own world (4 on land, 4 in water), self-collisions on, as shipped
(12-20 simulated seconds; ``--seconds S`` stops each at S simulated seconds instead, the same
cut VXA for both engines). ``--holdout SEED``: robots no test has run instead, a variant of
each sample (``held_out``: materials changed, voxels emptied, phases shuffled). The fork is
built from source by ``bench/voxcad_reference.py`` (``g++ -O3``, cached in ``--build``/O3)
and run by its driver (``bench/voxcad/driver.cpp``:
the fork's own stepping loop, as voxelyzeMain/main.cpp). softevo runs the same VXA through the
importer (``analysis.vxa_import.vxa_to_scene``: model ``voxcad-land-water``) with
``sim.simulate(scene, threads=1)``, after a warm-up run of the same scene that compiles (or
loads) the numba kernels. Both engines are single-threaded; the runs alternate (fork, then
softevo), ``--repeat`` pairs per robot, and the ratio is taken pair by pair because the
host's speed drifts. Timings: the fork's stepping loop as its driver reports it ("loop") and
the driver's whole process (load, import, mesh, stepping: "process"); softevo's whole
``simulate`` call (scene parse, robot build, stepping). Both take the same number of steps
(the same dt, from the same DtFrac and OptimalDt): printed for each.

``--profile`` also says where the time goes:
- the fork: each robot run under ``valgrind --tool=callgrind`` for ``--profile-seconds``
  (0.3 s by default; callgrind counts instructions, so the host's load does not matter), the
  instructions inside its step (``CVX_Sim::TimeStep``) grouped by the fork's functions (bond
  update, voxel Euler step, collision lists, mesh / drag, stats, temperature, other); libm
  calls go with their caller. Then the
  wall time of the whole run with SelfColEnabled 0 against 1: what self-collisions cost it
  (callgrind's short run is mostly before any contact).
- softevo: the same robot run as imported, with ``self_collisions`` off, and in water with
  ``model_options.drag`` "faces" (drag on each voxel's own exposed faces) instead of "mesh"
  (the fork's deformed-mesh drag); the differences are the cost of those parts.
"""

from __future__ import annotations

import argparse
import copy
import importlib.util
import json
import re
import shutil
import statistics
import subprocess
import sys
import time
from collections import defaultdict
from pathlib import Path

from softevo.evolution.environments import LAND, WATER

BENCH = Path(__file__).resolve().parent
REFERENCE = BENCH.parent / "tests" / "sim" / "reference" / "voxcad"


def _reference_module():
    """bench/voxcad_reference.py (the fork's build and driver helpers), imported by path."""
    spec = importlib.util.spec_from_file_location("voxcad_reference", BENCH / "voxcad_reference.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


ref = _reference_module()


def samples(only: str | None) -> list[dict]:
    """The 8 sample robots: {"name", "vxa", "world"}."""
    out = []
    for path in sorted(REFERENCE.glob("sample_*.json")):
        doc = json.loads(path.read_text())
        if only and not re.search(only, doc["name"]):
            continue
        vxa = doc["vxa"]
        world = WATER.name if "<FluidEnvironment>1<" in vxa else LAND.name
        out.append({"name": doc["name"][len("sample_") :], "vxa": vxa, "world": world})
    if not out:
        sys.exit(f"error: no sample robots under {REFERENCE} (--only {only!r})")
    return out


def held_out(robot: dict, seed: int) -> dict:
    """A variant of a sample robot that no test or bench has run: with the generator of
    ``seed`` (and the robot's name), a tenth of its filled voxels take another of the robot's
    materials, a twentieth are emptied (each only if the body stays in one piece, so that
    both engines simulate every voxel), and its phase offsets are shuffled within each layer.
    The world, size, stopping time and the fork's settings stay the sample's."""
    import random

    import numpy as np
    from scipy import ndimage

    rng = random.Random(f"{seed}:{robot['name']}")
    vxa = robot["vxa"]
    start, end = vxa.index("<Data>"), vxa.index("</Data>")
    cdata = re.compile(r"<!\[CDATA\[(.*?)\]\]>")
    layers = [list(layer) for layer in cdata.findall(vxa[start:end])]
    materials = sorted({c for layer in layers for c in layer} - {"0"})
    shape = (
        len(layers),
        int(re.search(r"<Y_Voxels>(\d+)<", vxa)[1]),
        int(re.search(r"<X_Voxels>(\d+)<", vxa)[1]),
    )
    for layer in layers:
        for k, c in enumerate(layer):
            if c == "0":
                continue
            u = rng.random()
            if u < 0.05:
                layer[k] = "0"
                if ndimage.label((np.array(layers) != "0").reshape(shape))[1] != 1:
                    layer[k] = c  # it would split the body
            elif u < 0.15 and len(materials) > 1:
                layer[k] = rng.choice([m for m in materials if m != c])
    rows = iter(layers)
    vxa = vxa[:start] + cdata.sub(lambda m: f"<![CDATA[{''.join(next(rows))}]]>", vxa[start:end]) + vxa[end:]
    if "<PhaseOffset>" in vxa:
        start, end = vxa.index("<PhaseOffset>"), vxa.index("</PhaseOffset>")

        def shuffled(m: re.Match) -> str:
            items = [v.strip() for v in m.group(1).split(",") if v.strip()]
            rng.shuffle(items)
            return f"<![CDATA[{', '.join(items)}, ]]>"

        vxa = vxa[:start] + cdata.sub(shuffled, vxa[start:end]) + vxa[end:]
    return {**robot, "name": f"{robot['name']}~{seed}", "vxa": vxa}


def cut(vxa: str, seconds: float | None) -> str:
    """The VXA stopping at ``seconds`` simulated seconds (when earlier than it stops)."""
    if seconds is None or seconds >= ref.stop_time(vxa):
        return vxa
    return re.sub(r"<StopConditionValue>[^<]+<", f"<StopConditionValue>{seconds!r}<", vxa)


def tag(vxa: str, name: str, value: str) -> str:
    return re.sub(rf"<{name}>[^<]*<", f"<{name}>{value}<", vxa)


# --------------------------------------------------------------------------- the two engines


def run_fork(driver: str, vxa: str, work: Path, name: str) -> dict:
    """One fork run: steps, voxels, dt, loop seconds, process seconds."""
    run = ref.run_driver(driver, vxa, work, name, every=0)
    res = run["result"]
    if not res["stable"]:
        sys.exit(f"error: the fork found {name} unstable")
    return {
        "steps": res["steps"],
        "voxels": res["voxels"],
        "dt": res["dt"],
        "loop": res["seconds"],
        "process": run["process_seconds"],
    }


def scene_of(vxa: str, precision: str) -> dict:
    """The VXA imported as a user would, run in ``precision`` (``--precision``)."""
    from softevo.analysis.vxa_import import vxa_to_scene

    scene = vxa_to_scene(vxa.encode("latin-1")).scene
    return {**scene, "model_options": {**scene["model_options"], "precision": precision}}


def warm_up(scene: dict) -> None:
    """Compile (or load from the cache) what ``scene`` runs, outside the timing."""
    from softevo import sim

    short = copy.deepcopy(scene)
    short["settle_seconds"] = min(scene.get("settle_seconds", 0.0), 0.005)
    short["duration"] = {"seconds": 0.005}
    sim.simulate(short, threads=1)


def run_ours(scene: dict) -> dict:
    from softevo import sim

    start = time.perf_counter()
    r = sim.simulate(scene, threads=1)
    seconds = time.perf_counter() - start
    if not r.stable:
        sys.exit(f"error: softevo found {scene.get('notes')} unstable ({r.reason})")
    return {"steps": r.steps, "voxels": len(r.voxels), "dt": r.dt, "seconds": seconds}


# --------------------------------------------------------------------------- paired timing


def paired(args, driver: str, robots: list[dict]) -> None:
    work = args.build / "paired"
    print(
        f"{args.repeat} pairs per robot (fork, then softevo), one core each; medians, ratios "
        f"pair by pair; {'as shipped' if args.seconds is None else f'{args.seconds:g} s simulated'}; "
        f"softevo in {args.precision}"
    )
    print(
        f"{'robot':<30}{'world':<7}{'vox':>5}{'steps fork':>11}{'ours':>9}{'sim s':>7}"
        f"{'fork eval/s':>12}{'(process)':>10}{'ours eval/s':>12}{'fork Mvs/s':>11}"
        f"{'ours Mvs/s':>11}{'ratio':>7}{'range':>12}{'vs process':>11}"
    )
    rows = defaultdict(list)
    steps_seen = []
    for robot in robots:
        vxa = cut(robot["vxa"], args.seconds)
        scene = scene_of(vxa, args.precision)
        warm_up(scene)
        fork, ours = [], []
        for _ in range(args.repeat):
            fork.append(run_fork(driver, vxa, work, robot["name"]))
            ours.append(run_ours(scene))
        f0, o0 = fork[0], ours[0]
        steps_seen.append((o0, f0))
        if f0["voxels"] != o0["voxels"]:
            print(f"note: {robot['name']}: {f0['voxels']} voxels in the fork, {o0['voxels']} in ours")
        ratio = [f["loop"] / o["seconds"] for f, o in zip(fork, ours, strict=True)]
        ratio_p = [f["process"] / o["seconds"] for f, o in zip(fork, ours, strict=True)]
        loop = statistics.median(f["loop"] for f in fork)
        proc = statistics.median(f["process"] for f in fork)
        mine = statistics.median(o["seconds"] for o in ours)
        row = {
            "fork_eval": 1 / loop,
            "fork_process_eval": 1 / proc,
            "ours_eval": 1 / mine,
            "fork_vs": f0["voxels"] * f0["steps"] / loop,
            "ours_vs": o0["voxels"] * o0["steps"] / mine,
            "ratio": statistics.median(ratio),
            "ratio_process": statistics.median(ratio_p),
        }
        rows[robot["world"]].append(row)
        steps = f"{o0['steps']}" + ("" if o0["steps"] == f0["steps"] else "*")
        print(
            f"{robot['name']:<30}{robot['world']:<7}{f0['voxels']:>5}{f0['steps']:>11}{steps:>9}"
            f"{f0['steps'] * f0['dt']:>7.2f}{row['fork_eval']:>12.3f}{row['fork_process_eval']:>10.3f}"
            f"{row['ours_eval']:>12.3f}{row['fork_vs'] / 1e6:>11.2f}{row['ours_vs'] / 1e6:>11.2f}"
            f"{row['ratio']:>7.2f}{f'{min(ratio):.2f}..{max(ratio):.2f}':>12}"
            f"{row['ratio_process']:>11.2f}",
            flush=True,
        )
        if abs(o0["dt"] / f0["dt"] - 1) > 1e-6:
            print(f"note: dt {f0['dt']:.9g} (fork) vs {o0['dt']:.9g} (ours)")
    if any(o["steps"] != f["steps"] for o, f in steps_seen):
        print(
            "*: a step count of its own (softevo rounds the settling and the rest of the run up "
            "separately, the fork stops once the time passes StopConditionValue)"
        )
    print("medians over the robots of each world:")
    for world, values in rows.items():
        med = {k: statistics.median(v[k] for v in values) for k in values[0]}
        print(
            f"{world + f' ({len(values)} robots)':<67}{med['fork_eval']:>12.3f}"
            f"{med['fork_process_eval']:>10.3f}{med['ours_eval']:>12.3f}{med['fork_vs'] / 1e6:>11.2f}"
            f"{med['ours_vs'] / 1e6:>11.2f}{med['ratio']:>7.2f}{'':>12}{med['ratio_process']:>11.2f}"
        )


# --------------------------------------------------------------------------- profiles

BUCKETS = ("bonds", "voxels", "collisions", "mesh/drag", "stats", "temperature", "other")


def bucket(function: str, water: bool) -> str | None:
    """The part of the fork's step a function (callgrind's name) belongs to; None: a library
    function (it goes with its caller)."""
    if "voxcad-driver" not in function:
        return None
    if (
        "Collision" in function
        or "CalcL1Bonds" in function
        or "CalcNearby" in function
        or "ColBond" in function
    ):
        return "collisions"
    if (
        "CVXS_BondInternal::" in function
        or "CVXS_Bond::" in function
        or "GetModelStress" in function
        or "CalcVoxMatStress" in function
        or "SetStrainDir" in function
    ):
        return "bonds"
    if "CVX_MeshUtil::" in function or "CMesh::" in function:
        return "mesh/drag"
    if "CVX_Sim::Integrate" in function:  # in water, the drag loop over the mesh facets is inline here
        return "mesh/drag" if water else "voxels"
    if "CVXS_Voxel::" in function:
        return "voxels"
    if "UpdateStats" in function:
        return "stats"
    if "Temp" in function:
        return "temperature"
    return "other"


def _bare(function: str) -> str:
    """callgrind's name of a function, without the call count and, for a library function,
    without its source file and object (libm's entries come under several source files)."""
    function = re.sub(r" \([\d,]+x\)", "", function)
    if "voxcad-driver" in function:
        return function
    return re.sub(r" \[.*\]$", "", function).rsplit(":", 1)[-1]


def callgrind_shares(driver: str, vxa: str, work: Path, name: str, water: bool) -> dict[str, float]:
    """Instructions by part of the fork's step (fractions of its stepping, ``CVX_Sim::TimeStep``
    and what it calls: set-up is not counted), from callgrind."""
    work.mkdir(parents=True, exist_ok=True)
    path, out = work / f"{name}.vxa", work / f"{name}.callgrind"
    path.write_text(vxa, encoding="latin-1")
    subprocess.run(
        [
            "valgrind",
            "--tool=callgrind",
            "--toggle-collect=CVX_Sim::TimeStep*",
            f"--callgrind-out-file={out}",
            driver,
            str(path),
        ],
        check=True,
        capture_output=True,
    )
    tree = subprocess.run(
        ["callgrind_annotate", "--tree=caller", "--threshold=100", str(out)],
        check=True,
        capture_output=True,
        text=True,
    ).stdout
    cost = re.compile(r"^\s*([\d,]+) \(\s*[\d.]+%\)\s+(<|\*)\s+(.*)$")
    own: dict[str, int] = {}  # function -> its own instructions
    calls: dict[str, list[tuple[int, str]]] = defaultdict(list)  # function -> (Ir, caller)
    callers: list[tuple[int, str]] = []
    for line in tree.split("file:function", 1)[1].splitlines():
        m = cost.match(line)
        if not m:
            callers = [] if not line.strip() else callers
            continue
        ir, function = int(m.group(1).replace(",", "")), _bare(m.group(3))
        if m.group(2) == "<":
            callers.append((ir, function))
            continue
        own[function] = own.get(function, 0) + ir
        calls[function] += callers
        callers = []

    def part(function: str, seen: frozenset = frozenset()) -> str:
        found = bucket(function, water)
        if found is not None:
            return found
        # a library function: with its heaviest caller (through other library functions)
        for _, caller in sorted(calls.get(function, []), reverse=True):
            if caller not in seen:
                return part(caller, seen | {function})
        return "other"

    totals: dict[str, float] = defaultdict(float)
    for function, ir in own.items():
        totals[part(function)] += ir
    whole = sum(totals.values())
    return {k: totals[k] / whole for k in BUCKETS}


def profile(args, driver: str, robots: list[dict]) -> None:
    work = args.build / "profile"
    print()
    if shutil.which("valgrind") and shutil.which("callgrind_annotate"):
        print(
            f"the fork under callgrind, {args.profile_seconds:g} s simulated: share of the "
            f"instructions of its step (TimeStep)"
        )
        print(f"{'robot':<30}{'world':<7}" + "".join(f"{b:>13}" for b in BUCKETS))
        per_world = defaultdict(list)
        for robot in robots:
            vxa = cut(robot["vxa"], args.profile_seconds)
            shares = callgrind_shares(driver, vxa, work, robot["name"], robot["world"] == WATER.name)
            per_world[robot["world"]].append(shares)
            print(
                f"{robot['name']:<30}{robot['world']:<7}" + "".join(f"{shares[b]:>13.1%}" for b in BUCKETS),
                flush=True,
            )
        for world, values in per_world.items():
            print(
                f"{'median, ' + world:<37}"
                + "".join(f"{statistics.median(v[b] for v in values):>13.1%}" for b in BUCKETS)
            )
    else:
        print("note: valgrind / callgrind_annotate not found: no instruction profile of the fork")

    print()
    length = "as shipped" if args.seconds is None else f"{args.seconds:g} s"
    print(
        f"what the parts cost, whole-run wall time ({length}"
        f", medians of {args.repeat}): the fork with SelfColEnabled 0; softevo with "
        f"self_collisions off and (water) drag 'faces' instead of 'mesh'"
    )
    print(
        f"{'robot':<30}{'world':<7}{'fork s':>8}{'no col':>8}{'col cost':>9}"
        f"{'ours s':>8}{'no col':>8}{'col cost':>9}{'faces':>8}{'mesh cost':>10}"
    )
    for robot in robots:
        vxa = cut(robot["vxa"], args.seconds)
        nocol_vxa = tag(vxa, "SelfColEnabled", "0")
        scene = scene_of(vxa, args.precision)
        nocol = {**scene, "self_collisions": False}
        faces = {**scene, "model_options": {**scene["model_options"], "drag": "faces"}}
        variants = {"ours": scene, "nocol": nocol}
        if robot["world"] == WATER.name:
            variants["faces"] = faces
        for s in variants.values():
            warm_up(s)
        times = defaultdict(list)
        for _ in range(args.repeat):
            times["fork"].append(run_fork(driver, vxa, work, robot["name"])["loop"])
            times["fork_nocol"].append(run_fork(driver, nocol_vxa, work, robot["name"])["loop"])
            for key, s in variants.items():
                times[key].append(run_ours(s)["seconds"])
        t = {k: statistics.median(v) for k, v in times.items()}
        line = (
            f"{robot['name']:<30}{robot['world']:<7}{t['fork']:>8.3f}{t['fork_nocol']:>8.3f}"
            f"{1 - t['fork_nocol'] / t['fork']:>9.1%}{t['ours']:>8.3f}{t['nocol']:>8.3f}"
            f"{1 - t['nocol'] / t['ours']:>9.1%}"
        )
        if "faces" in t:
            line += f"{t['faces']:>8.3f}{1 - t['faces'] / t['ours']:>10.1%}"
        print(line, flush=True)


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--evosoro", type=Path, default=ref.MIRROR, help="evosoro git dir or checkout")
    parser.add_argument(
        "--build", type=Path, default=Path("/tmp/voxcad-build"), help="the fork's build folder"
    )
    parser.add_argument("--repeat", type=int, default=3, help="pairs per robot")
    parser.add_argument("--seconds", type=float, help="simulated seconds per robot (default: as shipped)")
    parser.add_argument("--only", help="regex: only the matching sample robots")
    parser.add_argument(
        "--holdout",
        type=int,
        metavar="SEED",
        help="robots never seen: each sample robot's variant of this seed (``held_out``)",
    )
    parser.add_argument("--profile", action="store_true", help="also say where the time goes")
    parser.add_argument(
        "--precision",
        default="float64",
        choices=("float64", "mixed"),
        help="softevo's arithmetic (model_options.precision; the fork's is float64)",
    )
    parser.add_argument(
        "--profile-seconds", type=float, default=0.3, help="simulated seconds of the fork's callgrind runs"
    )
    parser.add_argument("--no-paired", action="store_true", help="with --profile: the profile only")
    args = parser.parse_args()
    if args.seconds is not None and args.seconds <= 0.5:
        sys.exit("error: --seconds must exceed 0.5 (the land robots settle for 0.5 s)")
    info = ref.build(args.evosoro, args.build / "O3")
    robots = samples(args.only)
    if args.holdout is not None:
        robots = [held_out(robot, args.holdout) for robot in robots]
    if not args.no_paired:
        paired(args, info["driver"], robots)
    if args.profile:
        profile(args, info["driver"], robots)


if __name__ == "__main__":
    main()
