"""What a first run has left to compile: the project's numba kernels a kernel reaches and the cache
does not hold yet (the compile bar's total).

numba compiles a kernel on its first call, and with it every kernel its code calls. The kernels a
compiled kernel reaches are read from its code: the global names it uses (and the attributes it
takes of a module), followed through other kernels and through plain Python functions of the
project (a 1750A operation's public function, whose numba overload calls the kernel its Python
body calls). A kernel whose cache index exists is counted as compiled already, with all it calls
(its cached code holds the kernels compiled into it: :func:`flightsw.numba_cache.callee_kernel`).

This reads the code, not numba's typing: the set can hold a kernel the call never compiles (a
branch of Python code it does not take); the compile bar then closes below its total. The test
holds it against the kernels numba compiles on an empty cache.
"""
from __future__ import annotations

import os
import types as pytypes

from flightsw.numba_cache import SOURCE_PACKAGES, is_callee_kernel

__all__ = ["PROJECT_PACKAGES", "reachable_kernels", "compiled_function", "is_cached",
           "uncached_kernels"]

#: the packages whose kernels the compile bar counts (numba's own are not counted): those the
#: kernels are made from, whose sources key the cache
PROJECT_PACKAGES = SOURCE_PACKAGES


def _is_project(obj) -> bool:
    mod = getattr(obj, "__module__", None) or ""
    return mod.split(".")[0] in PROJECT_PACKAGES


def _dispatcher_type():
    from numba.core.dispatcher import Dispatcher
    return Dispatcher


def _names(code) -> set:
    """The global and attribute names ``code`` and the functions nested in it use."""
    out = set(code.co_names)
    for c in code.co_consts:
        if isinstance(c, pytypes.CodeType):
            out |= _names(c)
    return out


def _referenced(func) -> list:
    """The objects ``func``'s code names: its globals, its closure's cells, and the attributes it
    takes of a project module it names (another package's attributes are not kernels of ours,
    and reading some warns: numpy 1.26's ``np.bool``)."""
    code = func.__code__
    g = func.__globals__
    names = _names(code)
    found = []
    for name in names:
        obj = g.get(name)
        if isinstance(obj, pytypes.ModuleType):
            if obj.__name__.split(".")[0] in PROJECT_PACKAGES:
                found.extend(getattr(obj, a) for a in names if hasattr(obj, a))
        elif obj is not None:
            found.append(obj)
    for cell in func.__closure__ or ():
        try:
            found.append(cell.cell_contents)
        except ValueError:              # an empty cell
            pass
    return found


def reachable_kernels(root, stop=None) -> list:
    """The project's kernels ``root`` reaches through its code, ``root`` included if it is one, in
    the order found: numba dispatchers and kernels compiled into their callers
    (:func:`flightsw.numba_cache.callee_kernel`). ``root``: a kernel or a Python function.
    ``stop(kernel)``: if given and true, that kernel is neither listed nor followed."""
    dispatcher = _dispatcher_type()
    seen_funcs, kernels, seen = set(), [], set()
    stack = [root]
    while stack:
        obj = stack.pop()
        if isinstance(obj, dispatcher) or is_callee_kernel(obj):
            if id(obj) in seen or not _is_project(obj.py_func):
                continue
            seen.add(id(obj))
            if stop is not None and stop(obj):
                continue
            kernels.append(obj)
            stack.extend(_referenced(obj.py_func))
        elif isinstance(obj, pytypes.FunctionType) and _is_project(obj):
            if id(obj) in seen_funcs:
                continue
            seen_funcs.add(id(obj))
            stack.extend(_referenced(obj))
    return kernels


def compiled_function(kernel):
    """The Python function numba compiles for ``kernel`` (and names in its compile events): a
    dispatcher's ``py_func``; the copy a kernel compiled into its callers is compiled from."""
    return kernel.inner if is_callee_kernel(kernel) else kernel.py_func


def is_cached(kernel) -> bool:
    """Whether numba's cache holds an index for ``kernel`` (it then loads, not compiles, the
    argument types the index lists); for a kernel compiled into its callers, for the copy they
    compile."""
    if is_callee_kernel(kernel):
        from numba.core.caching import FunctionCache
        cache = FunctionCache(kernel.inner)
    else:
        cache = getattr(kernel, "_cache", None)
    impl = getattr(cache, "_cache_file", None)
    path = getattr(impl, "_index_path", None)
    return bool(path) and os.path.exists(path)


def uncached_kernels(root) -> list:
    """The kernels a call of ``root`` compiles on the present cache: :func:`reachable_kernels` of
    ``root`` up to the cached ones (which load with the code of all they call)."""
    return reachable_kernels(root, stop=is_cached)
