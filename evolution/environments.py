"""World names: a pure world (``sim.worlds``, re-exported here), a transition between two, or
a compound world of a gradual transition. Every spelling of a transition is read here.

A treatment's environment is a pure world or a transition ``A-B`` (``transition`` reads it
as ``("A", "B")``; ``environments()`` lists every one offered for evolution); a schedule's
text ``A:0,B:50+10`` by ``schedule_entries`` (``evolution.schedule.Schedule.parse``); the
compound worlds of a gradual switch are named and read by ``compound`` / ``parts``.

A gradual transition moves a population from world A to world B over a span of ``G``
generations (``--switch-over G``). At the ``k``-th generation of the span (``k = 0..G-1``)
every evaluation runs in the compound world ``A>B@s`` with ``s = (k + 1) / (G + 1)``: a share
``1 - s`` of its actuation cycles in A, then ``s`` in B (``evolution.evaluation.evaluation_scenes``
builds the two scenes, ``evolution.outcome.Outcome.combine`` adds their distances). The share is written
with three decimals and read back from the name, so the name alone (stored in
``evaluations.environment``, at most 20 characters) says exactly what was simulated.

``compound(a, b, s)`` makes a name, ``parts(name)`` reads one back as ``[(world, share),
...]`` (one part of share 1.0 for a pure world).
"""

from __future__ import annotations

from softevo.sim.worlds import (
    HORIZONTAL,
    KINDS,
    LAND,
    THREE_D,
    VOID,
    WATER,
    World,
    added,
    all_worlds,
    get,
    names,
    register,
    unregister,
)

__all__ = [
    "HORIZONTAL", "KINDS", "LAND", "PAPER", "THREE_D", "VOID", "WATER", "World", "added", "all_worlds", "get",
    "names", "register", "unregister",
    "between", "compound", "environments", "final", "is_compound", "is_transition", "new_share", "parts",
    "schedule_entries", "share_at", "transition",
]

PAPER = (LAND.name, WATER.name)  # the paper's two worlds (docs/spec.md section 5)
TRANSITION = "-"
SEPARATOR = ">"
SHARE_MARK = "@"
SHARE_DIGITS = 3


def share_at(k: int, span: int) -> float:
    """The new world's share at the ``k``-th generation (0-based) of a span of ``span``."""
    if not 0 <= k < span:
        raise ValueError(f"generation {k} is not within a switch-over of {span}")
    return round((k + 1) / (span + 1), SHARE_DIGITS)


def compound(old: str, new: str, share: float) -> str:
    """The name of the world spending ``1 - share`` of each evaluation in ``old`` and
    ``share`` in ``new`` (0 < share < 1), e.g. ``land>water@0.250``."""
    if not 0.0 < share < 1.0:
        raise ValueError(f"a compound world's share must be within (0, 1) (got {share})")
    return f"{old}{SEPARATOR}{new}{SHARE_MARK}{share:.{SHARE_DIGITS}f}"


def is_compound(name: str) -> bool:
    return SEPARATOR in name


def parts(name: str) -> list[tuple[str, float]]:
    """``[(world, share of the evaluation's cycles), ...]`` in the order simulated."""
    if not is_compound(name):
        return [(name, 1.0)]
    old, _, rest = name.partition(SEPARATOR)
    new, mark, share_text = rest.partition(SHARE_MARK)
    try:
        share = float(share_text)
    except ValueError:
        share = -1.0
    if not (old and new and mark) or not 0.0 < share < 1.0:
        raise ValueError(f"bad compound world name {name!r}; expected e.g. land>water@0.250")
    return [(old, 1.0 - share), (new, share)]


def new_share(name: str) -> float:
    """The share of the last world of ``name`` (1.0 for a pure world)."""
    return parts(name)[-1][1]


def transition(environment: str) -> tuple[str, ...]:
    """The worlds of a treatment's environment in order: ``(LAND.name,)`` for a pure world,
    ``(LAND.name, WATER.name)`` for the transition ``land-water``; ValueError for an unknown
    world."""
    parts_ = tuple(environment.split(TRANSITION))
    if len(parts_) > 2 or len(set(parts_)) != len(parts_):
        raise ValueError(f"bad environment {environment!r}; expected a world or two joined by {TRANSITION}")
    for world in parts_:
        if world not in names(evolve=True):
            raise ValueError(f"unknown world {world!r}; choose one of {', '.join(names(evolve=True))}")
    return parts_


def is_transition(environment: str) -> bool:
    return TRANSITION in environment


def between(old: str, new: str) -> str:
    """The abrupt transition from world ``old`` to world ``new`` (``land-water``)."""
    return f"{old}{TRANSITION}{new}"


def environments() -> tuple[str, ...]:
    """Every treatment environment: the evolvable worlds, then each ordered pair of them as a
    transition (``land``, ``water``, ``land-water``, ``water-land``, ...)."""
    pure = names(evolve=True)
    return pure + tuple(between(a, b) for a in pure for b in pure if a != b)


def final(environment: str) -> str:
    """The world a treatment's environment ends in (``land-water`` -> ``water``)."""
    return environment.split(TRANSITION)[-1]


def schedule_entries(text: str) -> tuple[list[tuple[str, int]], list[int]]:
    """The ``(world, first generation)`` entries and switch-over spans of a schedule's text
    ``land:0,water:50+10`` (``evolution.schedule.Schedule.parse`` checks them); ValueError
    naming the problem."""
    if not isinstance(text, str) or not text.strip():
        raise ValueError(f"schedule: empty text {text!r}; expected e.g. land:0,water:50")
    entries, spans = [], []
    for part in text.split(","):
        environment, colon, first = part.strip().partition(":")
        if not colon or not environment:
            raise ValueError(f"schedule: {part.strip()!r} is not environment:first_generation")
        first, plus, span = first.partition("+")
        try:
            generation = int(first)
            spans.append(int(span) if plus else 0)
        except ValueError:
            raise ValueError(
                f"schedule: first generation (+ switch-over) of {environment} is not an integer "
                f"({part.strip()!r})"
            ) from None
        entries.append((environment, generation))
    return entries, spans

