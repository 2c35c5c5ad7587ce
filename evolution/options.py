"""Every option of a treatment, declared once: its name, part, type, default, bounds or
choices, unit, help text and command-line spelling.

A treatment (``evolution.treatments.Treatment``) is made of four parts, each a record of
the options declared for it (``part_type``, a frozen dataclass generated from the
declarations, each field's ``metadata["option"]`` its ``Option``):

- ``evaluation``: what one evaluation is (world, stiffness, model, cycles, the cap on
  seconds, the encoding: workspace, mapping, body rule, evolved stiffness, per-voxel
  frequency);
- ``schedule``: when a transition switches (``switch_at``, ``switch_over``);
- ``search``: the algorithm and its sizes (population, generations, algorithm, objectives);
- ``seeds``: ``seed`` and ``repetitions``.

Everything else is generated from these declarations: the ``softevo run`` options
(``service.cli.runs``), the REST ``TreatmentIn`` schema (``service.api.schemas``), the limits
a request may ask (``service.runs.limits.check_treatment``), the stored settings
(``Treatment.to_settings`` / ``from_settings``), the encoding an evaluation develops genomes
with (``encoding_of``), the paper presets' choices (``paper_choices``) and the report's methods
paragraph (``analysis.methods``).

Choices are callables, read when a value is checked or a schema is made, so that a model,
algorithm, mapping or world registered later is accepted. ``declare(option)`` adds an option
at run time (a plugin's, a test's): ``softevo run`` (when its command is read), REST (when
the app is built after it), the limits, the settings and the report then carry it; its value
reaches the evaluation only through what the plugin does with ``treatment.<name>``.
``undeclare(name)`` removes it.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from softevo.errors import UserError
from softevo.evolution import algorithm, environments, genotype, selection, traits
from softevo.evolution.archive import MAX_CELLS
from softevo.sim import models
from softevo.sim.registry import Registry
from softevo.sim.scene import DEFAULT_CYCLES, MAX_SIDE

PARTS = ("evaluation", "schedule", "search", "seeds")
STIFFNESS_RANGE_MPA = (0.001, 10.0)  # the paper's S1..S5
MAX_INT32 = 2**31 - 1  # what the database's integer columns hold


@dataclass(frozen=True)
class Option:
    """One treatment option.

    ``type`` is the value's (``int``, ``float``, ``bool``, ``str``), a sequence's item type
    when ``length`` (exactly that many items) or ``many`` (at most that many) is set; a
    sequence is written ``a,b,c`` on the command line and stored as a JSON list. ``least``,
    ``most`` and ``above`` (exclusive) bound a number, or each item of a sequence, wherever
    a treatment is made; ``limit`` is the most a request may ask (the cost of a run:
    ``service.runs.limits``, the REST schema), default ``most``. ``choices`` returns the
    allowed strings when asked; ``check`` raises ValueError for a value the other fields do
    not rule out. ``optional``: None is a value (no cap); ``required``: no default.
    ``encodes`` names the ``EncodingConfig`` field the option sets (times ``scale``:
    MPa to Pa); ``paper`` is the paper presets' choice; ``methods``: the report's methods
    paragraph names the option when it differs from its default."""

    name: str
    part: str
    type: type
    default: Any = None
    help: str = ""
    unit: str = ""
    least: float | None = None
    most: float | None = None
    above: float | None = None
    limit: float | None = None
    choices: Callable[[], Sequence[str]] | None = None
    check: Callable[[Any], None] | None = None
    optional: bool = False
    required: bool = False
    length: int | None = None
    many: int | None = None
    flag: str = ""
    label: str = ""
    encodes: str = ""
    scale: float = 1.0
    paper: Any = None
    methods: bool = True

    def __post_init__(self) -> None:
        if self.part not in PARTS:
            raise ValueError(f"option {self.name!r}: part must be one of {', '.join(PARTS)} "
                             f"(got {self.part!r})")
        if not self.name.isidentifier() or self.name.startswith("_"):
            raise ValueError(f"option name must be a public identifier (got {self.name!r})")
        if not self.flag:
            object.__setattr__(self, "flag", "--" + self.name.replace("_", "-"))
        if not self.label:
            object.__setattr__(self, "label", self.name)

    @property
    def sequence(self) -> bool:
        """Whether the value is a sequence of ``type`` items."""
        return self.length is not None or self.many is not None

    @property
    def most_asked(self) -> float | None:
        """The most a request may ask (``limit``, else ``most``)."""
        return self.limit if self.limit is not None else self.most

    def bounds_text(self, most: float | None = None) -> str:
        """E.g. ``within 1..64``, ``>= 2``, ``> 0``, ``at most 3600``."""
        most = self.most if most is None else most
        if self.least is not None and most is not None:
            return f"within {_figure(self.least)}..{_figure(most)}"
        if self.least is not None:
            return f">= {_figure(self.least)}"
        if self.above is not None:
            return f"> {_figure(self.above)}" + (f" and at most {_figure(most)}" if most is not None else "")
        return f"at most {_figure(most)}" if most is not None else ""

    # -- the command line ----------------------------------------------------------------

    def parse(self, text: str) -> Any:
        """A sequence's value from the command line's ``a,b,c`` (UserError naming the flag)."""
        parts = [part.strip() for part in str(text).split(",") if part.strip()]
        try:
            value = tuple(self.type(part) for part in parts)
        except ValueError:
            value = None
        if value is None or (self.length is not None and len(value) != self.length):
            raise UserError(f"{self.flag} must be {self.sequence_text()} (got {text!r})")
        return value

    def format(self, value: Any) -> str:
        """The command line's text of ``value`` (``7,7,7``; empty for None or no items)."""
        if value is None:
            return ""
        if self.sequence:
            return ",".join(_plain(item) for item in value)
        return _plain(value)

    def sequence_text(self) -> str:
        """E.g. ``3 integers within 1..64 voxels``, ``at most 16 names``."""
        kind = {int: "integers", float: "numbers", str: "names"}.get(self.type, "values")
        count = str(self.length) if self.length is not None else f"at most {self.many}"
        bounds = self.bounds_text()
        return " ".join(part for part in (count, kind, bounds, self.unit) if part)

    # -- stored settings -----------------------------------------------------------------

    def to_json(self, value: Any) -> Any:
        """``value`` as plain JSON (a sequence as a list)."""
        return list(value) if self.sequence and value is not None else value

    def from_json(self, value: Any) -> Any:
        """The value of stored JSON (a list read as a tuple)."""
        if self.sequence and isinstance(value, list | tuple):
            return tuple(int(item) if self.type is int and _integral(item) else item for item in value)
        return value

    # -- checks ----------------------------------------------------------------------------

    def validate(self, value: Any) -> None:
        """UserError (one line) for a value no treatment may have (type, bounds, choices);
        the limit on what a request may ask is ``beyond_limit``'s."""
        if value is None:
            if self.optional:
                return
            raise UserError(f"{self.label} must be given")
        if self.sequence:
            if (not isinstance(value, tuple | list) or (self.length is not None and len(value) != self.length)
                    or (self.many is not None and len(value) > self.many)
                    or not all(self._fits(item) for item in value)):
                shown = self.format(value) if _joinable(value) else repr(value)
                raise UserError(f"{self.label} must be {self.sequence_text()} (got {shown})")
        elif not self._fits(value):
            raise UserError(self._problem(value))
        if self.check is not None:
            try:
                self.check(value)
            except ValueError as exc:
                raise UserError(f"{self.label}: {exc}") from None

    def _fits(self, value: Any) -> bool:
        if self.type is bool:
            return isinstance(value, bool)
        if self.type is str:
            known = self.choices is None or value in self.choices()
            return isinstance(value, str) and bool(value) and known
        if isinstance(value, bool) or not isinstance(value, int if self.type is int else int | float):
            return False
        if not math.isfinite(value):
            return False
        return ((self.least is None or value >= self.least) and (self.most is None or value <= self.most)
                and (self.above is None or value > self.above))

    def _problem(self, value: Any) -> str:
        if self.type is bool:
            return f"{self.label} must be true or false (got {value!r})"
        if self.type is str:
            if self.choices is None:
                return f"{self.label} must be a non-empty text (got {value!r})"
            return f"unknown {self.label} {value!r}; choose one of {', '.join(self.choices())}"
        unit = f" {self.unit}" if self.unit else ""
        if self.type is float and isinstance(value, int | float) and not isinstance(value, bool) \
                and math.isfinite(value):  # a number out of bounds
            return f"{self.label} must be {self.bounds_text()}{unit} (got {_figure(value)})"
        kind = "an integer" if self.type is int else f"a number{' of' + unit if unit else ''}"
        wanted = " ".join(part for part in (kind, self.bounds_text()) if part)
        return f"{self.label} must be {wanted} (got {value!r})"

    def beyond_limit(self, value: Any) -> str | None:
        """The one-line problem of a value beyond what a request may ask (``limit``), or
        None (``service.runs.limits.check_treatment``; the value already ``validate``d)."""
        most = self.most_asked
        if most is None or value is None or self.type not in (int, float):
            return None
        values = value if self.sequence else (value,)
        if all(item <= most for item in values):
            return None
        if self.sequence:
            unit = f" {self.unit}" if self.unit else ""
            return f"{self.label} must be at most {_figure(most)}{unit} each (got {self.format(value)})"
        bounds = f"within {_figure(self.least)}..{_figure(most)}" if self.least is not None else \
            f"at most {_figure(most)}"
        return f"{self.label} must be {bounds} (got {_figure(value)})"


def _figure(value: Any) -> str:
    """A number as messages and the command line write it: ``10,000``, ``0.001``, ``3600``."""
    if isinstance(value, bool) or not isinstance(value, int | float):
        return str(value)
    if isinstance(value, int):
        return f"{value:,}"
    return f"{value:g}" if abs(value) < 1e6 else f"{value:,.0f}"


def _plain(value: Any) -> str:
    """A value as the command line writes it: ``5``, ``0.001``, ``evosoro``."""
    if isinstance(value, float):
        return f"{value:g}"
    return str(value)


def _integral(value: Any) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool) and float(value).is_integer()


def _joinable(value: Any) -> bool:
    return isinstance(value, tuple | list) and all(isinstance(item, int | float | str) for item in value)


# -- the built-in options ----------------------------------------------------------------


def _control_mappings() -> tuple[str, ...]:
    return tuple(genotype.CONTROL_MAPPINGS)


def _body_rules() -> tuple[str, ...]:
    return tuple(genotype.BODY_RULES)


MAX_MEASURES = 6  # the most traits a MAP-Elites grid spans
MAX_CELLS_ASKED = 1_000  # the most cells per measure a request may ask


def _traits_named(names: Sequence[str]) -> None:
    """ValueError for a name that is no registered trait (``evolution.traits``)."""
    unknown = [name for name in names if name not in traits.names()]
    if unknown:
        raise ValueError(f"{', '.join(unknown)} is no registered trait; choose among "
                         f"{', '.join(traits.names())}")


def _include_distance(names: Sequence[str]) -> None:
    """ValueError for objectives without distance (naming first a name that is no registered
    objective, ``evolution.selection``). Names are not checked otherwise here: settings stored
    with an objective no longer registered still read; they only cannot run
    (``Treatment.objective_list``)."""
    if names and "distance" not in names:
        try:
            selection.objectives_named(tuple(names))
        except KeyError as exc:  # a registry's lookup error: read as the ValueError it means
            raise ValueError(exc.args[0]) from None
        raise ValueError(f"must include distance (got {', '.join(names)})")


BUILT_IN = (
    Option("environment", "evaluation", str, required=True, flag="--env", choices=environments.environments,
           help="the world, or a transition between two (land-water)", methods=False),
    Option("stiffness_mpa", "evaluation", float, required=True, flag="--stiffness", label="stiffness",
           unit="MPa", least=STIFFNESS_RANGE_MPA[0], most=STIFFNESS_RANGE_MPA[1], methods=False,
           help="Young's modulus; with evolve_stiffness unused by the physics (softevo run: optional, 0.1)"),
    Option("workspace", "evaluation", int, genotype.EncodingConfig.workspace, length=3, least=1,
           most=MAX_SIDE, unit="voxels", encodes="workspace", help="voxels along x, y, z"),
    Option("cycles", "evaluation", int, DEFAULT_CYCLES, least=1, limit=10_000, methods=False,
           help="actuation cycles per evaluation"),
    Option("max_seconds", "evaluation", float, None, optional=True, above=0, limit=3600.0, unit="seconds",
           methods=False, help="the most seconds an evaluation lasts, settling not counted (none: its "
           "cycles alone; the paper's scripts: 4.5)"),
    Option("model", "evaluation", str, models.DEFAULT, choices=models.names, paper="voxcad-land-water",
           methods=False, help="physics model of every evaluation: voxelyze-2, or voxcad-land-water (the "
           "paper's engine: 3-D distance in both worlds)"),
    Option("control_mapping", "evaluation", str, "linear", choices=_control_mappings,
           encodes="control_mapping",
           paper="evosoro-logistic", methods=False,
           help="linear: one frequency mapped onto 1-5 Hz; evosoro-logistic: the paper scripts' "
           "10 / (mean(1/s') + 1.5) Hz of the logistic output (0-4 Hz); evosoro-bounded: the bipolar "
           "output clipped at 4 Hz; evosoro: unbounded; evosoro-positive, evosoro-bounded-positive: a "
           "negative frequency invalid"),
    Option("body_rule", "evaluation", str, "any", choices=_body_rules, encodes="body_rule", paper="evosoro",
           help="any: every non-empty body is simulated; evosoro: bodies with under 30% of the workspace "
           "full or 10% active are drawn or mutated again"),
    Option("evolve_stiffness", "evaluation", bool, False, encodes="evolve_stiffness",
           help="evolve a Young's modulus per voxel within stiffness_range_mpa"),
    Option("stiffness_range_mpa", "evaluation", float, STIFFNESS_RANGE_MPA, length=2,
           flag="--stiffness-range",
           least=STIFFNESS_RANGE_MPA[0], most=STIFFNESS_RANGE_MPA[1], unit="MPa", encodes="stiffness_range",
           scale=1e6, help="LO,HI of an evolved stiffness (default the paper's S1..S5)"),
    Option("frequency_per_voxel", "evaluation", bool, False, encodes="frequency_per_voxel",
           help="each voxel actuates at its own frequency"),
    Option("switch_at", "schedule", int, None, optional=True, least=1, limit=MAX_INT32, methods=False,
           help="first generation in the second environment (default: half the generations)"),
    Option("switch_over", "schedule", int, 0, least=0, limit=1_000_000, methods=False,
           help="generations of a gradual switch: compound worlds whose evaluations spend a rising share "
           "of their cycles in the second environment (0: abrupt)"),
    Option("population", "search", int, algorithm.PAPER_POPULATION, least=2, limit=10_000, methods=False,
           help="individuals kept each generation"),
    Option("generations", "search", int, 100, least=1, limit=1_000_000, methods=False,
           help="generations of each run"),
    Option("algorithm", "search", str, "afpo", choices=algorithm.names, paper="pareto", methods=False,
           help="pareto: the paper's plain 3-objective Pareto optimisation (mutation only); afpo: "
           "Age-Fitness Pareto, a named variant (age objective, one random newcomer a generation); "
           "map-elites: MAP-Elites over the grid of measures and cells (the farthest robot of each cell)"),
    Option("objectives", "search", str, (), many=16, check=_include_distance, methods=False,
           help="names of the objectives selection optimises, each a registered one, distance among "
           "them (evolution.selection; none: the paper's distance, active_share, voxel_count)"),
    Option("measures", "search", str, ("frequency", "branching"), many=MAX_MEASURES, check=_traits_named,
           methods=False, help="map-elites: the registered traits whose grid the archive covers "
           "(evolution.traits)"),
    Option("cells", "search", int, (6, 6), many=MAX_MEASURES, least=1, most=MAX_CELLS, limit=MAX_CELLS_ASKED,
           methods=False, help="map-elites: cells per measure"),
    Option("measure_bounds", "search", float, (), many=2 * MAX_MEASURES, methods=False,
           help="map-elites: LO,HI of each measure in turn (none: each trait's own bounds)"),
    Option("seed", "seeds", int, 0, least=0, limit=MAX_INT32 - 1000, methods=False,
           help="repetition r runs with seed + r"),
    Option("repetitions", "seeds", int, 1, least=1, limit=1000, methods=False,
           help="runs of the treatment, each with its own seed"),
)

OPTIONS: Registry[Option] = Registry("treatment option", BUILT_IN)


def declare(option: Option) -> Option:
    """Add a treatment option (ValueError if its name is taken)."""
    return OPTIONS.register(option)


def undeclare(name: str) -> None:
    """Remove an option ``declare`` added (ValueError for a built-in one)."""
    OPTIONS.unregister(name)


def declared(part: str | None = None) -> tuple[Option, ...]:
    """Every declared option (of ``part`` when given), in declaration order."""
    return tuple(o for o in OPTIONS.records() if part is None or o.part == part)


def option(name: str) -> Option:
    """The declared option ``name``; KeyError naming the choices."""
    return OPTIONS.get(name)


def defaults() -> dict[str, Any]:
    """Every option's default (the required ones' None)."""
    return {o.name: o.default for o in declared()}


def paper_choices() -> dict[str, Any]:
    """What the paper presets choose, by option (the built-in ``paper`` values)."""
    return {o.name: o.paper for o in BUILT_IN if o.paper is not None}


_PART_TYPES: dict[tuple[str, tuple[Option, ...]], type] = {}


def part_type(part: str) -> type:
    """The frozen dataclass of ``part``'s options (one field per option, its ``Option`` in the
    field's ``metadata["option"]``), made again when the declarations change."""
    members = declared(part)
    key = (part, members)
    if key not in _PART_TYPES:
        fields = [(o.name, Any, dataclasses.field(default=o.default, metadata={"option": o}))
                  for o in members]
        _PART_TYPES[key] = dataclasses.make_dataclass(
            f"{part.capitalize()}Part", fields, frozen=True,
            namespace={"__doc__": f"The {part} options of a treatment (evolution.options).",
                       "__module__": __name__})
    return _PART_TYPES[key]


def encoding_of(values: Mapping[str, Any]) -> genotype.EncodingConfig:
    """The ``EncodingConfig`` of a treatment's option values (the options that ``encodes``;
    absent ones, as in older stored settings, give their defaults)."""
    fields = {}
    for o in declared():
        if o.encodes:
            value = values.get(o.name, o.default)
            if o.scale != 1.0 and value is not None:
                value = tuple(float(x) * o.scale for x in value) if o.sequence else float(value) * o.scale
            elif o.sequence and value is not None:
                value = tuple(value)
            fields[o.encodes] = value
    return genotype.EncodingConfig(**fields)
