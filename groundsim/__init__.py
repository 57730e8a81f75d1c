"""groundsim: the world the UVISI flight code sees -- real Hipparcos 2 stars, satellites, launches and
aurora, the four UVISI imagers, the MSX spacecraft and scenario files -- plus ground assessment tools
(``groundsim.assess``). Never imports ``flightsw.ip`` / ``flightsw.tp``.

Entry points: ``Scenario.load(name_or_path, seed=None)`` -> ``.frames()`` / ``.world()``;
``RealSequence.load(path)``.
"""
# importing flightsw keys numba's cache on the sources (flightsw.numba_cache) before any kernel
# below is defined
from flightsw.numba_cache import serialise_cache_writes

from .imagers import IMAGER_IDS, IMAGERS, Imager, get_imager
from .scenario import Scenario, ScenarioError

serialise_cache_writes()         # numba's cache, written by several processes at once: locked

__all__ = ["Scenario", "ScenarioError", "RealSequence", "StarCatalog", "Imager", "IMAGERS", "IMAGER_IDS",
           "get_imager", "World"]


def __getattr__(name):
    """The heavier parts load on first use (a command that only reads scenario files does not pay
    for SciPy and the renderer's kernels)."""
    if name == "World":
        from .world import World
        return World
    if name == "RealSequence":
        from .realdata import RealSequence
        return RealSequence
    if name == "StarCatalog":
        from .sky import StarCatalog
        return StarCatalog
    raise AttributeError(name)
