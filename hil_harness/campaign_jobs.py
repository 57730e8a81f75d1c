"""The old dotted path of :mod:`hil_harness.campaign.jobs`, kept for campaign files that name
``hil_harness.campaign_jobs:<job>`` (new files name ``hil_harness.campaign.jobs:<job>``)."""
from hil_harness.campaign.jobs import *  # noqa: F401,F403
from hil_harness.campaign.jobs import __all__  # noqa: F401
