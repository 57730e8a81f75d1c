"""Numba's on-disk cache made safe: keyed on the project's sources, and written by several
processes at once.

**Keyed on the sources.** numba keys each cached function on its own source file only: a kernel
keeps the code of every function it calls as it was when the kernel was compiled, until the
kernel's own file changes. After an update that changes a callee (a 1750A primitive, a filter) and
not its callers, the cached callers would still run the old callee: other words out, with no sign
of it (a limit numba's "Notes on Caching" state; seen here on 2026-11-29, when the cached
full-frame front end ran its 5x5 filter as it was before the filter's last change, at 2.6x the
time). :func:`key_cache_on_sources` points numba's cache at a folder named by a digest of every
Python file of the packages the kernels are made from (:data:`SOURCE_PACKAGES`; the command line's
modules, which no kernel reaches, left out: :data:`NOT_KERNEL_SOURCES`), so that any change to them
compiles everything once, afresh. A ``NUMBA_CACHE_DIR`` set by the user is left alone (its keeping
is then the user's).

**Several processes.** ``uvisi`` compiles in two processes on a cold cache when the warm-up process
is on; campaigns run Dask workers.
Numba 0.68's cache (``numba.core.caching.IndexDataCacheFile.save``) reads a function's index,
picks the first unused data-file number and writes the index, then the data, with no lock: two
processes saving different signatures of one function at the same moment can both pick number 1,
so that the index names one signature's file while it holds the other's machine code. A later
process then runs code compiled for C-contiguous arrays on strided views, or the reverse (seen as
wrong opportunity-track states on a cold cache, 2026-11-28). :func:`serialise_cache_writes` wraps
``save`` in an exclusive ``fcntl.flock`` on a lock file beside the index, so each save reads the
index as the previous one left it and never reuses a number. Loading needs no lock: a data file is
written to a temporary name and renamed, and a number once in an index is never given to another
signature.

**One compile of a kernel at a time.** Two processes that miss the same kernel and argument types
in the cache would both compile them: a first run's warm-up process (:mod:`hil_harness.warmup`)
and the command it helps, or campaign workers. :func:`serialise_cache_writes` also wraps numba's
``Dispatcher.compile``: a process about to compile a cached kernel for argument types it has not
loaded takes an exclusive ``flock`` on a file named by the kernel's index and the types
(``<index>.<digest>.compiling``) and holds it until the kernel is compiled and saved. A process
that finds the lock taken waits for it (numba's event ``uvisi:compile-wait`` marks the wait, at
most :data:`COMPILE_WAIT_S`), then loads what the other saved, as numba's ``compile`` does first
anyway (numba types a recursive call without compiling the kernel again, so no process waits for
itself). Nothing about what is compiled changes; only who compiles it.

**Kernels compiled into their callers.** :func:`callee_kernel` marks a kernel that only other
kernels call: they compile it in without numba's wrappers, and Python calls reach it through a
separate dispatcher; the two copies are cached under different names. The copy the callers link is
kept as LLVM IR only (:func:`link_callee_copies_only`): no machine code of its own, and LLVM's
whole-module passes run once, in each caller.

**numba's BLAS check.** numba imports ``scipy.linalg`` in every process to learn whether BLAS is
there, though no kernel here calls it; :func:`defer_blas_check` has that check look for the file.

**Loading without a refresh.** numba refreshes its typing and target contexts before every load
from the cache, though a loaded kernel needs only its runtime; :func:`load_without_refresh` has a
load start the runtime alone, and leaves the refresh to the first compile, which makes its own.
"""
from __future__ import annotations

import fcntl
import functools
import hashlib
import os
import shutil
import types
from pathlib import Path

__all__ = ["serialise_cache_writes", "key_cache_on_sources", "source_digest", "cache_root",
           "KERNEL", "CALLEE", "IN_CALLERS", "callee_kernel", "is_callee_kernel", "dispatcher_of",
           "link_callee_copies_only", "SOURCE_PACKAGES", "NOT_KERNEL_SOURCES", "KEEP_OLD",
           "COMPILE_WAIT_S", "COMPILE_WAIT_EVENT", "compile_lock_path", "compile_for_callers",
           "defer_blas_check", "scipy_blas_installed", "load_without_refresh"]

#: the numba options every kernel of the project is compiled with (``@njit(**KERNEL)``, and the
#: ``jit_options`` of its overloads): cached on disk, and without the C-callable wrapper numba
#: otherwise adds to each compiled function for use as a first-class function value (a kernel
#: passed as a typed function pointer, ``numba.cfunc``), which nothing here does. Each wrapper is
#: one more function for LLVM to optimise and turn into machine code: dropping them took a first
#: run's compile 6 % less CPU (docs/validation.md, "The first run"). What a kernel computes does
#: not change. The Python-callable wrapper stays for the kernels Python calls; a kernel that only
#: kernels call is a :func:`callee_kernel`, compiled into its callers without it.
KERNEL = {"cache": True, "no_cfunc_wrapper": True}

#: the packages whose Python the compiled kernels are made from: the cache is keyed on all of it
SOURCE_PACKAGES = ("flightsw", "groundsim", "hil_harness")
#: folders left out of the digest: the command line, which no library module imports (a code rule,
#: tests/test_code_rules.py), so no kernel calls its functions or reads its globals; editing a
#: command compiles nothing again
NOT_KERNEL_SOURCES = ("hil_harness/cli",)
#: cache folders of other sources kept beside the current one (a checkout switched back and forth
#: recompiles nothing); older ones are removed when a new one is made
KEEP_OLD = 2
#: the project's root: the folder holding the packages
_ROOT = Path(__file__).resolve().parents[1]
#: the most seconds a process waits for another that compiles the same kernel and argument types
#: before compiling them itself (the longest compile, the IP's frame kernel, takes ~45 s of one
#: core on the slow development host)
COMPILE_WAIT_S = 300.0
#: numba event kind triggered around such a wait (``data``: the dispatcher and its argument types)
COMPILE_WAIT_EVENT = "uvisi:compile-wait"


def source_digest(root: Path = _ROOT, packages=SOURCE_PACKAGES,
                  leave_out=NOT_KERNEL_SOURCES) -> str:
    """The first 16 hex digits of the SHA-256 of every ``*.py`` file under ``root / package`` for
    each of ``packages`` but those under a folder of ``leave_out`` (paths relative to ``root``):
    its path relative to ``root`` and its bytes, in sorted path order."""
    h = hashlib.sha256()
    for pkg in packages:
        for f in sorted((Path(root) / pkg).rglob("*.py")):
            rel = f.relative_to(root).as_posix()
            if any(rel.startswith(d.rstrip("/") + "/") for d in leave_out):
                continue
            h.update(rel.encode() + b"\0")
            h.update(f.read_bytes() + b"\0")
    return h.hexdigest()[:16]


def cache_root(root: Path = _ROOT) -> Path:
    """Where the source-keyed folders go: ``root/.numba_cache`` if ``root`` is writable (a
    checkout), else ``$XDG_CACHE_HOME/uvisi/numba`` (``~/.cache/uvisi/numba``)."""
    if os.access(root, os.W_OK):
        return Path(root) / ".numba_cache"
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return Path(base) / "uvisi" / "numba"


def _drop_numba_default_cache(root: Path, packages) -> None:
    """Remove numba's index, data and lock files (``*.nbi``, ``*.nbc``, ``*.nbi.lock``) from the
    ``__pycache__`` folders under ``root / package``: numba's default cache, from before the
    cache was keyed on the sources."""
    for pkg in packages:
        for f in (root / pkg).rglob("__pycache__/*.nb[ic]*"):
            try:
                f.unlink()
            except OSError:
                pass


def _prune(top: Path, here: Path) -> None:
    """Remove the folders in ``top`` but ``here`` and the :data:`KEEP_OLD` most recently used
    others (one another process removes first is passed over)."""
    def used(d):
        try:
            return d.stat().st_mtime
        except OSError:
            return 0.0
    others = sorted((d for d in top.iterdir() if d.is_dir() and d != here), key=used,
                    reverse=True)
    for d in others[KEEP_OLD:]:
        shutil.rmtree(d, ignore_errors=True)


def key_cache_on_sources(root: Path = _ROOT, packages=SOURCE_PACKAGES) -> Path | None:
    """Point numba's cache at ``cache_root(root) / source_digest(root, packages)`` (through
    ``NUMBA_CACHE_DIR``, which child processes inherit, and numba's config if numba is loaded),
    unless ``NUMBA_CACHE_DIR`` is set already. A new folder removes all but the :data:`KEEP_OLD`
    most recently used others, and the files numba's default cache left in the packages'
    ``__pycache__`` folders (nothing reads them now). Returns the folder, or None when the user's
    setting stands. Call before any kernel is defined: numba reads the setting when it sets up a
    kernel's cache. Where no folder can be made, numba's default stands (None)."""
    if os.environ.get("NUMBA_CACHE_DIR"):
        return None
    top = cache_root(Path(root))
    here = top / source_digest(root, packages)
    new = not here.is_dir()
    try:
        here.mkdir(parents=True, exist_ok=True)
        os.utime(here)                              # most recently used: kept when pruning
    except OSError:                                 # nowhere to write: numba's own default
        return None
    if new:
        _prune(top, here)
        _drop_numba_default_cache(Path(root), packages)
    os.environ["NUMBA_CACHE_DIR"] = str(here)
    import sys
    config = sys.modules.get("numba.core.config")
    if config is not None:
        config.CACHE_DIR = str(here)
    return here


def serialise_cache_writes() -> None:
    """Install the locked ``save`` and the compile lock (the module's docstring): each now if its
    numba module is loaded, else when it is (a package that imports this does not import numba
    by itself: ``uvisi scenarios`` never loads it). Idempotent."""
    _patch_when_loaded("numba.core.caching", _lock_saves)
    _patch_when_loaded("numba.core.dispatcher", _lock_compiles)


def _patch_when_loaded(name: str, patch) -> None:
    """Call ``patch`` on the module ``name`` now if it is loaded, else once it is (once)."""
    import sys
    mod = sys.modules.get(name)
    if mod is not None:
        patch(mod)
    elif not any(isinstance(f, _PatchOnImport) and (f.name, f.patch) == (name, patch)
                 for f in sys.meta_path):
        sys.meta_path.insert(0, _PatchOnImport(name, patch))


def defer_blas_check() -> None:
    """Have numba find whether SciPy's BLAS is installed without importing it, at the check it
    makes once a process; numba's own ``ensure_blas`` still runs wherever a kernel needs BLAS.
    Idempotent; does nothing once ``numba.np.arraymath`` is loaded (numba has checked by then).

    ``numba.np.arraymath`` calls ``numba.np.linalg.ensure_blas()`` as it is imported (by the first
    compile or cache load of each process) to learn whether ``np.dot`` and its kin may call BLAS.
    That imports ``scipy.linalg`` (for ``scipy.linalg.cython_blas``), which starts OpenBLAS too:
    ~0.1-0.15 s of wall time and ~0.25 s of CPU of a warm ``uvisi event`` (5-7 % and 9-11 %,
    BENCHMARKS.md), though no kernel here calls BLAS (none of their cached code calls numba's
    BLAS wrappers). Here that first call answers whether the ``cython_blas`` extension is
    installed (:func:`scipy_blas_installed`) and puts numba's function back: a kernel that uses
    BLAS calls it as it compiles, which imports SciPy's BLAS and checks its integer width, as
    before. What a process that only loads such a kernel from the cache skips is that width check
    (the process that compiled it made it)."""
    import sys
    if "numba.np.arraymath" not in sys.modules:
        _patch_when_loaded("numba.np.linalg", _check_blas_without_import)


def load_without_refresh() -> None:
    """Have numba's cache load a kernel with its runtime started (``rtsys.initialize``) instead of
    a refresh of its typing and target contexts. Idempotent.

    numba's ``Cache.load_overload`` refreshes the target context before every load, to make sure
    it is initialised: each refresh runs the import statements of its ~30 lowering modules and
    installs their registries again, and the typing context's as well (the first also imports
    the modules). The 23 loads of a warm ``uvisi event`` took 0.44-0.60 s with the refreshes and
    0.34-0.45 s without; the command ran 0.06-0.15 s faster (BENCHMARKS.md). A kernel loaded from
    the cache is machine code: the one thing it needs of that refresh is the runtime (NRT) it
    calls, which ``rtsys.initialize`` starts, once a process, as the refresh does. Anything that
    compiles goes through numba's ``CompilerBase``, which refreshes both contexts first, so a
    kernel compiled after loads finds every registry in place. What a kernel computes does not
    change. What is saved is the repeated refreshing, not numba's imports: the environment of
    each numba function compiled into a kernel names that function's module, imported as the
    kernel is read (a warm event's process still imports every module a refresh would,
    ``numba.np.arraymath`` and its BLAS check, deferred by :func:`defer_blas_check`, included)."""
    _patch_when_loaded("numba.core.caching", _load_with_runtime_only)


def _load_with_runtime_only(caching) -> None:
    from numba.core.runtime import rtsys

    def make(refreshing):
        def load_overload(self, sig, target_context):
            rtsys.initialize(target_context)
            with self._guard_against_spurious_io_errors():
                return self._load_overload(sig, target_context)
        return load_overload

    _replace_once(caching.Cache, "load_overload", make)


def scipy_blas_installed() -> bool:
    """Whether SciPy's ``scipy.linalg.cython_blas`` extension is installed, found without
    importing SciPy (a file ``scipy/linalg/cython_blas*`` beside SciPy's package)."""
    import importlib.util
    spec = importlib.util.find_spec("scipy")
    places = (spec.submodule_search_locations or []) if spec is not None else []
    return any(any(Path(p, "linalg").glob("cython_blas*")) for p in places)


def _check_blas_without_import(linalg) -> None:
    real = getattr(linalg, "ensure_blas", None)
    if real is None or getattr(real, "uvisi_deferred", False):
        return

    def ensure_blas():
        linalg.ensure_blas = real           # every later call is numba's own
        if not scipy_blas_installed():
            raise ImportError("scipy 0.16+ is required for linear algebra")
    ensure_blas.uvisi_deferred = True
    linalg.ensure_blas = ensure_blas


class _PatchOnImport:
    """A meta-path finder that lets the module ``name`` load as usual, then calls ``patch`` on
    it."""

    def __init__(self, name: str, patch):
        self.name, self.patch = name, patch

    def find_spec(self, name, path=None, target=None):
        if name != self.name:
            return None
        import importlib.util
        import sys
        sys.meta_path.remove(self)
        spec = importlib.util.find_spec(name)
        if spec is None or spec.loader is None:
            return spec
        run = spec.loader.exec_module

        def exec_module(module):
            run(module)
            self.patch(module)
        spec.loader.exec_module = exec_module
        return spec


def _replace_once(cls, name: str, make) -> None:
    """Replace the method ``cls.name`` by ``make(original)`` (wrapped as the original), unless it
    was replaced before (the replacement is marked)."""
    original = getattr(cls, name)
    if getattr(original, "uvisi_replaced", False):
        return
    new = functools.wraps(original)(make(original))
    new.uvisi_replaced = True
    setattr(cls, name, new)


def _lock_saves(caching) -> None:
    def make(unlocked):
        def save(self, key, data):
            with open(self._index_path + ".lock", "a") as fh:
                fcntl.flock(fh, fcntl.LOCK_EX)
                try:
                    return unlocked(self, key, data)
                finally:
                    fcntl.flock(fh, fcntl.LOCK_UN)
        return save

    _replace_once(caching.IndexDataCacheFile, "save", make)


def compile_lock_path(dispatcher, args: tuple) -> str | None:
    """The compile lock of ``dispatcher`` for the argument types ``args`` (numba types): beside its
    cache index, named by the index and a digest of the types' names; None for a kernel that is
    not cached on disk."""
    index = getattr(getattr(getattr(dispatcher, "_cache", None), "_cache_file", None),
                    "_index_path", None)
    if index is None:
        return None
    digest = hashlib.sha1(repr(tuple(str(a) for a in args)).encode()).hexdigest()[:12]
    return f"{index}.{digest}.compiling"


def _lock_compiles(dispatcher_module) -> None:
    from numba.core import event, sigutils
    from numba.core.compiler_lock import global_compiler_lock

    def make(unlocked):
        def compile(self, sig):
            args, _ = sigutils.normalize_signature(sig)
            path = None if tuple(args) in self.overloads else compile_lock_path(self, args)
            if path is None:
                return unlocked(self, sig)
            try:
                fh = open(path, "a")
            except OSError:                 # a read-only cache: numba finds its own way
                return unlocked(self, sig)
            # numba's own lock first (re-entrant; ``compile`` takes it too): threads of one
            # process take the file locks one at a time, so none waits on a file lock another
            # thread holds while that thread waits for numba's lock
            with fh, global_compiler_lock:
                if not _try_lock(fh):
                    with event.trigger_event(COMPILE_WAIT_EVENT,
                                             data={"dispatcher": self, "args": args}):
                        _wait_lock(fh, COMPILE_WAIT_S)
                try:
                    return unlocked(self, sig)      # loads what another process saved meanwhile
                finally:
                    fcntl.flock(fh, fcntl.LOCK_UN)
        return compile

    _replace_once(dispatcher_module.Dispatcher, "compile", make)


def _try_lock(fh) -> bool:
    try:
        fcntl.flock(fh, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        return False
    return True


def _wait_lock(fh, limit_s: float) -> bool:
    """Take the lock of ``fh`` when it is free, polling, for at most ``limit_s`` seconds (a
    process waiting on another that waits on it would otherwise wait for ever); whether it was
    taken."""
    import time
    end = time.monotonic() + limit_s
    while time.monotonic() < end:
        time.sleep(0.05)
        if _try_lock(fh):
            return True
    return False


#: the numba options of the copy of a :func:`callee_kernel` its callers compile: neither of numba's
#: wrappers (no Python or C caller reaches this copy), and cached under a name of its own
CALLEE = {"cache": True, "no_cfunc_wrapper": True, "no_cpython_wrapper": True}
#: the suffix of that copy's name (its cache files are ``<module>.<name>_in_callers-<line>...``)
IN_CALLERS = "_in_callers"
#: the qualified names of those copies: numba names each code library after its function, and
#: :func:`link_callee_copies_only` keeps these libraries as IR (a function of another origin that
#: happens to end in the suffix is compiled as usual)
_LINK_ONLY = set()


def callee_kernel(fn=None, **options):
    """Decorator: a kernel that other kernels call, compiled into each of them without the wrappers
    that let Python and C call it. ``@callee_kernel`` or ``@callee_kernel(error_model="numpy",
    ...)`` (numba options, as for ``njit``).

    numba compiles beside every ``@njit`` function a wrapper that converts Python objects to its
    arguments and its result back (unboxing and boxing every array), whether Python ever calls
    the function or not, and LLVM optimises it and makes its machine code. Most of the project's
    kernels are called only by other kernels. The function returned here is a plain Python
    function registered with numba as an overload of itself (``numba.extending.overload``, the
    public way to teach numba a function): a kernel that calls it compiles a copy of ``fn``
    (``inner``: the same code, named ``<name>_in_callers``) with the options of :data:`CALLEE`,
    once per argument types, and links it in as it links a dispatcher. A first run compiled 10 %
    less CPU this way (docs/validation.md, "The first run"); what the callers compute does not
    change.

    A Python call (a test, a user at the prompt) goes to a separate ``@njit(**KERNEL)`` dispatcher
    of ``fn``, compiled and cached on its first call: the attribute ``twin`` (also what a kernel
    passed as an argument to another must be: :func:`dispatcher_of`). The two copies are cached
    under different names because numba's cache index keys a function's entries on its argument
    types and code, not on the options it was compiled with: under one name a Python call could
    load the copy that has no Python wrapper and end the process (seen with numba 0.68.1).
    ``py_func`` is ``fn``, as on a dispatcher."""
    if fn is None:
        return functools.partial(callee_kernel, **options)
    from numba import njit
    from numba.extending import overload
    link_callee_copies_only()
    twin = njit(**dict(KERNEL, **options))(fn)

    @functools.wraps(fn)
    def kernel(*args, **kwargs):
        return twin(*args, **kwargs)

    # the copy compiled into callers: fn's code under a name of its own, so that its cache entries
    # (cached: a later command's new caller loads it rather than compiling it again) are never
    # the twin's
    inner = types.FunctionType(fn.__code__, fn.__globals__, fn.__name__, fn.__defaults__,
                               fn.__closure__)
    inner.__qualname__ = fn.__qualname__ + IN_CALLERS
    _LINK_ONLY.add(inner.__qualname__)
    inner.__module__ = fn.__module__
    inner.__doc__ = fn.__doc__
    kernel.py_func = fn
    kernel.inner = inner
    kernel.twin = twin
    kernel.callee_options = dict(options, **CALLEE)

    def typing(*args, **kwargs):
        return inner

    overload(kernel, jit_options=kernel.callee_options, strict=False)(typing)
    return kernel


def compile_for_callers(kernel, argtypes: tuple) -> None:
    """Compile the copy of the :func:`callee_kernel` ``kernel`` that its callers link in, for the
    numba argument types ``argtypes``, as a caller's typing does when it first meets a call with
    those types (numba's ``jit`` of the copy with the overload's options, then ``compile``). The
    copy is cached, so a caller compiled later, in this process or another, loads it rather than
    compiling it; if another process is compiling it, this waits and loads it (the compile lock).
    A first run's second process compiles a large callee ahead this way
    (:mod:`hil_harness.warmup`). Types no caller uses compile a copy no caller loads: time only."""
    from numba import njit
    if not is_callee_kernel(kernel):
        raise ValueError(f"{getattr(kernel, '__qualname__', kernel)!r} is not a callee kernel")
    njit(**kernel.callee_options)(kernel.inner).compile(tuple(argtypes))


def dispatcher_of(kernel):
    """The numba dispatcher behind ``kernel``: a :func:`callee_kernel`'s ``twin``, else
    ``kernel`` itself. For passing a kernel as an argument to another (a first-class function
    value, as the tests' element-wise helpers do): numba types a dispatcher, not the Python
    function a callee kernel is."""
    return kernel.twin if is_callee_kernel(kernel) else kernel


def is_callee_kernel(obj) -> bool:
    """Whether ``obj`` was made by :func:`callee_kernel`."""
    if not isinstance(obj, types.FunctionType):
        return False
    twin = getattr(obj, "twin", None)
    return twin is not None and getattr(obj, "py_func", None) is getattr(twin, "py_func", False)


def link_callee_copies_only() -> None:
    """Make numba keep a :func:`callee_kernel`'s copy (a code library named after the copy:
    ``<name>_in_callers``) as LLVM IR, for linking into its callers only. Idempotent; called by
    :func:`callee_kernel`.

    numba finishes every compiled function's code library the same way: it links in the IR of
    the functions it calls, runs LLVM's whole-module passes over the result and makes its machine
    code, which it caches beside the IR. A callee copy has no wrapper, so nothing ever runs that
    machine code: each caller links the copy's IR into its own module and optimises and compiles
    it there, again. For these libraries only, this skips the whole-module passes and the machine
    code (LLVM's per-function passes still run as the IR is added), and caches the IR alone
    (numba's ``bitcode`` form, which it loads without optimising again). A caller then optimises
    its callees' code once, in its own module, as whole-program optimisation would. A first run
    compiled about a quarter less CPU this way (docs/validation.md, "The first run"); what the
    callers compute does not change.

    The functions' environments follow: numba points each function's environment global (what
    an exception with run-time values reads, among others) at its environment when it compiles
    the function (``set_env``), through the engine, which never holds a link-only copy. So that
    write is skipped for the copy, and made for each copy's global in the caller once the caller
    is in the engine, as numba does for the globals of a caller it loads from its cache.

    These are numba's internals (``numba.core.codegen``, as of numba 0.68): where they are not as
    expected, nothing is changed and the copies are finished as numba finishes any function, which
    costs time only."""
    from numba.core import codegen as cg
    try:
        from numba.core.environment import lookup_environment
    except ImportError:                             # another numba: its own way, unchanged
        return
    lib, gen = getattr(cg, "JITCodeLibrary", None), getattr(cg, "JITCPUCodegen", None)
    needed = ("_optimize_final_module", "_finalize_final_module", "_finalize_dynamic_globals",
              "_verify_declare_only_symbols", "serialize_using_object_code", "_ensure_finalized")
    if lib is None or gen is None or not all(hasattr(lib, n) for n in needed) \
            or not hasattr(gen, "set_env") or getattr(lib, "uvisi_link_only", False):
        return
    optimise, finish, serialise, set_env = (lib._optimize_final_module,
                                            lib._finalize_final_module,
                                            lib.serialize_using_object_code, gen.set_env)

    def link_only(library) -> bool:
        return library.name in _LINK_ONLY

    def optimize_final_module(self):
        if not link_only(self):
            optimise(self)

    def finalize_final_module(self):
        if not link_only(self):
            finish(self)
            for gv in self._final_module.global_variables:      # the linked copies' environments
                if gv.name.startswith("_ZN08NumbaEnv") and IN_CALLERS in gv.name:
                    env = lookup_environment(gv.name)
                    if env is not None:
                        self._codegen.set_env(gv.name, env)
            return
        self._finalize_dynamic_globals()
        self._verify_declare_only_symbols()
        self._finalized = True

    def serialize_using_object_code(self):
        if not link_only(self):
            return serialise(self)
        self._ensure_finalized()
        return (self.name, "bitcode", self._final_module.as_bitcode())

    def set_env_if_defined(self, env_name, env):
        if self._engine.get_global_value_address(env_name):
            set_env(self, env_name, env)

    lib._optimize_final_module = optimize_final_module
    lib._finalize_final_module = finalize_final_module
    lib.serialize_using_object_code = serialize_using_object_code
    gen.set_env = set_env_if_defined
    lib.uvisi_link_only = True
