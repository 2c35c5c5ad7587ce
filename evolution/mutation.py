"""Structural and parametric mutations of a CPPN (docs/spec.md section 2), mutation only.

Each operator is a pure function ``(cppn, rng) -> cppn | None`` (None: not applicable, e.g.
no hidden node to remove). :func:`mutate_cppn` picks one applicable operator uniformly at
random. Every operator keeps the invariants checked by :meth:`CPPN.validate` (acyclic, no
dangling or duplicate links, inputs without incoming and outputs without outgoing links).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from softevo.evolution.cppn import CPPN, HIDDEN_ACTIVATIONS, Link, Node

WEIGHT_SIGMA = 0.5
"""Standard deviation of the Gaussian added by a weight change."""


def add_node(cppn: CPPN, rng: np.random.Generator) -> CPPN | None:
    """Split a random link s->t into s->h (weight 1) and h->t (old weight), h hidden."""
    if not cppn.links:
        return None
    index = int(rng.integers(len(cppn.links)))
    old = cppn.links[index]
    node = Node(cppn.next_node_id(), "hidden", str(rng.choice(HIDDEN_ACTIVATIONS)))
    links = cppn.links[:index] + cppn.links[index + 1 :]
    links += (Link(old.source, node.id, 1.0), Link(node.id, old.target, old.weight))
    return CPPN(cppn.nodes + (node,), links)


def remove_node(cppn: CPPN, rng: np.random.Generator) -> CPPN | None:
    """Remove a random hidden node and every link touching it."""
    if not cppn.hidden_ids:
        return None
    gone = int(rng.choice(cppn.hidden_ids))
    nodes = tuple(n for n in cppn.nodes if n.id != gone)
    links = tuple(lk for lk in cppn.links if gone not in (lk.source, lk.target))
    return CPPN(nodes, links)


def candidate_links(cppn: CPPN) -> list[tuple[int, int]]:
    """Every (source, target) a new link could join without a duplicate or a cycle."""
    existing = {(lk.source, lk.target) for lk in cppn.links}
    sources = [n.id for n in cppn.nodes if n.role != "output"]
    targets = [n.id for n in cppn.nodes if n.role != "input"]
    pairs = []
    for target in targets:
        downstream = cppn.reachable_from(target)  # a link s->t closes a cycle iff t reaches s
        pairs += [
            (s, target) for s in sources if s not in downstream and (s, target) not in existing
        ]
    return pairs


def add_link(cppn: CPPN, rng: np.random.Generator) -> CPPN | None:
    """Add a link between a random unconnected pair that keeps the graph acyclic."""
    pairs = candidate_links(cppn)
    if not pairs:
        return None
    source, target = pairs[int(rng.integers(len(pairs)))]
    return CPPN(cppn.nodes, cppn.links + (Link(source, target, float(rng.uniform(-1, 1))),))


def remove_link(cppn: CPPN, rng: np.random.Generator) -> CPPN | None:
    """Remove a random link."""
    if not cppn.links:
        return None
    index = int(rng.integers(len(cppn.links)))
    return CPPN(cppn.nodes, cppn.links[:index] + cppn.links[index + 1 :])


def change_weight(cppn: CPPN, rng: np.random.Generator) -> CPPN | None:
    """Add N(0, WEIGHT_SIGMA^2) to a random link's weight."""
    if not cppn.links:
        return None
    index = int(rng.integers(len(cppn.links)))
    old = cppn.links[index]
    new = Link(old.source, old.target, float(old.weight + rng.normal(0.0, WEIGHT_SIGMA)))
    return CPPN(cppn.nodes, cppn.links[:index] + (new,) + cppn.links[index + 1 :])


def change_activation(cppn: CPPN, rng: np.random.Generator) -> CPPN | None:
    """Give a random hidden node a different activation function."""
    if not cppn.hidden_ids:
        return None
    target = int(rng.choice(cppn.hidden_ids))
    old = cppn.node_by_id[target]
    choices = [a for a in HIDDEN_ACTIVATIONS if a != old.activation]
    new = Node(old.id, old.role, str(rng.choice(choices)), old.name)
    return CPPN(tuple(new if n.id == target else n for n in cppn.nodes), cppn.links)


OPERATORS: dict[str, Callable[[CPPN, np.random.Generator], CPPN | None]] = {
    "add_node": add_node,
    "remove_node": remove_node,
    "add_link": add_link,
    "remove_link": remove_link,
    "change_weight": change_weight,
    "change_activation": change_activation,
}


def mutate_cppn(cppn: CPPN, rng: np.random.Generator) -> tuple[CPPN, str]:
    """Apply one operator, chosen uniformly among those applicable; returns (child, op name).

    Operators are tried in a random order and the first applicable one is used. One always
    applies: with a link, ``change_weight``; without, ``add_link`` (input -> output).
    """
    for index in rng.permutation(len(OPERATORS)):
        name = list(OPERATORS)[int(index)]
        child = OPERATORS[name](cppn, rng)
        if child is not None:
            return child, name
    raise AssertionError("no applicable mutation")  # unreachable: a CPPN can always change
