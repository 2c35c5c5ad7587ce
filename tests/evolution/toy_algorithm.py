"""A toy algorithm built from the operators alone (``evolution.operators``): a (mu + 2 mu)
scheme, two mutated children per survivor, cut back by truncation on distance alone. Tests
register it in their own process (``register_toy``); ``tests.service.plugin_algorithm`` is
the deployment plugin that registers it in a ``softevo`` process."""

from __future__ import annotations

from contextlib import contextmanager

from softevo.evolution import algorithm
from softevo.evolution.operators import mutate_each, truncation

NAME = "toy"


def toy() -> algorithm.Algorithm:
    return algorithm.Algorithm(NAME, truncation("distance"), (mutate_each, mutate_each), (),
                               "(mu + 2 mu) truncation on distance alone")


@contextmanager
def register_toy():
    """The toy registered for the ``with`` block, unregistered after."""
    record = algorithm.register(toy())
    try:
        yield record
    finally:
        algorithm.unregister(NAME)
