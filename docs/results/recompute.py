"""Recompute docs/results from its export alone and compare: every finding of findings.csv
(test statistic, p, Holm's p and threshold, A12 with its bootstrap interval, the generation-0
test, the adjacent levels' A12s, power, the detectable A12, the runs needed and the verdict's
word), the designs that would decide each finding (designs.csv: `softevo plan`'s figures on
1,000 cores), the sensitivity (sensitivity.csv, from sensitivity/), the pilot's knees, and
every number of README.md, which is README.template.md filled from what this script
computes. Exit status 1 on any difference.

    python docs/results/recompute.py docs/results           # check
    python docs/results/recompute.py docs/results --write   # write designs.csv and README.md

The findings' rules are written here a second time, from the export's three files rather
than from the database (analysis.findings); power, intervals and runs needed call the same
simulation (analysis.design) on the values recomputed here.
"""

from __future__ import annotations

import dataclasses
import difflib
import functools
import math
import sys
from pathlib import Path

import numpy as np
import pandas as pd

from softevo.analysis import design
from softevo.analysis.rank_tests import holm, jonckheere_terpstra, mann_whitney
from softevo.evolution.stats import vargha_delaney as _vargha_delaney

ALPHA, POWER = 0.05, 0.8
DESIGN_CORES = 1_000
TRENDS = (  # (world, metric, verb, levels in the order the hypothesis says values rise)
    ("land", "distance", "rises", ("S2", "S3", "S4", "S5")),
    ("water", "distance", "falls", ("S5", "S4", "S3", "S2", "S1")),
    ("land", "frequency", "falls", ("S5", "S4", "S3", "S2")),
    ("water", "frequency", "rises", ("S1", "S2", "S3", "S4", "S5")),
)
MEASURES = {  # metric: (family, measure, label)
    "distance": (("primary", "best_distance", ""), ("gain", "distance_gain", " (gain)"),
                 ("gain", "distance_log_gain", " (log gain)")),
    "frequency": (("primary", "frequency_change", ""), ("secondary", "frequency", " (secondary)")),
}
GAIN_OF = {"best_distance": "distance_gain", "frequency": "frequency_change"}
CHANGES = ("distance_gain", "distance_log_gain", "frequency_change")
FAMILIES = ("primary", "gain", "secondary")
VERDICTS = ("evolved", "present in random bodies", "not detected", "reversed")
LOW_HZ = 0.5


def vargha_delaney(a, b) -> float:
    """A12, NaN where a side has no run."""
    return _vargha_delaney(a, b) if len(a) and len(b) else math.nan


# ---- the export -------------------------------------------------------------------------------
def load(export: Path):
    runs = pd.read_csv(export / "runs.csv")
    evaluations = pd.read_csv(export / "individuals.csv")
    members = pd.read_csv(export / "populations.csv")
    return runs, evaluations, members


def population_values(runs, evaluations, members) -> pd.DataFrame:
    """Per run and generation: the best distance and mean |frequency| of its population, each
    member read at its latest evaluation up to that generation (a member re-evaluated at a
    switch counts in its new world)."""
    latest = evaluations.sort_values("generation").rename(columns={"generation": "evaluated_at"})
    joined = members.merge(latest, on=["run_id", "individual_id"])
    joined = joined[joined["evaluated_at"] <= joined["generation"]]
    joined = joined.sort_values("evaluated_at").groupby(["run_id", "generation", "individual_id"]).last()
    joined = joined.reset_index()
    joined["frequency"] = joined["frequency"].abs()
    values = joined.groupby(["run_id", "generation"]).agg(distance=("distance", "max"),
                                                         frequency=("frequency", "mean"))
    return values.reset_index().merge(runs[["run_id", "treatment"]], on="run_id")


def level(values, treatment: str, generation: int, metric: str) -> pd.Series:
    rows = values[(values["treatment"] == treatment) & (values["generation"] == generation)]
    return rows.set_index("run_id").sort_index()[metric].astype(float)


def measure(values, treatment: str, generation: int, name: str) -> np.ndarray:
    """One value per run (run order) of measure ``name`` at ``generation``."""
    metric = "distance" if "distance" in name else "frequency"
    final = level(values, treatment, generation, metric)
    if name in CHANGES:
        start = level(values, treatment, 0, metric).reindex(final.index)
        out = np.log(final / start) if name == "distance_log_gain" else final - start
        out = out.to_numpy(float)
        return out[np.isfinite(out)]
    return final.to_numpy(float)


def last_common(values, names) -> int:
    rows = values[values["treatment"].isin(names)]
    return int(rows.groupby("run_id")["generation"].max().min())


# ---- the findings -----------------------------------------------------------------------------
def trend_rows(values) -> list[dict]:
    rows = []
    for world, metric, verb, levels in TRENDS:
        names = [f"{world} {lv}" for lv in levels]
        last = last_common(values, names)
        ordered = ", ".join(sorted(levels))
        key = "best_distance" if metric == "distance" else "frequency"
        start = [measure(values, n, 0, key) for n in names]
        for family, name, label in MEASURES[metric]:
            final = [measure(values, n, last, name) for n in names]
            adjacent = "; ".join(f"{b} over {a} {vargha_delaney(y, x):.2f}"
                                 for a, b, x, y in zip(levels, levels[1:], final, final[1:], strict=False))
            turns = [f"{a} and {b}" for a, b, x, y in zip(levels, levels[1:], final, final[1:], strict=False)
                     if mann_whitney(y, x, "less").p < ALPHA]
            test = jonckheere_terpstra(final)
            rows.append({
                "question": f"{world} {metric} {verb} with stiffness ({ordered}){label}", "family": family,
                "key": name, "trend": (world, metric), "groups": final, "one_sided": True,
                "statistic": test.statistic, "p": test.p,
                "reverse_p": jonckheere_terpstra(final, "decreasing").p,
                "p_generation0": jonckheere_terpstra(start).p, "a12": vargha_delaney(final[-1], final[0]),
                "a12_generation0": vargha_delaney(start[-1], start[0]), "adjacent_a12": adjacent,
                "turns": turns, "means": [g.mean() for g in final], "names": names, "generation": last,
            })
    return rows


def transition_rows(runs, values) -> list[dict]:
    rows = []
    for _, run in runs.drop_duplicates("treatment").iterrows():
        if pd.isna(run["switch_at"]):
            continue
        name = run["treatment"]
        switch, end = int(run["switch_at"]), last_common(values, [name])
        final_world = run["environment_schedule"].split(",")[-1].split(":")[0]
        control = f"{final_world} {name.split()[-1]}"
        above = final_world == "land"  # the paper: water->land better, land->water worse
        contrasts = (("primary", "equal total generations", end),
                     ("secondary", f"equal time in {final_world} (secondary)", end - switch))
        for family, how, control_at in contrasts:
            a = measure(values, name, end, "best_distance")
            b = measure(values, control, control_at, "best_distance")
            a0 = measure(values, name, switch, "best_distance")
            b0 = measure(values, control, 0, "best_distance")
            test = mann_whitney(a, b)
            rows.append({
                "question": f"{name} vs {control}, {how}: generation {end} vs {control_at}", "family": family,
                "key": "best_distance", "trend": None, "groups": [b, a] if above else [a, b],
                "one_sided": False,
                "expected_above": above, "statistic": test.statistic, "p": test.p,
                "p_generation0": mann_whitney(a0, b0).p, "a12": vargha_delaney(a, b),
                "a12_generation0": vargha_delaney(a0, b0), "means": [a.mean(), b.mean()],
                "names": [name, control], "generation": end, "arrival": (a0.mean(), b0.mean()),
                "pair": (a, b),
            })
    return rows


def findings(runs, values, design_figures: bool = True) -> list[dict]:
    rows = trend_rows(values) + transition_rows(runs, values)
    for family in FAMILIES:
        members = [r for r in rows if r["family"] == family]
        p = [r["p"] for r in members]
        m = int(np.isfinite(p).sum())
        starts = holm([r["p_generation0"] if r["one_sided"] else math.nan for r in members])
        for r, p_holm, threshold, start in zip(members, holm(p), design.holm_thresholds(p, ALPHA), starts,
                                               strict=True):
            r.update(p_holm=p_holm, holm_threshold=threshold, p_generation0_holm=start, m=m)
            high, low = (r["groups"][-1], r["groups"][0]) if r["one_sided"] else r["pair"]
            r["a12_low"], r["a12_high"] = design.a12_interval(high, low)
            groups = [g for g in r["groups"] if len(g)]
            if design_figures and len(groups) >= 2 and min(len(g) for g in groups) >= 2:
                n, two_sided = min(len(g) for g in groups), not r["one_sided"]
                seen = design.observed_effect(groups)
                r.update(power=design.power(seen, n, ALPHA / m, two_sided),
                         detectable_a12=design.detectable_a12(len(groups), n, ALPHA / m, two_sided),
                         runs_needed=design.runs_needed(seen, ALPHA / m, two_sided, POWER),
                         runs_needed_a12_071=design.runs_needed(design.linear_effect(len(groups)), ALPHA / m,
                                                                two_sided, POWER))
    for r in rows:
        r["verdict"] = verdict(r, rows)
    return rows


def verdict(r: dict, rows: list[dict]) -> str:
    """The first word(s) of the row's verdict, by docs/results/README.md's vocabulary."""
    holds = r["p_holm"] < ALPHA
    if not r["one_sided"]:
        if not holds:
            return "not detected"
        return "evolved" if (r["a12"] > 0.5) == r["expected_above"] else "reversed"
    if r["reverse_p"] < ALPHA / r["m"]:
        return "reversed"
    gain = r if r["key"] in CHANGES else next(
        (g for g in rows if g["trend"] == r["trend"] and g["key"] == GAIN_OF[r["key"]]), None)
    gain_holds = gain is not None and gain["p_holm"] < ALPHA
    if holds and gain_holds:
        return "evolved"
    if r["p_generation0_holm"] < ALPHA and not gain_holds:
        return "present in random bodies"
    return "not detected"


COMPARED = ("statistic", "p", "p_holm", "holm_threshold", "a12", "a12_low", "a12_high", "a12_generation0",
            "p_generation0", "power", "detectable_a12", "runs_needed", "runs_needed_a12_071")


def same(a, b) -> bool:
    a = float("nan") if a is None or (isinstance(a, str) and not a) or pd.isna(a) else float(a)
    b = float("nan") if b is None or pd.isna(b) else float(b)
    return (math.isnan(a) and math.isnan(b)) or math.isclose(a, b, rel_tol=1e-6, abs_tol=1e-12)


def check_findings(results: Path, rows: list[dict]) -> int:
    table = pd.read_csv(results / "findings.csv").set_index("question")
    differ = 0
    for r in rows:
        if r["question"] not in table.index:
            print(f"MISSING {r['question']}")
            differ += 1
            continue
        stored = table.loc[r["question"]]
        bad = [k for k in COMPARED if not same(stored[k], r.get(k))]
        if r["one_sided"] and str(stored["adjacent_a12"]) != r["adjacent_a12"]:
            bad.append("adjacent_a12")
        word = next(v for v in VERDICTS if str(stored["verdict"]).startswith(v))
        if word != r["verdict"]:
            bad.append("verdict")
        if r["one_sided"] and any(f"turns between {t}" not in stored["verdict"] for t in r["turns"]):
            bad.append("turns")
        differ += bool(bad)
        print(f"{'DIFF' if bad else 'ok  '} {r['question'][:72]:72s} {', '.join(bad)}")
    print(f"findings.csv: {len(rows) - differ} of {len(rows)} rows recomputed "
          f"({len(COMPARED) + 2} values each)")
    return differ


# ---- designs: what would decide each finding ---------------------------------------------------
def designs(rows: list[dict]) -> pd.DataFrame:
    """Per finding of the primary and gain families: the runs a treatment needed at the effect
    seen and at A12 0.71, and `softevo plan`'s figures on 1,000 cores for each design: the
    finding's treatments at the study's sizes with that many runs each (its stored cost
    model, no --measure)."""
    out = []
    for r in rows:
        if r["family"] == "secondary":
            continue
        for effect, n in (("seen", r.get("runs_needed")), ("A12 0.71", r.get("runs_needed_a12_071"))):
            figures = {"core_hours": math.nan, "evaluation_core_hours": math.nan, "wall_hours": math.nan,
                       "evaluations": math.nan}
            if n is not None and not pd.isna(n):
                figures = design_plan(tuple(r["names"]), int(n))
            out.append({"question": r["question"], "effect": effect, "a12": r["a12"],
                        "runs_per_treatment": None if n is None or pd.isna(n) else int(n),
                        "treatments": len(r["names"]), "cores": DESIGN_CORES, **figures})
    frame = pd.DataFrame(out)
    frame["runs_per_treatment"] = pd.array(frame["runs_per_treatment"], dtype="Int64")
    return frame


@functools.cache
def design_plan(names: tuple[str, ...], n: int) -> dict[str, float]:
    """`softevo plan`'s figures on DESIGN_CORES cores for the study's treatments ``names`` with
    ``n`` runs each (kept: the same design is planned once per process, however often ``main``
    runs)."""
    from softevo.evolution.treatments import preset_grid, select_treatments
    from softevo.service.plan import model as planner

    treatments = [dataclasses.replace(t, repetitions=n)  # the plan does not depend on seeds
                  for t in select_treatments(preset_grid("paper", "study"), list(names))]
    plan = planner.plan(treatments, cores=DESIGN_CORES, executor="rq")
    return {"core_hours": plan.core_hours,
            "evaluation_core_hours": sum(t.core_seconds for t in plan.treatments) / 3600,
            "wall_hours": plan.wall_hours, "evaluations": plan.evaluations}


def check_designs(results: Path, frame: pd.DataFrame) -> int:
    path = results / "designs.csv"
    if not path.exists():
        print("MISSING designs.csv")
        return 1
    stored = pd.read_csv(path)
    differ = int(len(stored) != len(frame))
    for (_, a), (_, b) in zip(stored.iterrows(), frame.iterrows(), strict=False):
        keys = ("runs_per_treatment", "core_hours", "evaluation_core_hours", "wall_hours", "evaluations")
        differ += int(a["question"] != b["question"] or not all(same(a[k], b[k]) for k in keys))
    print(f"designs.csv: {len(frame) - differ} of {len(frame)} designs recomputed")
    return differ


# ---- the sensitivity and the pilot --------------------------------------------------------------
SENSITIVITY = (("land frequency falls with stiffness", "land S2", "land S4"),
               ("water frequency rises with stiffness", "water S4", "water S1"))


def sensitivity(results: Path) -> tuple[int, pd.DataFrame]:
    """sensitivity.csv recomputed from the exports in sensitivity/MAPPING/; (differences,
    the recomputed rows)."""
    table = pd.read_csv(results / "sensitivity.csv")
    differ, out = 0, []
    for mapping in table["mapping"].unique():
        runs, evaluations, members = load(results / "sensitivity" / mapping)
        values = population_values(runs, evaluations, members)
        last = int(values.groupby("run_id")["generation"].max().min())
        for question, high, low in SENSITIVITY:
            a0, b0 = measure(values, high, 0, "frequency"), measure(values, low, 0, "frequency")
            for name in ("frequency_change", "frequency"):
                a, b = measure(values, high, last, name), measure(values, low, last, name)
                out.append({"mapping": mapping, "question": question, "measure": name,
                            "a12": vargha_delaney(a, b), "a12_generation0": vargha_delaney(a0, b0),
                            "mean_high": a.mean(), "mean_low": b.mean(),
                            "max_frequency": float(evaluations["frequency"].abs().max())})
    mine = pd.DataFrame(out)
    for (_, a), (_, b) in zip(table.iterrows(), mine.iterrows(), strict=True):
        for key in ("a12", "a12_generation0", "mean_high", "mean_low", "max_frequency"):
            differ += int(not math.isclose(float(a[key]), float(b[key]), rel_tol=1e-3, abs_tol=1e-9))
    print(f"sensitivity.csv: {5 * len(mine) - differ} of {5 * len(mine)} values recomputed from sensitivity/")
    return differ, mine


def knees(results: Path) -> int:
    """pilot/knee.csv's knees recomputed from pilot/export (knee.py's rule); the number that differ."""
    sys.path.insert(0, str(Path(__file__).parent))
    from knee import knee  # docs/results/knee.py, beside this script

    table = pd.read_csv(results / "pilot" / "knee.csv")
    values = population_values(*load(results / "pilot" / "export"))
    differ = 0
    for (treatment, run_id), run in values.groupby(["treatment", "run_id"]):
        repetition = sorted(values.loc[values["treatment"] == treatment, "run_id"].unique()).index(run_id)
        at, ninety = knee(run["generation"].to_numpy(float), run["distance"].to_numpy(float))
        row = table[(table["treatment"] == treatment) & (table["curve"] == f"run {repetition}")].iloc[0]
        differ += int(at != row["knee"]) + int(ninety != row["gain_90"])
    checked = 2 * int(table["curve"].str.startswith("run ").sum())
    print(f"pilot/knee.csv: {checked - differ} of {checked} per-run values recomputed from pilot/export")
    return differ


# ---- the README's numbers ----------------------------------------------------------------------
def g3(value) -> str:
    return "-" if value is None or pd.isna(value) else f"{float(value):.3g}"


def p_text(value) -> str:
    return "-" if pd.isna(value) else f"{float(value):.2g}"


PAPER = {  # the paper's own result, by the start of a finding's question
    "land distance": "stiffer walks farther; S1 non-functional",
    "water distance": "softer swims farther",
    "land frequency": "falls with stiffness",
    "water frequency": "rises with stiffness (stiff swimmers flap)",
    "land-water": "worse than water only (significant)",
    "water-land": "a trend to better, not significant",
}


def paper_result(question: str) -> str:
    return next((text for start, text in PAPER.items() if question.startswith(start)), "-")


def turning_text(rows: list[dict]) -> str:
    """The adjacent levels whose A12 is below 0.5 (against the hypothesis) in the primary and
    gain rows, significant or not."""
    found = []
    for r in rows:
        if r["one_sided"] and r["family"] != "secondary":
            against = [part for part in r["adjacent_a12"].split("; ") if float(part.rsplit(" ", 1)[1]) < 0.5]
            if against:
                found.append(f"{r['question']}: {', '.join(against)}")
    return "; ".join(found) if found else "none"


def runs_text(n) -> str:
    return "> 4000" if n is None or pd.isna(n) else f"{int(n):,}"


def findings_markdown(rows: list[dict], family: str) -> str:
    lines = ["| finding | the paper | generation | means there, per level or group | n | p | p (Holm) | "
             "Holm's threshold | A12 [95% interval] | A12 at generation 0 | power | "
             "runs needed (seen, A12 0.71) | verdict |",
             "| --- | --- | ---: | --- | --- | ---: | ---: | ---: | --- | ---: | ---: | --- | --- |"]
    for r in (r for r in rows if r["family"] == family):
        means = ", ".join(f"{n.split()[-1] if r['one_sided'] else n} {g3(v)}"
                          for n, v in zip(r["names"], r["means"], strict=True))
        n = "+".join(str(len(g)) for g in r["groups"])
        needed = f"{runs_text(r.get('runs_needed'))}, {runs_text(r.get('runs_needed_a12_071'))}"
        turns = "; turns between " + ", ".join(r["turns"]) if r.get("turns") else ""
        lines.append(f"| {r['question']} | {paper_result(r['question'])} | {r['generation']} | {means} | "
                     f"{n} | {p_text(r['p'])} | {p_text(r['p_holm'])} | "
                     f"{p_text(r['holm_threshold'])} | {r['a12']:.2f} "
                     f"[{r['a12_low']:.2f}, {r['a12_high']:.2f}] | "
                     f"{r['a12_generation0']:.2f} | {r.get('power', math.nan):.2f} | {needed} | "
                     f"{r['verdict']}{turns} |")
    return "\n".join(lines)


def adjacent_markdown(rows: list[dict]) -> str:
    lines = ["| trend (measure) | adjacent levels, A12 of each over the one before it |", "| --- | --- |"]
    for r in rows:
        if r["one_sided"] and r["family"] != "secondary":
            lines.append(f"| {r['question']} | {r['adjacent_a12']} |")
    return "\n".join(lines)


def designs_markdown(frame: pd.DataFrame) -> str:
    lines = ["| finding | A12 seen | effect planned for | runs a treatment | evaluations | "
             "core-hours evaluating | core-hours booked (wall x 1,000) | wall on 1,000 cores (h) |",
             "| --- | ---: | --- | ---: | ---: | ---: | ---: | ---: |"]
    for _, d in frame.iterrows():
        runs = runs_text(d["runs_per_treatment"])
        evaluations = "-" if pd.isna(d["evaluations"]) else f"{int(d['evaluations']):,}"
        lines.append(f"| {d['question']} | {d['a12']:.2f} | {d['effect']} | {runs} | {evaluations} | "
                     f"{g3(d['evaluation_core_hours'])} | {g3(d['core_hours'])} | {g3(d['wall_hours'])} |")
    return "\n".join(lines)


def means_markdown(runs, values) -> str:
    lines = ["| treatment | runs | generations (planned, run) | best distance, end (generation 0) | "
             "population frequency, end (generation 0), Hz |", "| --- | ---: | --- | --- | --- |"]
    for name, group in runs.groupby("treatment", sort=False):
        last = last_common(values, [name])
        d, d0 = level(values, name, last, "distance"), level(values, name, 0, "distance")
        f, f0 = level(values, name, last, "frequency"), level(values, name, 0, "frequency")
        planned, run = sorted(set(group["generations"])), sorted(set(group["generations_run"]))
        lines.append(f"| {name} | {len(group)} | {'/'.join(map(str, planned))}, {'/'.join(map(str, run))} | "
                     f"{g3(d.mean())} ({g3(d0.mean())}) | {g3(f.mean())} ({g3(f0.mean())}) |")
    return "\n".join(lines)


def sensitivity_markdown(frame: pd.DataFrame) -> str:
    lines = ["| contrast | measure | " + " | ".join(f"`{m}`" for m in frame["mapping"].unique()) + " |",
             "| --- | --- |" + " ---: |" * frame["mapping"].nunique()]
    for (question, name), group in frame.groupby(["question", "measure"], sort=False):
        cells = [f"{row.a12:.2f} ({row.a12_generation0:.2f}): {g3(row.mean_high)} vs {g3(row.mean_low)}"
                 for row in group.itertuples()]
        lines.append(f"| {question} | {name} | " + " | ".join(cells) + " |")
    fastest = frame.groupby("mapping", sort=False)["max_frequency"].first()
    lines.append("| fastest robot evaluated | | " + " | ".join(f"{g3(v)} Hz" for v in fastest) + " |")
    return "\n".join(lines)


@functools.cache
def study_plan():
    """`softevo plan paper --scale study --cores 2` (the local executor), once per process."""
    from softevo.evolution.treatments import preset_grid
    from softevo.service.plan import model as planner

    return planner.plan(preset_grid("paper", "study"), cores=2, executor="local")


def cost_numbers(runs, evaluations) -> dict[str, str]:
    """What the study cost, planned and measured, and the frequencies' shares."""
    frequency = evaluations["frequency"].abs()
    simulated = evaluations.dropna(subset=["steps"])
    merged = evaluations.merge(runs[["run_id", "cycles", "max_seconds", "treatment"]], on="run_id")
    cut = ((merged["cycles"] / merged["frequency"].abs() > merged["max_seconds"])
           & merged["frequency"].notna())
    at_bound = (frequency >= 4.0) | cut
    shared = evaluations.dropna(subset=["frequency"]).groupby("frequency")["run_id"].nunique()
    start = pd.to_datetime(runs["created_at"]).min()
    end = pd.to_datetime(runs["last_stored_at"]).max()
    planned = study_plan()
    rows = ["| treatment | evaluations planned, run | seconds an evaluation, planned (mean per world) | "
            "measured (mean wall) | simulated seconds (mean) | steps (mean) |",
            "| --- | --- | --- | ---: | ---: | ---: |"]
    for t in planned.treatments:
        mine = simulated[simulated["run_id"].isin(runs.loc[runs["treatment"] == t.name, "run_id"])]
        worlds = ", ".join(f"{w} {v['mean']:.3g}" for w, v in t.seconds_per_evaluation.items())
        ran = int(evaluations["run_id"].isin(runs.loc[runs["treatment"] == t.name, "run_id"]).sum())
        rows.append(f"| {t.name} | {t.evaluations:,}, {ran:,} | {worlds} | "
                    f"{mine['wall_seconds'].mean():.3g} | "
                    f"{mine['simulated_seconds'].mean():.3g} | {mine['steps'].mean():.3g} |")
    return {
        "plan_table": "\n".join(rows),
        "evaluations": f"{len(evaluations):,}",
        "runs": f"{len(runs)}",
        "simulated": f"{len(simulated):,}",
        "share_at_bound": f"{100 * at_bound.mean():.2f}%",
        "share_cut": f"{100 * cut.mean():.2f}%",
        "cut": f"{int(cut.sum())}",
        "share_below_low": f"{100 * (frequency < LOW_HZ).mean():.2f}%",
        "highest_hz": f"{frequency.max():.4g}",
        "lowest_hz": f"{frequency[frequency > 0].min():.3g}",
        "shared_values": f"{int((shared > 1).sum())}",
        "wall_hours": f"{(end - start).total_seconds() / 3600:.2f}",
        "planned_hours": f"{planned.wall_hours:.2f}",
        "simulated_hours": f"{simulated['simulated_seconds'].sum() / 3600:,.0f}",
        "evaluation_core_hours": f"{simulated['wall_seconds'].sum() / 3600:.2f}",
        "steps": f"{simulated['steps'].sum():.3g}",
        "planned_evaluations": f"{planned.evaluations:,}",
        "planned_core_hours": f"{sum(t.core_seconds for t in planned.treatments) / 3600:.2f}",
    }


def design_numbers(runs) -> dict[str, str]:
    """The design as runs.csv stores it: sizes, protocol, generations, the switch."""
    static = runs[runs["switch_at"].isna()]
    transitions = runs[runs["switch_at"].notna()]
    long = set(transitions["generations"])
    return {
        "cycles": "/".join(str(c) for c in sorted(set(runs["cycles"]))),
        "guard": "/".join(f"{g:g}" for g in sorted(set(runs["max_seconds"]))),
        "population": "/".join(str(p) for p in sorted(set(runs["population"]))),
        "workspace": "/".join(w.replace("x", "×") for w in sorted(set(runs["workspace"]))),
        "repetitions": "/".join(str(n) for n in sorted(set(runs.groupby("treatment").size()))),
        "grid_generations": "/".join(str(g) for g in sorted(set(static["generations"]) - long)),
        "transition_generations": "/".join(str(g) for g in sorted(long)),
        "switch": "/".join(str(int(g)) for g in sorted(set(transitions["switch_at"]))),
    }


def numbers(results: Path, rows, design_frame, sensitivity_frame) -> dict[str, str]:
    runs, evaluations, members = load(results / "export")
    values = population_values(runs, evaluations, members)
    out = cost_numbers(runs, evaluations) | design_numbers(runs)
    out["findings_primary"] = findings_markdown(rows, "primary")
    out["findings_gain"] = findings_markdown(rows, "gain")
    out["findings_secondary"] = findings_markdown(rows, "secondary")
    out["adjacent"] = adjacent_markdown(rows)
    out["turning"] = turning_text(rows)
    out["designs"] = designs_markdown(design_frame)
    out["means"] = means_markdown(runs, values)
    out["sensitivity"] = sensitivity_markdown(sensitivity_frame) if sensitivity_frame is not None else ""
    for r in rows:
        if not r["one_sided"] and r["family"] == "primary":
            key = r["names"][0].split()[0].replace("-", "_")
            out[f"{key}_arrival"] = f"{g3(r['arrival'][0])} vs {g3(r['arrival'][1])}"
            out[f"{key}_arrival_a12"] = f"{r['a12_generation0']:.2f}"
    return out


def render(results: Path, numbers_: dict[str, str]) -> str:
    return (results / "README.template.md").read_text().format(**numbers_)


def main(results: Path, write: bool = False) -> int:
    runs, evaluations, members = load(results / "export")
    values = population_values(runs, evaluations, members)
    rows = findings(runs, values)
    status = int(check_findings(results, rows) > 0)
    design_frame = designs(rows)
    differ, sensitivity_frame = (sensitivity(results) if (results / "sensitivity.csv").exists()
                                 else (0, None))
    status |= int(differ > 0)
    if (results / "pilot" / "export").is_dir():
        status |= int(knees(results) > 0)
    text = render(results, numbers(results, rows, design_frame, sensitivity_frame))
    if write:
        design_frame.to_csv(results / "designs.csv", index=False)
        (results / "README.md").write_text(text)
        print("wrote designs.csv and README.md")
        return status
    status |= int(check_designs(results, design_frame) > 0)
    stored = (results / "README.md").read_text()
    if stored != text:
        print("README.md differs from what the export gives:")
        for line in difflib.unified_diff(stored.splitlines(), text.splitlines(), "README.md", "recomputed",
                                         lineterm="", n=0):
            print(line)
        status = 1
    else:
        print("README.md: every number recomputed from the export")
    return status


if __name__ == "__main__":
    sys.exit(main(Path(sys.argv[1]), "--write" in sys.argv[2:]))
