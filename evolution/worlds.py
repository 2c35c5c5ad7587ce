"""World names: a pure world (``land``, ``water``) or a compound world of a gradual transition.

A gradual transition moves a population from world A to world B over a span of ``G``
generations (``--switch-over G``). At the ``k``-th generation of the span (``k = 0..G-1``)
every evaluation runs in the compound world ``A>B@s`` with ``s = (k + 1) / (G + 1)``: a share
``1 - s`` of its actuation cycles in A, then ``s`` in B (``worker.tasks.scenes_of`` builds the
two scenes, ``worker.tasks.compound_outcome`` adds their distances). The share is written
with three decimals and read back from the name, so the name alone (stored in
``evaluations.environment``, at most 20 characters) says exactly what was simulated.

``compound(a, b, s)`` makes a name, ``parts(name)`` reads one back as ``[(world, share),
...]`` (one part of share 1.0 for a pure world).
"""

from __future__ import annotations

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
