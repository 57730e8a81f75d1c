"""flightsw: the emulated MSX flight software (the UVISI image processor, the track processor, their
messages and arithmetic)."""
from flightsw.numba_cache import (defer_blas_check, key_cache_on_sources, load_without_refresh,
                                  serialise_cache_writes)

key_cache_on_sources()           # numba's cache: a folder per version of the sources
serialise_cache_writes()         # numba's cache, written by several processes at once: locked
defer_blas_check()               # numba's BLAS check without importing scipy.linalg
load_without_refresh()           # a cache load starts numba's runtime, not a refresh
