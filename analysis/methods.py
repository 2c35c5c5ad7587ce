"""What each treatment's evaluations were, in words, from its own stored settings (the
report's methods paragraph): physics model, frequency mapping, settling, cycles and the cap
on seconds, how many evaluations the cap cut, and every other declared treatment option
(``evolution.options``, those whose ``methods`` is set) that differs from its default, as
``name = value unit`` (``options_text``).

Settling is read from the scenes the treatment's evaluations build (``evolution.evaluation.
evaluation_scenes`` with the treatment's model, cycles and cap, in each world of its
schedule), not written here: it depends on the model and the world. The mappings are
described from ``evolution.genotype`` (``CONTROL_MAPPINGS``, and per evosoro variant
whether it reads the output through the logistic, whether it is bounded at
``EVOSORO_MAX_FREQUENCY`` and whether a negative frequency is invalid); a name this module does
not know is named as it is stored.
"""

from __future__ import annotations

from typing import Any

import pandas as pd

from softevo.analysis.run_summary import capped
from softevo.evolution import environments, genotype, options
from softevo.evolution.evaluation import DEFAULT_MODEL, evaluation_scenes

METHOD_COLUMNS = ["treatment", "model", "frequency", "settling", "cycles", "cap", "options", "capped",
                  "counted", "at_bound", "below_low"]
LOW_FREQUENCY_HZ = 0.5  # the report counts the evaluations below it


def mapping_text(name: str, frequency_range: tuple[float, float] = (1.0, 5.0)) -> str:
    """The control mapping ``name`` in words (``evolution.genotype``)."""
    if name == "linear":
        low, high = frequency_range
        return f"one evolved frequency mapped linearly onto {low:g}-{high:g} Hz"
    variants = genotype.EVOSORO_MAPPINGS
    if name in variants:
        logistic, bounded, positive_only = variants[name]
        if logistic:
            return (f"the evosoro scripts' frequency 10 / (mean(1/s') + 1.5) Hz of the output read through "
                    f"the logistic, s' = (1 + s) / 2: below {genotype.EVOSORO_MAX_FREQUENCY:g} Hz")
        bound = f"at most {genotype.EVOSORO_MAX_FREQUENCY:g} Hz" if bounded else "unbounded"
        negative = "a negative f makes the robot invalid" if positive_only else "a negative f runs at |f|"
        return f"the evosoro scripts' frequency 10 / (mean(1/s) + 1.5) Hz, {bound}; {negative}"
    known = "" if name in genotype.CONTROL_MAPPINGS else " (unknown to this version)"
    return f"control mapping {name!r}{known}"


def options_text(treatment: pd.Series) -> str:
    """The declared options the paragraph names (``Option.methods``) whose stored value
    differs from the default, e.g. ``workspace = 5,5,5 voxels, evolve_stiffness = True``; an
    option the settings do not hold (stored before it existed) is at its default."""
    parts = []
    for option in options.declared():
        if not option.methods or option.name not in treatment.index:
            continue
        value = option.from_json(treatment[option.name])
        if value is None or (not option.sequence and not isinstance(value, str) and pd.isna(value)):
            continue
        if value != option.default:
            unit = f" {option.unit}" if option.unit else ""
            parts.append(f"{option.name} = {option.format(value)}{unit}")
    return ", ".join(parts)


def settling_text(treatment: pd.Series, phenotype) -> str:
    """Seconds of settling before distance counts, per world of the treatment's schedule,
    read from the scene its evaluations build with ``phenotype`` (any robot: settling does
    not depend on the body)."""
    parts = []
    for world in environments.transition(treatment["environment"]):
        scene = evaluation_scenes(
            phenotype,
            world,
            float(treatment["stiffness_mpa"]) * 1e6,
            int(treatment["cycles"]),
            model=str(treatment.get("model", DEFAULT_MODEL)),
            max_seconds=_cap(treatment),
        )[0]
        parts.append(f"{float(scene['settle_seconds']):g} s {environments.get(world).label}")
    return ", ".join(parts)


def _cap(treatment: pd.Series) -> float | None:
    cap = treatment.get("max_seconds")
    return None if cap is None or pd.isna(cap) else float(cap)


def cap_cuts(treatment: pd.Series, evaluations: pd.DataFrame) -> tuple[int, int]:
    """(evaluations the cap on seconds cut short, evaluations counted) among ``evaluations``
    of the treatment: their stored ``capped`` flag where the data have it, else cycles /
    |frequency| > max_seconds."""
    mine = evaluations[evaluations["treatment"] == treatment["name"]]
    if "capped" in mine.columns and mine["capped"].notna().any():
        flags = mine["capped"].dropna().astype(bool)
    else:
        mine = mine.dropna(subset=["frequency"])
        flags = pd.Series(capped(mine["frequency"], float(treatment["cycles"]), _cap(treatment)))
    return int(flags.sum()), int(flags.size)


def frequency_shares(treatment: pd.Series, evaluations: pd.DataFrame) -> tuple[int, int]:
    """(evaluations at a bound: at the mapping's 4 Hz clip or cut by the cap on seconds,
    evaluations below ``LOW_FREQUENCY_HZ``) among the treatment's evaluations with a frequency."""
    mine = evaluations[evaluations["treatment"] == treatment["name"]].dropna(subset=["frequency"])
    frequency = mine["frequency"].abs().to_numpy(float)
    bounded = genotype.EVOSORO_MAPPINGS.get(str(treatment.get("control_mapping", "linear")))
    clipped = (frequency >= genotype.EVOSORO_MAX_FREQUENCY
               if bounded is not None and bounded.bounded else False)
    cut = capped(frequency, float(treatment["cycles"]), _cap(treatment))
    return int((clipped | cut).sum()), int((frequency < LOW_FREQUENCY_HZ).sum())


def evaluation_methods(treatments: pd.DataFrame, evaluations: pd.DataFrame, phenotype) -> pd.DataFrame:
    """One row per treatment (``METHOD_COLUMNS``): its model, mapping, settling, cycles, cap,
    the evaluations the cap cut (``capped``) of those counted in ``evaluations``, those at a
    bound (the clip or the cap: ``at_bound``) and those below 0.5 Hz (``below_low``)."""
    rows = []
    for _, t in treatments.iterrows():
        cap = _cap(t)
        cut, counted = cap_cuts(t, evaluations)
        at_bound, below = frequency_shares(t, evaluations)
        rows.append(
            {
                "treatment": t["name"],
                "model": t.get("model", DEFAULT_MODEL),
                "frequency": mapping_text(str(t.get("control_mapping", "linear"))),
                "settling": settling_text(t, phenotype),
                "cycles": int(t["cycles"]),
                "cap": "none" if cap is None else f"{cap:g} s",
                "options": options_text(t),
                "capped": cut,
                "counted": counted,
                "at_bound": at_bound,
                "below_low": below,
            }
        )
    return pd.DataFrame(rows, columns=METHOD_COLUMNS)


def methods_text(methods: pd.DataFrame) -> str:
    """The methods as sentences, treatments with the same evaluation grouped."""
    keys = [c for c in METHOD_COLUMNS if c not in ("treatment", "capped", "counted", "at_bound", "below_low")]
    sentences = []
    for values, group in methods.groupby(keys, sort=False):
        setting: dict[str, Any] = dict(zip(keys, values, strict=True))
        cap = setting["cap"]
        capped_text = (
            f", at most {cap} after settling (the cap cut {group['capped'].sum()} of the "
            f"{group['counted'].sum()} evaluations counted)"
            if cap != "none"
            else ", no cap on seconds"
        )
        counted = max(int(group["counted"].sum()), 1)
        shares = (f" Of its evaluations {100 * group['at_bound'].sum() / counted:.1f}% sit at a bound of the "
                  f"frequency (the mapping's clip or the cap) and "
                  f"{100 * group['below_low'].sum() / counted:.1f}% "
                  f"run below {LOW_FREQUENCY_HZ:g} Hz.")
        others = f"; {setting['options']}" if setting["options"] else ""
        sentences.append(
            f"{', '.join(group['treatment'])}: physics model {setting['model']}; frequency: "
            f"{setting['frequency']}; settling {setting['settling']}; {setting['cycles']} "
            f"actuation cycles per evaluation{capped_text}{others}.{shares}"
        )
    return " ".join(sentences)
