"""The trait registry (``evolution.traits``): what a registration may say, and what the
lists that storage, REST and the command line are generated from hold."""

from __future__ import annotations

import math
from types import SimpleNamespace

import pytest

from softevo.evolution import traits


@pytest.fixture
def registered():
    """Two traits registered for one test: one that fails on an empty body, one never finite."""
    added = (
        traits.register(traits.Trait("width", "width (voxels)", lambda p: 1 / p.size, header="wide")),
        traits.register(traits.Trait("wild", "wild", lambda p: math.nan, along_lines=False)),
    )
    yield added
    for trait in added:
        traits.unregister(trait.name)


def test_the_built_in_traits_are_the_columns_with_their_records():
    assert traits.columns() == (
        "distance", "active_share", "voxel_count", "frequency", "symmetry", "branching", "shape_entropy",
    )  # fmt: skip
    required = {t.name for t in traits.column_traits() if t.required}
    assert required == {"distance", "active_share", "voxel_count"}
    assert [t.name for t in traits.column_traits() if t.integer] == ["voxel_count"]
    assert traits.headers()["voxel_count"] == "voxels" and traits.headers()["distance"] == "distance"
    assert traits.registered() == ()


def test_registered_traits_join_every_list_but_the_columns(registered):
    assert traits.names()[-2:] == ("width", "wild")
    assert traits.registered() == ("width", "wild")
    assert "width" in traits.along_lines() and "wild" not in traits.along_lines()
    assert "width" not in traits.columns() and traits.headers()["width"] == "wide"
    assert traits.computed(SimpleNamespace(size=4)) == {"width": 0.25, "wild": None}  # NaN: no value
    assert traits.computed(SimpleNamespace(size=0)) == {"width": None, "wild": None}  # a failure: no value


@pytest.mark.parametrize(
    "trait",
    [
        traits.Trait("no_compute", "x"),
        traits.Trait("columned", "x", lambda p: 1.0, column=True),
        traits.Trait("always", "x", lambda p: 1.0, required=True),
        traits.Trait("Upper", "x", lambda p: 1.0),
        traits.Trait("voxel_count", "x", lambda p: 1.0),
    ],
)
def test_a_registration_that_storage_could_not_follow_is_refused(trait):
    with pytest.raises(ValueError):
        traits.register(trait)
    assert traits.registered() == ()
