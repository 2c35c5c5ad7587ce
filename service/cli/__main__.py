"""``python -m softevo.service.cli``: the ``softevo`` command."""

from softevo.service.cli import main

main()
