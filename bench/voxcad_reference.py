"""The paper's own engine as a reference: the VoxCAD fork shipped with evosoro, built from source.

Usage:
  python bench/voxcad_reference.py [--evosoro PATH] [--build DIR] [--out DIR]   # reference data
  python bench/voxcad_reference.py --speed [--speed-seconds S]                  # timing only
  python bench/voxcad_reference.py --check-main 2                               # + stock binary

``PATH`` is the evosoro repository (skriegman/evosoro, commit b95ec95): its git directory (the
default is the fetched mirror /work/.mirror/skriegman+evosoro/repo) or a checkout / unpacked
copy. The fork's sources (``evosoro/_voxcad_land_water``: Voxelyze/, voxelyzeMain/,
sample_vxa/; prebuilt .a/.o/.d files and the shipped binary are left behind) are copied into
``--build`` and built there: ``make`` in Voxelyze/ gives libvoxelyze.0.9.a, then
voxelyzeMain/main.cpp is linked into ``voxelyze`` and ``bench/voxcad/driver.cpp`` into
``voxcad-driver``. The shipped Makefile's compile rule uses an unset $(CXXFLAGS), so a plain
``make`` builds without optimisation; this script passes ``CXXFLAGS="-O3 -std=c++11"`` (the
physics is the same, bit for bit, at either level: x86-64 without -march uses no FMA).

Reference cases (``--out``, default tests/sim/reference/voxcad/; one JSON file each plus
index.json; see the README.md there):
- the 8 sample robots of the fork (``sample_vxa/*.vxa``), run as shipped (12-20 s each);
- random CPPN robots of softevo's own encoding (softevo.evolution.genotype, fixed seeds) in a
  5x5x5 workspace at S1..S5 = 1e3..1e7 Pa, land and water, self-collisions on and off (the
  same body for the on/off pair), 5 actuation cycles (after 0.5 s of settling on land);
- four 6x6x6 robots with an evolved per-voxel stiffness (the fork's <Stiffness> block), land
  and water, collisions on.
Each is run by the driver (the fork's own stepping, as main.cpp): dt, the fitness-file
values, the centre of mass and 5 voxels every 20 steps for the first 400 steps, and the
centre of mass at ~60 instants over the whole run.

``--speed`` times the fork on the sample robots (one process at a time, one core: the fork
has no threads): wall time per evaluation, evaluations/s and voxel-steps/s, for the -O3
build and for the build as the shipped Makefiles make it (-O0 library, -g main).
"""

from __future__ import annotations

import argparse
import json
import os
import re
import shutil
import statistics
import subprocess
import sys
import time
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np

from softevo.evolution.environments import LAND, PAPER, WATER

REPO = Path(__file__).resolve().parents[1]
DRIVER = Path(__file__).with_name("voxcad") / "driver.cpp"
MIRROR = Path("/work/.mirror/skriegman+evosoro/repo")
FORK = "evosoro/_voxcad_land_water"
PARTS = ("Voxelyze/", "voxelyzeMain/", "sample_vxa/")
OUT = REPO / "tests" / "sim" / "reference" / "voxcad"
STIFFNESS = {"S1": 1e3, "S2": 1e4, "S3": 1e5, "S4": 1e6, "S5": 1e7}  # Pa
EVERY, FRAMES, COARSE_POINTS = 20, 400, 60
CYCLES = 5  # actuation cycles of the CPPN robots (after 0.5 s of settling on land)


# --------------------------------------------------------------------------- source and build


def _skip(rel: str) -> bool:
    return rel.endswith((".a", ".o", ".d")) or rel == "voxelyzeMain/voxelyze"


def copy_source(evosoro: Path, dest: Path) -> str:
    """Copy the fork's Voxelyze/, voxelyzeMain/, sample_vxa/ into ``dest``; returns the commit
    (or "unknown" for a plain directory)."""
    if dest.exists():
        shutil.rmtree(dest)
    dest.mkdir(parents=True)
    git = ["git", "--git-dir", str(evosoro)]
    probe = subprocess.run(git + ["rev-parse", "HEAD"], capture_output=True, text=True)
    if probe.returncode == 0 and not (evosoro / FORK).exists():
        commit = probe.stdout.strip()
        listing = (
            subprocess.run(git + ["ls-tree", "-r", "-z", "HEAD", FORK], capture_output=True, check=True)
            .stdout.decode()
            .split("\0")
        )
        for entry in filter(None, listing):
            meta, path = entry.split("\t", 1)
            rel = path[len(FORK) + 1 :]
            if not rel.startswith(PARTS) or _skip(rel):
                continue
            blob = subprocess.run(git + ["cat-file", "blob", meta.split()[2]], capture_output=True)
            if blob.returncode != 0:
                sys.exit(f"error: {path} is missing from {evosoro}")
            target = dest / rel
            target.parent.mkdir(parents=True, exist_ok=True)
            target.write_bytes(blob.stdout)
        return commit
    for root in (evosoro / FORK, evosoro / "_voxcad_land_water", evosoro):
        if (root / "Voxelyze" / "VX_Sim.cpp").exists():
            break
    else:
        sys.exit(f"error: no {FORK} under {evosoro}")
    for part in PARTS:
        for src in (root / part).rglob("*"):
            rel = src.relative_to(root).as_posix()
            if src.is_file() and not _skip(rel):
                (dest / rel).parent.mkdir(parents=True, exist_ok=True)
                shutil.copy2(src, dest / rel)
    head = subprocess.run(["git", "-C", str(root), "rev-parse", "HEAD"], capture_output=True, text=True)
    return head.stdout.strip() if head.returncode == 0 else "unknown"


def build(
    evosoro: Path, out: Path, flags: str = "-O3", main_flags: str = "-O3", rebuild: bool = False
) -> dict:
    """Build the fork under ``out``: {"src", "voxelyze", "driver", "commit"} (cached)."""
    stamp = out / "build.json"
    if stamp.exists() and not rebuild:
        info = json.loads(stamp.read_text())
        driver = Path(info["driver"])
        if (
            info.get("flags") == [flags, main_flags]
            and driver.exists()
            and driver.stat().st_mtime > DRIVER.stat().st_mtime
        ):
            return info
    src = out / "src"
    print(f"copying the fork from {evosoro} into {src} ...", flush=True)
    commit = copy_source(evosoro, src)
    jobs = str(max(1, os.cpu_count() or 1))
    print(f"building libvoxelyze.0.9.a (make CXXFLAGS='{flags} -std=c++11 -w') ...", flush=True)
    subprocess.run(
        ["make", "-C", str(src / "Voxelyze"), "-j", jobs, f"CXXFLAGS={flags} -std=c++11 -w"],
        check=True,
        stdout=subprocess.DEVNULL,
    )
    lib = src / "Voxelyze" / "libvoxelyze.0.9.a"
    inc = ["-I", str(src / "Voxelyze"), "-I", str(src / "Voxelyze" / "Utils")]
    voxelyze = src / "voxelyzeMain" / "voxelyze"
    subprocess.run(
        [
            "g++",
            *main_flags.split(),
            "-std=c++11",
            "-w",
            *inc,
            str(src / "voxelyzeMain" / "main.cpp"),
            str(lib),
            "-lz",
            "-o",
            str(voxelyze),
        ],
        check=True,
    )
    driver = out / "voxcad-driver"
    subprocess.run(
        [
            "g++",
            *main_flags.split(),
            "-std=c++11",
            "-w",
            *inc,
            str(DRIVER),
            str(lib),
            "-lz",
            "-o",
            str(driver),
        ],
        check=True,
    )
    info = {
        "src": str(src),
        "voxelyze": str(voxelyze),
        "driver": str(driver),
        "commit": commit,
        "flags": [flags, main_flags],
    }
    stamp.write_text(json.dumps(info, indent=1))
    return info


# --------------------------------------------------------------------------- VXA files


def _g(value: float) -> str:
    return f"{float(value):.10g}"


def _material(mid: int, name: str, rgb: tuple, e: float, cte: float, density: float, poisson: float) -> str:
    return f"""<Material ID="{mid}">
<MatType>0</MatType>
<Name>{name}</Name>
<Display>
<Red>{rgb[0]}</Red>
<Green>{rgb[1]}</Green>
<Blue>{rgb[2]}</Blue>
<Alpha>1</Alpha>
</Display>
<Mechanical>
<MatModel>0</MatModel>
<Elastic_Mod>{_g(e)}</Elastic_Mod>
<Plastic_Mod>0</Plastic_Mod>
<Yield_Stress>0</Yield_Stress>
<FailModel>0</FailModel>
<Fail_Stress>0</Fail_Stress>
<Fail_Strain>0</Fail_Strain>
<Density>{_g(density)}</Density>
<Poissons_Ratio>{_g(poisson)}</Poissons_Ratio>
<CTE>{_g(cte)}</CTE>
<uStatic>1</uStatic>
<uDynamic>0.5</uDynamic>
</Mechanical>
</Material>
"""


def _layers(values: np.ndarray, fmt) -> list[str]:
    """One string per z layer, x fastest then y (the fork's index x + X y + X Y z)."""
    return [fmt(values[:, :, z].ravel(order="F")) for z in range(values.shape[2])]


def make_vxa(
    body: np.ndarray,
    phase_cycles: np.ndarray,
    period: float,
    youngs: float,
    water: bool,
    collisions: bool,
    stop_time: float,
    stiffness: np.ndarray | None = None,
    voxel_size: float = 0.05,
    density: float = 1200.0,
    poisson: float = 0.4,
) -> str:
    """A VXA in the layout of the fork's sample files, with only tags the fork reads.

    body[x, y, z]: 0 empty, 1 passive (material 1), 2 active (material 3, CTE +0.01).
    Materials 2 (passive, 100 E) and 4 (active, CTE -0.01) are in the palette, unused, as in
    the samples. phase_cycles: the fork's phaseOffset (cycles, sin(2 pi (t / T + phase))).
    """
    digits = np.where(body == 2, 3, body).astype(int)
    data = _layers(digits, lambda row: "".join(str(v) for v in row))
    phases = _layers(np.where(body > 0, phase_cycles, 0.0), lambda row: "".join(f"{_g(v)}, " for v in row))
    nx, ny, nz = body.shape
    palette = (
        _material(1, "Passive_Soft", (0, 1, 1), youngs, 0, density, poisson)
        + _material(2, "Passive_Hard", (0, 0, 1), 100 * youngs, 0, density, poisson)
        + _material(3, "Active_+", (1, 0, 0), youngs, 0.01, density, poisson)
        + _material(4, "Active_-", (0, 1, 0), youngs, -0.01, density, poisson)
    )
    layer = "\n".join(f"<Layer><![CDATA[{row}]]></Layer>" for row in data)
    phase = "\n".join(f"<Layer><![CDATA[{row}]]></Layer>" for row in phases)
    extra = ""
    if stiffness is not None:
        rows = _layers(np.where(body > 0, stiffness, 0.0), lambda row: "".join(f"{_g(v)}, " for v in row))
        extra = (
            "<Stiffness>\n<MinElasticMod>1000.0</MinElasticMod>\n<MaxElasticMod>10000000.0</MaxElasticMod>\n"
            + "\n".join(f"<Layer><![CDATA[{row}]]></Layer>" for row in rows)
            + "\n</Stiffness>\n"
        )
    return f"""<?xml version="1.0" encoding="ISO-8859-1"?>
<VXA Version="1.0">
<Simulator>
<Integration>
<Integrator>0</Integrator>
<DtFrac>0.7</DtFrac>
</Integration>
<Damping>
<BondDampingZ>1</BondDampingZ>
<ColDampingZ>0.8</ColDampingZ>
<SlowDampingZ>0.01</SlowDampingZ>
</Damping>
<Collisions>
<SelfColEnabled>{int(collisions)}</SelfColEnabled>
<ColSystem>3</ColSystem>
<CollisionHorizon>2</CollisionHorizon>
</Collisions>
<StopCondition>
<StopConditionType>2</StopConditionType>
<StopConditionValue>{_g(stop_time)}</StopConditionValue>
<InitCmTime>{0.0 if water else 0.5}</InitCmTime>
</StopCondition>
<GA>
<WriteFitnessFile>1</WriteFitnessFile>
<FitnessFileName>softbotsOutput.xml</FitnessFileName>
<QhullTmpFile>tempFiles/qhullInput.txt</QhullTmpFile>
<CurvaturesTmpFile>tempFiles/curvatures.txt</CurvaturesTmpFile>
</GA>
</Simulator>
<Environment>
<FluidEnvironment>{int(water)}</FluidEnvironment>
<AggregateDragCoefficient>750.0</AggregateDragCoefficient>
<Fixed_Regions>
<NumFixed>0</NumFixed>
</Fixed_Regions>
<Forced_Regions>
<NumForced>0</NumForced>
</Forced_Regions>
<Gravity>
<GravEnabled>1</GravEnabled>
<GravAcc>-9.81</GravAcc>
<FloorEnabled>1</FloorEnabled>
</Gravity>
<Thermal>
<TempEnabled>1</TempEnabled>
<TempAmp>39</TempAmp>
<TempBase>25</TempBase>
<VaryTempEnabled>1</VaryTempEnabled>
<TempPeriod>{_g(period)}</TempPeriod>
</Thermal>
</Environment>
<VXC Version="0.93">
<Lattice>
<Lattice_Dim>{_g(voxel_size)}</Lattice_Dim>
<X_Dim_Adj>1</X_Dim_Adj>
<Y_Dim_Adj>1</Y_Dim_Adj>
<Z_Dim_Adj>1</Z_Dim_Adj>
<X_Line_Offset>0</X_Line_Offset>
<Y_Line_Offset>0</Y_Line_Offset>
<X_Layer_Offset>0</X_Layer_Offset>
<Y_Layer_Offset>0</Y_Layer_Offset>
</Lattice>
<Voxel>
<Vox_Name>BOX</Vox_Name>
<X_Squeeze>1</X_Squeeze>
<Y_Squeeze>1</Y_Squeeze>
<Z_Squeeze>1</Z_Squeeze>
</Voxel>
<Palette>
{palette}</Palette>
<Structure Compression="ASCII_READABLE">
<X_Voxels>{nx}</X_Voxels>
<Y_Voxels>{ny}</Y_Voxels>
<Z_Voxels>{nz}</Z_Voxels>
<Data>
{layer}
</Data>
<PhaseOffset>
{phase}
</PhaseOffset>
{extra}</Structure>
</VXC>
</VXA>
"""


def cppn_robot(seed: int, workspace: tuple[int, int, int], evolve_stiffness: bool = False):
    """A random robot of softevo's encoding: the first seed >= ``seed`` giving >= 40% of the
    workspace full with at least 20% active voxels. Returns (seed, phenotype)."""
    from softevo.evolution.genotype import EncodingConfig, develop, random_viable_genotype

    config = EncodingConfig(workspace=workspace, evolve_stiffness=evolve_stiffness)
    volume = int(np.prod(workspace))
    for s in range(seed, seed + 1000):
        pheno = develop(random_viable_genotype(np.random.default_rng(s), config), config)
        if pheno.voxel_count >= 0.4 * volume and 0.2 <= pheno.active_share <= 0.8:
            return s, pheno
    raise RuntimeError(f"no suitable robot from seed {seed}")


def cases(src: Path) -> list[dict]:
    """All reference cases: {"name", "group", "vxa", "notes"}."""
    out = []
    for path in sorted((src / "sample_vxa").glob("*.vxa")):
        out.append(
            {
                "name": f"sample_{path.stem}",
                "group": "sample",
                "vxa": path.read_text(encoding="latin-1"),
                "notes": f"the fork's sample_vxa/{path.name}, unchanged",
            }
        )
    seed = 100
    for level, youngs in STIFFNESS.items():
        for env in PAPER:
            seed, pheno = cppn_robot(seed, (5, 5, 5))
            cycles = CYCLES
            period = 1.0 / pheno.frequency
            stop = cycles * period + (0.0 if env == WATER.name else 0.5)
            for collisions in (True, False):
                vxa = make_vxa(
                    pheno.body, pheno.phase / (2 * np.pi), period, youngs, env == WATER.name, collisions, stop
                )
                out.append(
                    {
                        "name": f"cppn_{level}_{env}_{'col' if collisions else 'nocol'}",
                        "group": "cppn",
                        "vxa": vxa,
                        "robot": {
                            "seed": seed,
                            "workspace": [5, 5, 5],
                            "frequency": pheno.frequency,
                            "cycles": cycles,
                            "youngs_modulus": youngs,
                            "environment": env,
                            "self_collisions": collisions,
                        },
                        "notes": f"softevo random_viable_genotype(default_rng({seed})), 5x5x5, {level}",
                    }
                )
            seed += 1
    for k, env in enumerate(PAPER * 2):
        seed, pheno = cppn_robot(500 + 10 * k, (6, 6, 6), evolve_stiffness=True)
        period = 1.0 / pheno.frequency
        stop = CYCLES * period + (0.0 if env == WATER.name else 0.5)
        vxa = make_vxa(
            pheno.body,
            pheno.phase / (2 * np.pi),
            period,
            1e5,
            env == WATER.name,
            True,
            stop,
            stiffness=pheno.stiffness,
        )
        out.append(
            {
                "name": f"cppn_field{k // 2 + 1}_{env}_col",
                "group": "cppn-stiffness-field",
                "vxa": vxa,
                "robot": {
                    "seed": seed,
                    "workspace": [6, 6, 6],
                    "frequency": pheno.frequency,
                    "cycles": CYCLES,
                    "youngs_modulus": "field",
                    "environment": env,
                    "self_collisions": True,
                },
                "notes": f"softevo random_viable_genotype(default_rng({seed})) with evolve_stiffness, "
                "6x6x6, per-voxel E 1e3..1e7 Pa in <Stiffness>",
            }
        )
    return out


# --------------------------------------------------------------------------- running


def stop_time(vxa: str) -> float:
    return float(re.search(r"<StopConditionValue>([^<]+)<", vxa).group(1))


def run_driver(
    driver: str,
    vxa: str,
    work: Path,
    name: str,
    coarse: int | None = None,
    every: int = EVERY,
    frames: int = FRAMES,
    voxels: str | None = None,
) -> dict:
    """Run one VXA text; the parsed header, frames, coarse COM samples, result, fitness XML."""
    work.mkdir(parents=True, exist_ok=True)
    path, fit = work / f"{name}.vxa", work / f"{name}.fitness.xml"
    path.write_text(vxa, encoding="latin-1")
    args = [driver, str(path), "--fitness", str(fit)]
    if every:
        args += ["--every", str(every), "--frames", str(frames)]
    if voxels:
        args += ["--voxels", voxels]
    if coarse:
        args += ["--coarse", str(coarse)]
    start = time.perf_counter()
    proc = subprocess.run(args, capture_output=True, text=True)
    wall = time.perf_counter() - start
    if proc.returncode not in (0, 1):
        sys.exit(f"error: driver failed on {name}: {proc.stderr}")
    lines = [json.loads(line) for line in proc.stdout.splitlines() if line.startswith("{")]
    out = {
        "header": lines[0],
        "frames": [x for x in lines if x["kind"] == "frame"],
        "coarse": [x for x in lines if x["kind"] == "com"],
        "result": lines[-1],
        "process_seconds": wall,
    }
    # the convex-hull and shape-complexity entries are left out: main.cpp's qhull / python
    # measurements are not run (they do not affect the physics)
    out["fitness_file"] = {
        el.tag: (int(el.text) if el.tag == "VoxelNumber" else float(el.text))
        for el in ET.parse(fit).getroot().find("Fitness")
        if not el.tag.startswith(("ConvexHull", "ShapeComplexity"))
    }
    return out


def tracked(n: int) -> list[int]:
    return sorted({0, n // 4, n // 2, (3 * n) // 4, n - 1})


def r(v, digits: int = 10):
    if isinstance(v, list):
        return [r(x, digits) for x in v]
    return round(float(v), digits)


def reference(args, info: dict) -> None:
    out: Path = args.out
    out.mkdir(parents=True, exist_ok=True)
    work = Path(args.build) / "runs"
    index = []
    total = time.perf_counter()
    for case in cases(Path(info["src"])):
        if args.only and not re.search(args.only, case["name"]):
            continue
        # a first run for the voxel count and the step count, then the recorded run
        first = run_driver(info["driver"], case["vxa"], work, case["name"], every=0)
        n, steps = first["header"]["voxels"], first["result"]["steps"]
        coarse = max(1, steps // COARSE_POINTS)
        run = run_driver(
            info["driver"],
            case["vxa"],
            work,
            case["name"],
            coarse=coarse,
            voxels=",".join(map(str, tracked(n))),
        )
        res, head = run["result"], run["header"]
        assert (
            res["steps"] == steps
            and res["normAbsoluteDisplacement"] == first["result"]["normAbsoluteDisplacement"]
        )
        doc = {
            "name": case["name"],
            "group": case["group"],
            "notes": case["notes"],
            "engine": {
                "source": "skriegman/evosoro " + FORK,
                "commit": info["commit"][:7],
                "build": f"g++ {' '.join(info['flags'])}",
                "driver": "bench/voxcad/driver.cpp",
            },
            "robot": case.get("robot"),
            "vxa": case["vxa"],
            "voxcad": {
                "voxels": n,
                "bonds": head["bonds"],
                "surface_voxels": head["surface_voxels"],
                "lattice_dim": head["lattice_dim"],
                "dt": head["dt"],
                "optimal_dt": head["optimal_dt"],
                "dt_frac": head["dt_frac"],
                "steps": steps,
                "t_end": r(res["t"], 12),
                "stable": res["stable"],
                "fitness": {
                    k: r(res[k])
                    for k in (
                        "normAbsoluteDisplacement",
                        "normDistX",
                        "normDistY",
                        "normDistZ",
                        "RobotVolumeStart",
                        "RobotVolumeEnd",
                    )
                },
                "fitness_file": run["fitness_file"],
                "ini_cm": r(res["ini_cm"]),
                "final_cm": r(res["final_cm"]),
                "ijk": head["ijk"],
                "tracked": head["tracked"],
                "frames": {
                    "step": [f["step"] for f in run["frames"]],
                    "t": [r(f["t"], 12) for f in run["frames"]],
                    "com": [r(f["com"]) for f in run["frames"]],
                    "positions": [r(f["pos"]) for f in run["frames"]],
                },
                "coarse": {
                    "step": [c["step"] for c in run["coarse"]],
                    "t": [r(c["t"], 9) for c in run["coarse"]],
                    "com": [r(c["com"], 8) for c in run["coarse"]],
                },
                "seconds": round(res["seconds"], 3),
            },
        }
        (out / f"{case['name']}.json").write_text(json.dumps(doc, separators=(",", ":")) + "\n")
        fit = doc["voxcad"]["fitness"]["normAbsoluteDisplacement"]
        index.append(
            {
                "name": case["name"],
                "group": case["group"],
                "voxels": n,
                "dt": head["dt"],
                "steps": steps,
                "t_end": r(res["t"], 9),
                "normAbsoluteDisplacement": fit,
                "fitness_file_normAbsoluteDisplacement": run["fitness_file"]["normAbsoluteDisplacement"],
                "stable": res["stable"],
                "seconds": round(res["seconds"], 3),
            }
        )
        print(
            f"{case['name']:<42}{n:>5} vox  dt {head['dt']:.4e}  {steps:>7} steps  "
            f"normAbsDisp {fit:9.5f}  {res['seconds']:6.2f} s",
            flush=True,
        )
    if not args.only:
        (out / "index.json").write_text(
            json.dumps({"engine_commit": info["commit"][:7], "cases": index}, indent=1) + "\n"
        )
    print(f"total {time.perf_counter() - total:.1f} s; written to {out}")


def check_main(info: dict, count: int, work: Path) -> None:
    """Run the stock voxelyzeMain binary (``voxelyze -f``) on the first ``count`` cases (short
    versions of the samples) and compare its fitness file with the driver's."""
    if not shutil.which("qhull"):
        print("note: qhull is not installed; the stock binary retries it for a minute per call")
    picked = cases(Path(info["src"]))[:count]
    for case in picked:
        vxa = re.sub(r"<StopConditionValue>[^<]+<", "<StopConditionValue>2.0<", case["vxa"])
        d = work / "main" / case["name"]
        (d / "fitnessFiles").mkdir(parents=True, exist_ok=True)
        (d / "tempFiles").mkdir(parents=True, exist_ok=True)
        vxa = re.sub(r"<FitnessFileName>[^<]+<", "<FitnessFileName>fitnessFiles/out.xml<", vxa)
        vxa = re.sub(r"<QhullTmpFile>[^<]+<", f"<QhullTmpFile>{d}/tempFiles/qhull.txt<", vxa)
        vxa = re.sub(r"<CurvaturesTmpFile>[^<]+<", f"<CurvaturesTmpFile>{d}/tempFiles/curv.txt<", vxa)
        (d / "in.vxa").write_text(vxa, encoding="latin-1")
        subprocess.run([info["voxelyze"], "-f", "in.vxa"], cwd=d, capture_output=True, timeout=900)
        stock = {el.tag: el.text for el in ET.parse(d / "fitnessFiles" / "out.xml").getroot().find("Fitness")}
        ours = run_driver(info["driver"], vxa, work, case["name"] + "_check", every=0)["fitness_file"]
        same = all(
            float(stock[k]) == ours[k]
            for k in ("normAbsoluteDisplacement", "normDistX", "normDistY", "normDistZ")
        )
        print(
            f"{case['name']:<40} stock voxelyze {stock['normAbsoluteDisplacement']:>10}  driver "
            f"{ours['normAbsoluteDisplacement']:<10} {'identical' if same else 'DIFFERENT'}",
            flush=True,
        )


def speed(args, infos: dict[str, dict]) -> None:
    """Wall time per evaluation of the sample robots, one process at a time."""
    print(
        f"{'build':<10}{'robot':<34}{'env':<7}{'vox':>5}{'steps':>8}{'sim s':>7}{'wall s':>8}"
        f"{'eval/s':>8}{'Mvox-step/s':>13}"
    )
    for label, info in infos.items():
        rows = {name: [] for name in PAPER}
        for case in cases(Path(info["src"]))[:8]:
            vxa = case["vxa"]
            if args.speed_seconds:
                vxa = re.sub(r"<StopConditionValue>[^<]+<", f"<StopConditionValue>{args.speed_seconds}<", vxa)
            env = WATER.name if "<FluidEnvironment>1<" in vxa else LAND.name
            best = None
            for _ in range(args.repeat):
                run = run_driver(info["driver"], vxa, Path(args.build) / "speed", case["name"], every=0)
                if best is None or run["process_seconds"] < best["process_seconds"]:
                    best = run
            res = best["result"]
            vps = res["voxels"] * res["steps"] / res["seconds"]
            rows[env].append((best["process_seconds"], vps))
            print(
                f"{label:<10}{case['name'][7:]:<34}{env:<7}{res['voxels']:>5}{res['steps']:>8}"
                f"{res['t']:>7.2f}{best['process_seconds']:>8.3f}{1 / best['process_seconds']:>8.3f}"
                f"{vps / 1e6:>13.3f}",
                flush=True,
            )
        for env, values in rows.items():
            walls, vpss = zip(*values, strict=True)
            print(
                f"{label:<10}{'mean of the ' + env + ' samples':<41}{'':>13}{statistics.mean(walls):>8.3f}"
                f"{1 / statistics.mean(walls):>8.3f}{statistics.mean(vpss) / 1e6:>13.3f}"
            )


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--evosoro", type=Path, default=MIRROR, help="evosoro git dir or checkout")
    parser.add_argument("--build", type=Path, default=Path("/tmp/voxcad-build"), help="scratch build folder")
    parser.add_argument("--out", type=Path, default=OUT, help="where the reference JSON goes")
    parser.add_argument("--only", help="regex: run only the matching cases (no index.json)")
    parser.add_argument("--rebuild", action="store_true")
    parser.add_argument("--speed", action="store_true", help="time the fork on the sample robots instead")
    parser.add_argument(
        "--speed-seconds", type=float, help="simulated seconds per sample run (default: as shipped)"
    )
    parser.add_argument("--repeat", type=int, default=1, help="runs per robot in --speed (best kept)")
    parser.add_argument(
        "--check-main",
        type=int,
        default=0,
        metavar="N",
        help="also compare the stock voxelyze binary with the driver on N cases",
    )
    args = parser.parse_args()
    info = build(args.evosoro, args.build / "O3", rebuild=args.rebuild)
    if args.speed:
        shipped = build(args.evosoro, args.build / "shipped", flags="", main_flags="-g", rebuild=args.rebuild)
        speed(args, {"-O3": info, "shipped": shipped})
        return
    if args.check_main:
        check_main(info, args.check_main, args.build)
    reference(args, info)


if __name__ == "__main__":
    main()
