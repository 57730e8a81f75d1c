"""flightsw: the emulated MSX flight software (the UVISI image processor, the track processor, their
messages and arithmetic)."""
from flightsw.numba_cache import serialise_cache_writes

serialise_cache_writes()         # numba's cache, written by several processes at once: locked
