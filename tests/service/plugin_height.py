"""A deployment's plugin (``SOFTEVO_PLUGINS=tests.service.plugin_height``): one new trait,
the body's height in voxels, registered once."""

from softevo.evolution import traits


def height(phenotype) -> float:
    """Layers of the body that hold a voxel (z is the last axis)."""
    return float(phenotype.body.any(axis=(0, 1)).sum())


HEIGHT = traits.register(traits.Trait("height", "height (voxels)", height))
