"""Compositional Pattern Producing Networks: immutable genome data and vectorised expression.

A :class:`CPPN` is plain data: a tuple of :class:`Node` (id, role, activation) and a tuple of
:class:`Link` (source id, target id, weight). The graph is acyclic; inputs have no incoming
links and outputs no outgoing ones.

Inputs, per voxel (i, j, k) of a workspace of shape (nx, ny, nz):
- ``x, y, z``: the voxel index mapped linearly onto [-1, 1] (a dimension of size 1 gives 0);
- ``d``: Euclidean distance from the workspace centre in those coordinates divided by
  sqrt(3), so the centre is 0 and a corner of the workspace is 1 (range [0, 1]);
- ``bias``: 1.

Hidden nodes apply one of :data:`ACTIVATIONS`. Output nodes always apply the bipolar sigmoid
``2 / (1 + exp(-s)) - 1`` (evosoro's convention), so every output lies in (-1, 1).
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from functools import cached_property, lru_cache
from typing import Any

import numpy as np

INPUT_NAMES: tuple[str, ...] = ("x", "y", "z", "d", "bias")
OUTPUT_ACTIVATION = "sigmoid"


def _sigmoid(s: np.ndarray) -> np.ndarray:
    """Bipolar sigmoid in (-1, 1); equals tanh(s/2), written so it never overflows."""
    return np.tanh(0.5 * s)


def _gaussian(s: np.ndarray) -> np.ndarray:
    """Bipolar Gaussian 2 exp(-s^2) - 1 in (-1, 1], so it can produce either sign."""
    return 2.0 * np.exp(-np.square(s)) - 1.0


def _sqrt_abs(s: np.ndarray) -> np.ndarray:
    return np.sqrt(np.abs(s))


ACTIVATIONS: dict[str, Callable[[np.ndarray], np.ndarray]] = {
    "sigmoid": _sigmoid,
    "sin": np.sin,
    "abs": np.abs,
    "neg_abs": lambda s: -np.abs(s),
    "square": np.square,
    "neg_square": lambda s: -np.square(s),
    "sqrt_abs": _sqrt_abs,
    "neg_sqrt_abs": lambda s: -_sqrt_abs(s),
    "gaussian": _gaussian,
    "identity": lambda s: s,
}
HIDDEN_ACTIVATIONS: tuple[str, ...] = tuple(ACTIVATIONS)


class GenomeError(ValueError):
    """A CPPN that breaks an invariant (cycle, dangling link, unknown activation...)."""


@dataclass(frozen=True)
class Node:
    """One CPPN node. ``role`` is "input", "output" or "hidden"."""

    id: int
    role: str
    activation: str
    name: str = ""


@dataclass(frozen=True)
class Link:
    """A weighted connection ``source -> target``."""

    source: int
    target: int
    weight: float


@dataclass(frozen=True)
class CPPN:
    """An immutable CPPN genome. Node ids are unique ints; links are unique (source, target)."""

    nodes: tuple[Node, ...]
    links: tuple[Link, ...]

    # ---- structure -------------------------------------------------------------------------
    @cached_property
    def node_by_id(self) -> dict[int, Node]:
        return {node.id: node for node in self.nodes}

    @cached_property
    def input_ids(self) -> tuple[int, ...]:
        return tuple(n.id for n in self.nodes if n.role == "input")

    @cached_property
    def output_ids(self) -> tuple[int, ...]:
        return tuple(n.id for n in self.nodes if n.role == "output")

    @cached_property
    def hidden_ids(self) -> tuple[int, ...]:
        return tuple(n.id for n in self.nodes if n.role == "hidden")

    @property
    def output_names(self) -> tuple[str, ...]:
        return tuple(self.node_by_id[i].name for i in self.output_ids)

    def next_node_id(self) -> int:
        return max(n.id for n in self.nodes) + 1

    @cached_property
    def topological_order(self) -> tuple[int, ...]:
        """Node ids, every source before its targets (Kahn); raises GenomeError on a cycle."""
        indegree = {n.id: 0 for n in self.nodes}
        children: dict[int, list[int]] = {n.id: [] for n in self.nodes}
        for link in self.links:
            indegree[link.target] += 1
            children[link.source].append(link.target)
        ready = [n.id for n in self.nodes if indegree[n.id] == 0]
        order: list[int] = []
        while ready:
            node_id = ready.pop(0)
            order.append(node_id)
            for child in children[node_id]:
                indegree[child] -= 1
                if indegree[child] == 0:
                    ready.append(child)
        if len(order) != len(self.nodes):
            raise GenomeError("links form a cycle")
        return tuple(order)

    def reachable_from(self, node_id: int) -> set[int]:
        """Ids reachable from ``node_id`` along links (including itself)."""
        children: dict[int, list[int]] = {}
        for link in self.links:
            children.setdefault(link.source, []).append(link.target)
        seen, stack = {node_id}, [node_id]
        while stack:
            for child in children.get(stack.pop(), ()):
                if child not in seen:
                    seen.add(child)
                    stack.append(child)
        return seen

    def validate(self) -> None:
        """Raise GenomeError unless every invariant holds."""
        ids = [n.id for n in self.nodes]
        if len(set(ids)) != len(ids):
            raise GenomeError("duplicate node ids")
        if tuple(self.node_by_id[i].name for i in self.input_ids) != INPUT_NAMES:
            raise GenomeError(f"inputs must be {INPUT_NAMES}")
        if not self.output_ids:
            raise GenomeError("no output node")
        for node in self.nodes:
            if node.role not in ("input", "output", "hidden"):
                raise GenomeError(f"node {node.id}: unknown role {node.role!r}")
            if node.activation not in ACTIVATIONS:
                raise GenomeError(f"node {node.id}: unknown activation {node.activation!r}")
        pairs = set()
        for link in self.links:
            if link.source not in self.node_by_id or link.target not in self.node_by_id:
                raise GenomeError(f"dangling link {link.source}->{link.target}")
            if self.node_by_id[link.target].role == "input":
                raise GenomeError(f"link into input node {link.target}")
            if self.node_by_id[link.source].role == "output":
                raise GenomeError(f"link out of output node {link.source}")
            if (link.source, link.target) in pairs:
                raise GenomeError(f"duplicate link {link.source}->{link.target}")
            if not math.isfinite(link.weight):
                raise GenomeError(f"non-finite weight on {link.source}->{link.target}")
            pairs.add((link.source, link.target))
        self.topological_order  # noqa: B018 - raises on a cycle

    # ---- JSON ------------------------------------------------------------------------------
    def to_dict(self) -> dict[str, Any]:
        """``{"nodes": [[id, role, activation, name], ...], "links": [[source, target,
        weight], ...]}``: the same dict at every call (a CPPN never changes; the run's state,
        its tasks and its rows all write it), so read it, do not change it."""
        return self._plain

    @cached_property
    def _plain(self) -> dict[str, Any]:
        return {
            "nodes": [[n.id, n.role, n.activation, n.name] for n in self.nodes],
            "links": [[lk.source, lk.target, lk.weight] for lk in self.links],
        }

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> CPPN:
        nodes = tuple(Node(int(i), str(r), str(a), str(nm)) for i, r, a, nm in data["nodes"])
        links = tuple(Link(int(s), int(t), float(w)) for s, t, w in data["links"])
        cppn = cls(nodes, links)
        cppn.validate()
        return cppn

    def to_json(self) -> str:
        """Exact JSON: floats are written with repr precision, so from_json(to_json(g)) == g."""
        return json.dumps(self.to_dict())

    @classmethod
    def from_json(cls, text: str) -> CPPN:
        return cls.from_dict(json.loads(text))

    # ---- evaluation plan -------------------------------------------------------------------
    @cached_property
    def _plan(self) -> tuple[list[int], list[tuple[int, np.ndarray, np.ndarray, str]], dict]:
        """(input rows, [(row, source rows, weights, activation)], {output name: row})."""
        order = self.topological_order
        row = {node_id: r for r, node_id in enumerate(order)}
        incoming: dict[int, list[Link]] = {}
        for link in self.links:
            incoming.setdefault(link.target, []).append(link)
        inputs = [row[i] for i in self.input_ids]
        steps = []
        for node_id in order:
            node = self.node_by_id[node_id]
            if node.role == "input":
                continue
            links = incoming.get(node_id, [])
            sources = np.array([row[lk.source] for lk in links], dtype=np.intp)
            weights = np.array([lk.weight for lk in links], dtype=np.float64)
            activation = OUTPUT_ACTIVATION if node.role == "output" else node.activation
            steps.append((row[node_id], sources, weights, activation))
        outputs = {self.node_by_id[o].name: row[o] for o in self.output_ids}
        return inputs, steps, outputs


def minimal_cppn(output_names: tuple[str, ...], weights: np.ndarray) -> CPPN:
    """Every input linked to every output; ``weights`` shape (n_inputs, n_outputs)."""
    inputs = tuple(Node(i, "input", "identity", name) for i, name in enumerate(INPUT_NAMES))
    first = len(INPUT_NAMES)
    outputs = tuple(
        Node(first + o, "output", OUTPUT_ACTIVATION, name) for o, name in enumerate(output_names)
    )
    links = tuple(
        Link(i, first + o, float(weights[i, o]))
        for o in range(len(output_names))
        for i in range(len(INPUT_NAMES))
    )
    return CPPN(inputs + outputs, links)


@lru_cache(maxsize=32)
def workspace_inputs(shape: tuple[int, int, int]) -> np.ndarray:
    """Input matrix, shape (5, nx*ny*nz), rows x, y, z, d, bias, voxels in C (x-major) order."""
    axes = [np.linspace(-1.0, 1.0, n) if n > 1 else np.zeros(1) for n in shape]
    grid = np.meshgrid(*axes, indexing="ij")
    x, y, z = (g.ravel() for g in grid)
    d = np.sqrt(x * x + y * y + z * z) / np.sqrt(3.0)
    inputs = np.stack([x, y, z, d, np.ones_like(x)])
    inputs.setflags(write=False)
    return inputs


def express(cppn: CPPN, workspace_shape: tuple[int, int, int]) -> dict[str, np.ndarray]:
    """Query ``cppn`` at every voxel: {output name: array of ``workspace_shape``, in (-1, 1)}.

    Vectorised over voxels: one NumPy weighted sum and one activation per node.
    """
    shape = tuple(int(n) for n in workspace_shape)
    inputs = workspace_inputs(shape)
    input_rows, steps, output_rows = cppn._plan
    values = np.empty((len(cppn.nodes), inputs.shape[1]))
    values[input_rows] = inputs
    for row, sources, weights, activation in steps:
        total = weights @ values[sources] if len(sources) else np.zeros(inputs.shape[1])
        values[row] = ACTIVATIONS[activation](total)
    return {name: values[row].reshape(shape) for name, row in output_rows.items()}
