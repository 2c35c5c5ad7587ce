"""Shared helpers for the evolution tests."""

from __future__ import annotations

import numpy as np
import pytest

from softevo.evolution.cppn import CPPN, INPUT_NAMES, Link, Node


def hand_cppn(output_names, links, hidden=()):
    """A CPPN from explicit parts: inputs 0..4, outputs 5.., hidden given as (id, activation)."""
    nodes = [Node(i, "input", "identity", n) for i, n in enumerate(INPUT_NAMES)]
    nodes += [Node(5 + o, "output", "sigmoid", n) for o, n in enumerate(output_names)]
    nodes += [Node(i, "hidden", a) for i, a in hidden]
    return CPPN(tuple(nodes), tuple(Link(s, t, w) for s, t, w in links))


@pytest.fixture
def rng():
    return np.random.default_rng(12345)
