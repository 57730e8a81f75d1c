"""Numba's on-disk cache (flightsw.numba_cache): keyed on the sources, and written by several
processes at once.

Keyed: the oracle is a caller's value after its callee's file changed (numba's own cache keeps the
old callee). Locked saves: the oracle is the index and data files themselves. Two processes save 60
different keys each into one cache file at the same time; afterwards every key is in the index and
its data file holds that key's payload (numba 0.68's unlocked save lets two processes pick the same
data-file number, so a key can name the other process's machine code). One compile at a time: the
oracles are numba's own compile events in each of two processes calling one kernel (the second
compiles nothing and loads the first's) and the kernels' values.
"""
from __future__ import annotations

import json
import math
import multiprocessing as mp
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest
from numba.core.caching import IndexDataCacheFile

import flightsw  # noqa: F401  (installs the locked save)
from flightsw import numba_cache as nc

N = 60


def _writer(path: str, tag: str, go) -> None:
    import flightsw  # noqa: F401
    f = IndexDataCacheFile(path, "kernel-1.py311", ("stamp", 1))
    go.wait()
    for i in range(N):
        f.save((tag, i), {"payload": (tag, i), "pad": b"x" * 2048})


def test_concurrent_saves_keep_every_key_with_its_own_data(tmp_path):
    ctx = mp.get_context("fork")
    go = ctx.Event()
    procs = [ctx.Process(target=_writer, args=(str(tmp_path), tag, go)) for tag in "ab"]
    for p in procs:
        p.start()
    go.set()
    for p in procs:
        p.join(60)
        assert p.exitcode == 0
    f = IndexDataCacheFile(str(tmp_path), "kernel-1.py311", ("stamp", 1))
    for key in [(tag, i) for tag in "ab" for i in range(N)]:       # numba's own reader
        got = f.load(key)
        assert got is not None and got["payload"] == key, key


# ------------------------------------------------------------------------------------------------
# one compile of a kernel at a time across processes
# ------------------------------------------------------------------------------------------------

_KERNELS = """
from numba import njit

@njit(cache=True)
def f(x):
    return 3 * x + 1

@njit("int64(int64)", cache=True)
def fact(n):
    return 1 if n <= 1 else n * fact(n - 1)
"""

#: one process of the compile-lock test: ``compiler`` compiles ``f`` for int64, slowly (2 s in
#: numba's compile event), ``waiter`` calls it once the compiler has started; each prints its
#: numba compile events of ``f``, its waits and ``f(4)``
_ROLE = """
import json, os, sys, time
sys.path.insert(0, {tree!r})
import flightsw                                   # installs the locks
from flightsw.numba_cache import COMPILE_WAIT_EVENT
from numba.core import event
role, flag = sys.argv[1], {flag!r}
compiles, waits = [], []

class Count(event.Listener):
    def __init__(self, into, slow):
        self.into, self.slow = into, slow
    def on_start(self, ev):
        if ev.data["dispatcher"].py_func.__name__ == "f":
            self.into.append(1)
            if self.slow:
                open(flag, "w").close()           # the compiler holds f's lock now
                time.sleep(2.0)
    def on_end(self, ev):
        pass

event.register("numba:compile", Count(compiles, role == "compiler"))
event.register(COMPILE_WAIT_EVENT, Count(waits, False))
from pkgy.kernels import f
if role == "waiter":
    while not os.path.exists(flag):
        time.sleep(0.01)
f4 = int(f(4))
print(json.dumps({{"compiles": len(compiles), "waits": len(waits), "f4": f4}}))
"""


def test_a_second_process_waits_for_the_kernel_being_compiled_and_loads_it(tmp_path):
    """Oracles: numba's own compile events in each process (the second compiles nothing), the
    lock's wait event (seen once, in the second only) and the kernel's value (3 * 4 + 1)."""
    tree = tmp_path / "tree"
    (tree / "pkgy").mkdir(parents=True)
    (tree / "pkgy" / "__init__.py").write_text("")
    (tree / "pkgy" / "kernels.py").write_text(_KERNELS)
    script = tmp_path / "role.py"
    script.write_text(_ROLE.format(tree=str(tree), flag=str(tmp_path / "compiling")))
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path / "cache"))
    procs = {role: subprocess.Popen([sys.executable, str(script), role], env=env, text=True,
                                    stdout=subprocess.PIPE, stderr=subprocess.PIPE)
             for role in ("compiler", "waiter")}
    got = {}
    for role, p in procs.items():
        out, err = p.communicate(timeout=300)
        assert p.returncode == 0, err[-2000:]
        got[role] = json.loads(out.splitlines()[-1])
    assert got["compiler"] == {"compiles": 1, "waits": 0, "f4": 13}
    assert got["waiter"] == {"compiles": 0, "waits": 1, "f4": 13}
    assert list((tmp_path / "cache").rglob("*.compiling"))         # the lock files, beside it


def test_a_recursive_kernel_does_not_wait_for_itself(tmp_path):
    """A recursive kernel calls itself with the types it is being compiled for, under its own
    lock: numba types that call without compiling again, so the process never waits for itself
    (oracle: math.factorial; the wait event never fires; a numba that compiled again there would
    wait out COMPILE_WAIT_S and fail the subprocess's timeout)."""
    (tmp_path / "pkgy").mkdir()
    (tmp_path / "pkgy" / "__init__.py").write_text("")
    (tmp_path / "pkgy" / "kernels.py").write_text(_KERNELS)
    code = textwrap.dedent(f"""
        import sys
        sys.path.insert(0, {str(tmp_path)!r})
        import flightsw
        from flightsw.numba_cache import COMPILE_WAIT_EVENT
        from numba.core import event
        waits = []
        class W(event.Listener):
            def on_start(self, ev):
                waits.append(1)
            def on_end(self, ev):
                pass
        event.register(COMPILE_WAIT_EVENT, W())
        from pkgy.kernels import fact
        print(fact(10), len(waits))
    """)
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path / "cache"))
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True,
                         timeout=120)
    assert out.returncode == 0, out.stderr[-2000:]
    assert out.stdout.split() == [str(math.factorial(10)), "0"]


_CALLEES = """
from numba import njit
from flightsw.numba_cache import callee_kernel

@callee_kernel
def h(x):
    return 2 * x + 5

@njit(cache=True)
def g(x):
    return h(x) + 1
"""

#: one process: ``ahead`` compiles h's copy for its callers for int64, ``caller`` calls g on
#: argv[2] (an int or a float); each prints the numba compile events of h's copy and g's value
_AHEAD = """
import json, sys
sys.path.insert(0, {tree!r})
from numba import types
from numba.core import event
from flightsw.numba_cache import compile_for_callers
from pkgz.kernels import g, h
copies = []

class Count(event.Listener):
    def on_start(self, ev):
        if ev.data["dispatcher"].py_func.__qualname__ == "h_in_callers":
            copies.append(1)
    def on_end(self, ev):
        pass

event.register("numba:compile", Count())
value = None
if sys.argv[1] == "ahead":
    compile_for_callers(h, (types.int64,))
else:
    value = g(int(sys.argv[2]) if sys.argv[2].isdigit() else float(sys.argv[2]))
print(json.dumps({{"copies": len(copies), "value": value}}))
"""


def _kernel_tree(tmp_path, kernels: str, script: str) -> tuple:
    """A package ``pkgz`` whose ``kernels`` module is ``kernels``, a script made from the template
    ``script`` (``{tree}``: the package's folder) and an environment with a cache of its own ->
    (script path, environment)."""
    tree = tmp_path / "tree"
    (tree / "pkgz").mkdir(parents=True)
    (tree / "pkgz" / "__init__.py").write_text("")
    (tree / "pkgz" / "kernels.py").write_text(kernels)
    path = tmp_path / "script.py"
    path.write_text(script.format(tree=str(tree)))
    return path, dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path / "cache"))


def test_a_callee_compiled_ahead_is_what_a_later_caller_links(tmp_path):
    """compile_for_callers caches the copy a caller's typing would compile. Oracles: numba's
    compile events of the copy in each process (the caller's process compiles none for the types
    compiled ahead, one for other types) and g's value (2 x + 6)."""
    script, env = _kernel_tree(tmp_path, _CALLEES, _AHEAD)

    def run(*argv):
        out = subprocess.run([sys.executable, str(script), *argv], env=env, capture_output=True,
                             text=True, timeout=300)
        assert out.returncode == 0, out.stderr[-2000:]
        return json.loads(out.stdout.splitlines()[-1])

    assert run("ahead") == {"copies": 1, "value": None}
    assert run("caller", "4") == {"copies": 0, "value": 14}
    assert run("caller", "4.5") == {"copies": 1, "value": 15.0}


def test_compile_for_callers_takes_callee_kernels_only():
    from numba import njit, types
    with pytest.raises(ValueError, match="not a callee kernel"):
        nc.compile_for_callers(njit(lambda x: x), (types.int64,))


def test_the_lock_is_named_by_the_kernel_and_its_types():
    from numba.core import types
    from flightsw.arith.m1750_float import _fa32_k, _fm32_k
    a = nc.compile_lock_path(_fa32_k, (types.int64, types.int64))
    assert a.endswith(".compiling") and a.startswith(_fa32_k._cache._cache_file._index_path)
    assert a == nc.compile_lock_path(_fa32_k, (types.int64, types.int64))
    assert a != nc.compile_lock_path(_fa32_k, (types.int32, types.int64))
    assert a != nc.compile_lock_path(_fm32_k, (types.int64, types.int64))
    from numba import njit
    assert nc.compile_lock_path(njit(lambda x: x), (types.int64,)) is None    # not cached


# ------------------------------------------------------------------------------------------------
# the cache keyed on the sources
# ------------------------------------------------------------------------------------------------

_CALLER = """
from numba import njit
from pkgx.callee import f

@njit(cache=True)
def g():
    return f() + 10
"""


def _callee(tree: Path, value: int, when: float) -> None:
    p = tree / "pkgx" / "callee.py"
    p.write_text(f"from numba import njit\n\n@njit(cache=True)\ndef f():\n    return {value}\n")
    os.utime(p, (when, when))            # a new stamp, the same size: numba sees an edit


def _run_g(tree: Path, env_cache: str | None) -> int:
    """``pkgx.caller.g()`` in a fresh process: the cache keyed on pkgx's sources
    (``env_cache`` None) or numba's own per-file cache in ``env_cache``."""
    env = {k: v for k, v in os.environ.items() if k != "NUMBA_CACHE_DIR"}
    if env_cache is not None:
        env["NUMBA_CACHE_DIR"] = env_cache
    code = textwrap.dedent(f"""
        import os, sys
        sys.path.insert(0, {str(tree)!r})
        keyed = {env_cache is None!r}
        from flightsw.numba_cache import key_cache_on_sources   # keys the project's own cache
        if keyed:
            del os.environ["NUMBA_CACHE_DIR"]                       # then key it on pkgx instead
            key_cache_on_sources({str(tree)!r}, ("pkgx",))
        from pkgx.caller import g
        print(g())
    """)
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True,
                         timeout=300)
    assert out.returncode == 0, out.stderr[-2000:]
    return int(out.stdout.split()[-1])


def test_a_changed_callee_reaches_its_cached_caller(tmp_path):
    """numba keys a cached kernel on its own file: after the callee's file changes, the caller
    loaded from numba's own cache still returns the old callee's value (11, the hazard); with the
    cache keyed on the package's sources the caller returns the new one (12)."""
    for mode in ("numba's own", "keyed"):
        tree = tmp_path / mode.replace("'", "").replace(" ", "_")
        (tree / "pkgx").mkdir(parents=True)
        (tree / "pkgx" / "__init__.py").write_text("")
        (tree / "pkgx" / "caller.py").write_text(_CALLER)
        env_cache = str(tree / "own_cache") if mode == "numba's own" else None
        _callee(tree, 1, 1.7e9)
        assert _run_g(tree, env_cache) == 11
        _callee(tree, 2, 1.7e9 + 100)
        got = _run_g(tree, env_cache)
        assert got == (11 if mode == "numba's own" else 12), (mode, got)
    assert len(list((tmp_path / "keyed" / ".numba_cache").iterdir())) == 2   # one per version


def test_the_digest_follows_python_sources_only(tmp_path):
    (tmp_path / "pkgx" / "sub").mkdir(parents=True)
    (tmp_path / "pkgx" / "a.py").write_text("A = 1\n")
    (tmp_path / "pkgx" / "sub" / "b.py").write_text("B = 2\n")
    d0 = nc.source_digest(tmp_path, ("pkgx",))
    (tmp_path / "pkgx" / "data.toml").write_text("x = 1\n")
    assert nc.source_digest(tmp_path, ("pkgx",)) == d0
    (tmp_path / "pkgx" / "sub" / "b.py").write_text("B = 3\n")
    d1 = nc.source_digest(tmp_path, ("pkgx",))
    (tmp_path / "pkgx" / "sub" / "b.py").write_text("B = 2\n")
    assert d1 != d0 and nc.source_digest(tmp_path, ("pkgx",)) == d0
    (tmp_path / "pkgx" / "sub" / "b.py").rename(tmp_path / "pkgx" / "b.py")   # moved: another tree
    d2 = nc.source_digest(tmp_path, ("pkgx",))
    assert d2 != d0
    (tmp_path / "pkgx" / "cmd").mkdir()                  # a folder left out: edits there count not
    (tmp_path / "pkgx" / "cmd" / "c.py").write_text("C = 1\n")
    assert nc.source_digest(tmp_path, ("pkgx",), leave_out=("pkgx/cmd",)) == d2
    assert nc.source_digest(tmp_path, ("pkgx",)) != d2
    assert nc.NOT_KERNEL_SOURCES == ("hil_harness/cli",)


def test_a_new_version_keeps_two_others_drops_numbas_default_and_respects_the_user(
        tmp_path, monkeypatch):
    import numba.core.config
    monkeypatch.setattr(numba.core.config, "CACHE_DIR", numba.core.config.CACHE_DIR)  # restored
    monkeypatch.delenv("NUMBA_CACHE_DIR", raising=False)
    (tmp_path / "pkgx").mkdir()
    (tmp_path / "pkgx" / "a.py").write_text("A = 1\n")
    top = tmp_path / ".numba_cache"
    for i, name in enumerate(["old0", "old1", "old2", "old3"]):
        (top / name).mkdir(parents=True)
        os.utime(top / name, (1e9 + i, 1e9 + i))
    old_cache = tmp_path / "pkgx" / "__pycache__"
    old_cache.mkdir()
    for name in ("a.f-3.py311.nbi", "a.f-3.py311.1.nbc", "a.f-3.py311.nbi.lock",
                 "a.cpython-311.pyc"):
        (old_cache / name).write_bytes(b"x")
    here = nc.key_cache_on_sources(tmp_path, ("pkgx",))
    assert here == top / nc.source_digest(tmp_path, ("pkgx",))
    assert sorted(d.name for d in top.iterdir()) == sorted(["old2", "old3", here.name])
    assert [f.name for f in old_cache.iterdir()] == ["a.cpython-311.pyc"]     # numba's files gone
    assert os.environ["NUMBA_CACHE_DIR"] == str(here)
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path / "mine"))
    assert nc.key_cache_on_sources(tmp_path, ("pkgx",)) is None
    assert os.environ["NUMBA_CACHE_DIR"] == str(tmp_path / "mine")


def _project_kernels() -> tuple[list, list]:
    """The kernels (numba dispatchers; for a kernel compiled into its callers, the dispatcher
    Python calls) defined in the packages the digest covers, and those defined in a folder it
    leaves out (the command line)."""
    import importlib
    import pkgutil

    from numba.core.registry import CPUDispatcher
    left_out = tuple(d.replace("/", ".") + "." for d in nc.NOT_KERNEL_SOURCES)
    kernels, outside = [], []
    for pkg in nc.SOURCE_PACKAGES:
        top = importlib.import_module(pkg)
        for m in pkgutil.walk_packages(top.__path__, pkg + "."):
            if m.name.endswith(".__main__"):                # runs a command when imported
                continue
            mod = importlib.import_module(m.name)
            for obj in vars(mod).values():
                obj = nc.dispatcher_of(obj)
                if isinstance(obj, CPUDispatcher) and obj.__module__ == m.name:
                    (outside if m.name.startswith(left_out) else kernels).append(obj)
    return kernels, outside


def test_every_project_kernel_caches_in_one_folder():
    """Each kernel of the flight code, the simulator and the harness keeps its cache in the one
    folder the process chose (the source-keyed one, unless the user set ``NUMBA_CACHE_DIR``), and
    none is defined in a folder the digest leaves out (the command line)."""
    where = Path(os.environ["NUMBA_CACHE_DIR"]).resolve()
    paths, outside = _project_kernels()
    assert len(paths) > 200 and not outside        # no kernel where the digest does not look
    for k in paths:
        if k._cache:
            p = Path(k._cache.cache_path).resolve()
            assert where in p.parents or p == where, (k, p)


def test_nowhere_to_write_leaves_numbas_default(tmp_path, monkeypatch):
    """A cache root that cannot be made (a file stands in its place) leaves numba's default."""
    import numba.core.config
    monkeypatch.setattr(numba.core.config, "CACHE_DIR", numba.core.config.CACHE_DIR)
    monkeypatch.delenv("NUMBA_CACHE_DIR", raising=False)
    (tmp_path / "pkgx").mkdir()
    (tmp_path / "pkgx" / "a.py").write_text("A = 1\n")
    (tmp_path / ".numba_cache").write_text("not a folder")
    assert nc.key_cache_on_sources(tmp_path, ("pkgx",)) is None
    assert "NUMBA_CACHE_DIR" not in os.environ


def test_every_project_kernel_is_compiled_with_the_kernel_options():
    """Every kernel of the three packages that Python calls (for a kernel compiled into its
    callers, its Python-callable twin) is compiled with :data:`flightsw.numba_cache.KERNEL`
    (cached, no C-callable wrapper), whatever else it asks for."""
    from numba.core.caching import NullCache
    assert nc.KERNEL == {"cache": True, "no_cfunc_wrapper": True}
    kernels, _ = _project_kernels()
    missing = [k.py_func.__qualname__ for k in kernels             # numba keeps "cache" as
               if isinstance(k._cache, NullCache)                   # the kernel's cache object
               or k.targetoptions.get("no_cfunc_wrapper") is not True]
    assert len(kernels) > 200 and not missing, missing


def test_the_kernel_options_drop_only_the_c_callable_wrapper():
    """The oracle is numba's own LLVM IR: a function compiled with the options (uncached here)
    defines its Python wrapper and no ``cfunc.`` wrapper, where plain ``njit`` defines both; both
    return the same value to Python."""
    from numba import njit

    def f(a, b):
        return a * b + 1

    plain = njit(f)
    ours = njit(**dict(nc.KERNEL, cache=False))(f)
    assert plain(6, 7) == ours(6, 7) == 43
    ir_plain, = plain.inspect_llvm().values()
    ir_ours, = ours.inspect_llvm().values()

    def wrappers(ir):
        defined = [ln for ln in ir.splitlines() if ln.startswith("define")]
        return (any("@cfunc." in ln for ln in defined),      # the C-callable wrapper
                any("@_ZN7cpython" in ln for ln in defined))  # the Python-callable one
    assert wrappers(ir_plain) == (True, True)
    assert wrappers(ir_ours) == (False, True)


CALLEE_MODULE = """
import numpy as np
from numba import njit
from flightsw.numba_cache import KERNEL, callee_kernel

@callee_kernel
def scale(x, k):
    if k < 0.0:
        raise ValueError("negative factor", k)     # a message with a run-time value
    out = np.empty_like(x)
    for i in range(x.size):
        out[i] = x[i] * k
    return out

@njit(**KERNEL)
def total(x, k):
    return scale(x, k).sum()

@njit(**KERNEL)
def top(x, k):
    return scale(x, k).max()
"""

CALLEE_RUN = """
import sys
import numpy as np
import numba.core.codegen as cg
sys.path.insert(0, sys.argv[1])
made = []                                       # the code libraries LLVM made machine code of
emit = cg.JITCodeLibrary._finalize_specific
cg.JITCodeLibrary._finalize_specific = lambda lib: (made.append(lib.name), emit(lib))[1]
import callee_mod as m
x = np.arange(4.0)
def value_and_error(caller):
    print(caller(x, 3.0))
    try:
        caller(x, -2.0)
    except ValueError as e:
        print(e.args)
if sys.argv[2] == "caller":
    value_and_error(m.total)
    if sys.argv[3] == "cold":
        ir = "\\n".join(m.total.inspect_llvm().values())
        defined = [ln for ln in ir.splitlines() if ln.startswith("define") and "scale" in ln]
        print(len(defined) <= 1, any("cpython" in ln or "cfunc" in ln for ln in defined))
elif sys.argv[2] == "other caller":
    value_and_error(m.top)
else:
    print(m.scale(x, 2.0).tolist())
print(sorted({name for name in made if "total" in name or "top" in name or "scale" in name}))
"""


def test_a_callee_kernel_is_compiled_into_its_caller_and_still_answers_python(tmp_path):
    """A kernel made by ``callee_kernel`` is compiled into its caller with neither wrapper (the
    oracle: numba's LLVM IR of the caller defines the callee at most once, where LLVM did not
    inline it, and no ``cpython`` or ``cfunc`` function of it), and a Python call to it in a
    later process, on the cache the caller left, returns the right answer rather than loading the
    wrapperless copy and crashing; and the other way round. The copy is kept as IR for linking
    only: LLVM makes machine code of the caller alone (numba's code library's last stage,
    watched), and a second caller in a later process links the copy from the cache. In each, an
    exception the callee raises with a run-time value reaches Python with its value. Each step is
    a process of its own."""
    (tmp_path / "callee_mod.py").write_text(CALLEE_MODULE)
    (tmp_path / "run.py").write_text(CALLEE_RUN)

    def run(cache, who, state):
        env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path / cache))
        res = subprocess.run([sys.executable, str(tmp_path / "run.py"), str(tmp_path), who,
                              state], capture_output=True, text=True, timeout=300, env=env)
        assert res.returncode == 0, (who, state, res.returncode, res.stderr[-2000:])
        return res.stdout.split("\n")

    total, error, ir, made = run("a", "caller", "cold")[:4]
    assert float(total) == 18.0                     # 3 * (0 + 1 + 2 + 3)
    assert error == "('negative factor', -2.0)"     # the copy's environment reached
    assert ir == "True False"                       # the callee's body (or inlined), no wrapper
    assert made == "['total']"                      # the copy is IR only: no machine code
    top, error, made = run("a", "other caller", "warm")[:3]
    assert (float(top), error) == (9.0, "('negative factor', -2.0)")
    assert made == "['top']"                        # the copy's IR, loaded from the cache
    assert run("a", "python", "warm")[0] == "[0.0, 2.0, 4.0, 6.0]"
    assert run("b", "python", "cold")[0] == "[0.0, 2.0, 4.0, 6.0]"
    assert run("b", "caller", "warm")[:2] == ["18.0", "('negative factor', -2.0)"]


def test_only_callee_copies_are_kept_as_ir(tmp_path):
    """A function of another origin whose name ends like a callee copy's is compiled whole: Python
    calls it (in a process of its own: a library without machine code would end the process)."""
    (tmp_path / "named_mod.py").write_text(textwrap.dedent("""
        from numba import njit
        from flightsw.numba_cache import IN_CALLERS, callee_kernel

        @callee_kernel
        def twice(x):
            return 2 * x

        def shift_in_callers(x):
            return twice(x) + 1

        assert shift_in_callers.__qualname__.endswith(IN_CALLERS)
        print(njit(shift_in_callers)(20))
    """))
    res = subprocess.run([sys.executable, str(tmp_path / "named_mod.py")], capture_output=True,
                         text=True, timeout=300,
                         env=dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path / "cache")))
    assert (res.returncode, res.stdout.strip()) == (0, "41"), res.stderr[-2000:]


def test_numbas_blas_check_imports_no_scipy_linalg_and_a_blas_kernel_still_compiles():
    """In a fresh process the first kernel run leaves ``scipy.linalg`` unimported while numba's
    flag says BLAS is there (what numba's own check gives with SciPy installed); a kernel calling
    ``np.dot`` then compiles through numba's own check (SciPy's BLAS imported) and equals numpy."""
    code = textwrap.dedent("""
        import sys
        import numpy as np
        import flightsw
        from numba import njit
        import numba.np.linalg as linalg

        @njit
        def plus_one(x):
            return x + 1.0

        plus_one(1.0)
        import numba.np.arraymath as am
        before = "scipy.linalg" in sys.modules
        restored = not getattr(linalg.ensure_blas, "uvisi_deferred", False)

        @njit
        def dot(a, b):
            return np.dot(a, b)

        a, b = np.arange(6.0).reshape(2, 3), np.array([1.0, -2.0, 0.5])
        same = bool(np.array_equal(dot(a, b), a @ b))
        print(before, am._HAVE_BLAS, restored, "scipy.linalg" in sys.modules, same)
    """)
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr[-2000:]
    assert out.stdout.split() == ["False", "True", "True", "True", "True"]


@pytest.mark.parametrize("files, found", [((), False),
                                          (("cython_blas.cpython-311-x86_64-linux-gnu.so",), True),
                                          (("cython_lapack.pyd",), False)])
def test_scipy_blas_is_found_by_its_file_without_importing_scipy(tmp_path, files, found):
    """A made SciPy package (an ``__init__`` that raises if imported): the check finds its BLAS
    extension file, or its absence, without importing it."""
    linalg = tmp_path / "scipy" / "linalg"
    linalg.mkdir(parents=True)
    (tmp_path / "scipy" / "__init__.py").write_text("raise RuntimeError('imported')\n")
    for f in files:
        (linalg / f).write_bytes(b"")
    code = ("import sys; from flightsw.numba_cache import scipy_blas_installed; "
            "print(scipy_blas_installed(), 'scipy' in sys.modules)")
    root = Path(__file__).resolve().parents[2]
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(tmp_path), str(root)]))
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env,
                         timeout=120)
    assert out.returncode == 0, out.stderr[-2000:]
    assert out.stdout.split() == [str(found), "False"]


# ------------------------------------------------------------------------------------------------
# loading from the cache without refreshing numba's contexts
# ------------------------------------------------------------------------------------------------

_NRT_KERNELS = """
import numpy as np
from numba import njit

@njit(cache=True)
def ramp(n):
    a = np.empty(n)              # allocated by numba's runtime (NRT) and boxed for Python
    for i in range(n):
        a[i] = 0.5 * i
    return a
"""

#: one process: counts numba's target-context refreshes, calls the cached ``ramp`` (``patched``:
#: with flightsw's patches, else numba as shipped), then compiles a kernel that is in no cache
#: (numpy reductions and math: numba's lowering registries) and prints what it saw
_LOAD = """
import json, sys
sys.path.insert(0, {tree!r})
import numpy as np
if sys.argv[1] == "patched":
    import flightsw                               # noqa: F401  (installs the patches)
from numba.core import base, event
refreshes, compiles = [], []
real = base.BaseContext.refresh
def counted(self):
    refreshes.append(1)
    return real(self)
base.BaseContext.refresh = counted

class Count(event.Listener):
    def on_start(self, ev):
        name = ev.data["dispatcher"].py_func.__name__
        if name in ("ramp", "stats"):               # not numba's own overloads
            compiles.append(name)
    def on_end(self, ev):
        pass
event.register("numba:compile", Count())
from pkgz.kernels import ramp
a = ramp(7)
out = {{"ramp": a.tolist(), "refreshes_at_load": len(refreshes),
        "lowering_loaded": "numba.np.arraymath" in sys.modules}}
from numba import njit

@njit
def stats(x):
    return np.sum(x), np.max(x), np.sqrt(x[3])

s = stats(a)
out.update(stats=[float(v) for v in s], compiles=compiles, refreshes=len(refreshes))
print(json.dumps(out))
"""


def test_a_cached_kernel_loads_without_a_refresh_and_a_later_compile_still_works(tmp_path):
    """Oracles: numpy (``0.5 * arange(7)``, its sum, max and a square root), numba's compile
    events and a count of its target-context refreshes. One process compiles ``ramp`` into the
    cache; then, as numba ships, loading it refreshes the contexts and imports numba's lowering
    modules, and with flightsw's patch it does neither and the array numba's runtime allocated
    comes back right; a kernel compiled after that load refreshes first and answers right."""
    script, env = _kernel_tree(tmp_path, _NRT_KERNELS, _LOAD)
    got = {}
    for run in ("compile", "shipped", "patched"):       # the first fills the cache
        out = subprocess.run([sys.executable, str(script), run], env=env, capture_output=True,
                             text=True, timeout=300)
        assert out.returncode == 0, out.stderr[-2000:]
        got[run] = json.loads(out.stdout.splitlines()[-1])
    want = [0.5 * i for i in range(7)]
    assert got["compile"]["compiles"] == ["ramp", "stats"]
    for run in ("shipped", "patched"):
        g = got[run]
        assert g["ramp"] == want and g["compiles"] == ["stats"], run       # ramp was loaded
        assert g["stats"] == [sum(want), max(want), math.sqrt(want[3])], run
        assert g["refreshes"] > g["refreshes_at_load"], run                 # the compile's own
    assert got["shipped"]["refreshes_at_load"] > 0 and got["shipped"]["lowering_loaded"]
    assert got["patched"]["refreshes_at_load"] == 0
    assert not got["patched"]["lowering_loaded"]
