"""``python -m sanlab`` runs the command line."""

from sanlab.cli import app

app(prog_name="sanlab")
