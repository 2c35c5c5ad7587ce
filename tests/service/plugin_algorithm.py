"""A deployment's plugin (``SOFTEVO_PLUGINS=tests.service.plugin_algorithm``): one new
algorithm, the toy (mu + 2 mu) truncation on distance, registered once."""

from softevo.evolution import algorithm
from tests.evolution.toy_algorithm import toy

TOY = algorithm.register(toy())
