"""``python -m hil_harness.cli``: the same entry point as the ``uvisi`` console script."""
from hil_harness.cli import run

run()
