"""``python -m roughsense.cli``: the same as the ``roughsense`` command."""
from . import run

run()
