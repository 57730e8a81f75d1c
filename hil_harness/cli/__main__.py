"""``python -m hil_harness.cli``: the same entry point as the ``uvisi`` console script."""
import sys

from hil_harness.cli import main

sys.exit(main())
