"""A deployment's plugin (``SOFTEVO_PLUGINS=tests.service.plugin_option``): one new treatment
option, declared alone (``evolution.options.declare``): ``softevo run``, REST, the limits, the
stored settings and the report carry it with nothing else written."""

from softevo.evolution import options

DRAG_SCALE = options.declare(options.Option(
    "drag_scale", "evaluation", float, 1.0, least=0.1, most=100.0, limit=10.0, unit="x",
    help="a factor on the water's drag (a plugin's option)",
))
