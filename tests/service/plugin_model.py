"""A deployment's plugin (``SOFTEVO_PLUGINS=tests.service.plugin_model``): one new physics
model, the paper's engine without its tenfold angular damping, registered once."""

from softevo.sim import models

SOFT_FORK = models.register(models.Model(
    "soft-fork", models.options("voxcad-land-water").replace(rotation_damping=1.0), 0.7, 0.14,
    "the paper's engine without its tenfold angular damping",
))
