"""``python -m circuitsim`` runs the same command line as ``circuitsim``."""

from circuitsim.cli import run

run()
