"""The old dotted path of :mod:`hil_harness.tuning.closed`, kept for campaign files that name
``hil_harness.tuning_closed:identification_job`` (new files name ``hil_harness.tuning.closed``)."""
from hil_harness.tuning.closed import *  # noqa: F401,F403
from hil_harness.tuning.closed import __all__  # noqa: F401
