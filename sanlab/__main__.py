"""``python -m sanlab`` runs the command line."""

from sanlab.cli import run

run()
