"""``python -m driftmap``: the command line (what ``driftmap serve`` uses to start its worker)."""

from driftmap.cli import app

app(prog_name="driftmap")
