"""The compile bar's total (:mod:`hil_harness.compile_plan`) against what numba compiles: on an
empty cache, every project kernel numba compiles for a call is in the set read from the code, and
the bar counts them against that set, with no time estimate."""
import json
import os
import subprocess
import sys

SCRIPT = r"""
import json
import numpy as np
from numba.core import event
from hil_harness import console
from hil_harness.compile_plan import PROJECT_PACKAGES, reachable_kernels, uncached_kernels
from flightsw.numba_cache import IN_CALLERS
import flightsw.tp.f1750 as f
from flightsw.arith.m1750 import encode32

compiled = []
class Seen(event.Listener):
    def on_start(self, e):
        pass
    def on_end(self, e):
        compiled.append(e.data["dispatcher"].py_func)
event.register("numba:compile", Seen())
console.watch_compilation()
name = lambda fn: fn.__module__ + "." + fn.__qualname__.removesuffix(IN_CALLERS)
planned = [name(k.py_func) for k in reachable_kernels(f.qdcm)]
assert len(uncached_kernels(f.qdcm)) == len(planned)          # an empty cache
R = np.zeros(9, np.int64)
half = encode32(0.5)
f.qdcm(half, half, half, half, R)
# the overloads' implementations numba makes are not kernels of their own: a kernel is a
# module's dispatcher, or the copy of a kernel compiled into its callers
import sys
def own(fn):
    k = getattr(sys.modules[fn.__module__], fn.__qualname__.removesuffix(IN_CALLERS), None)
    return fn in (getattr(k, "py_func", None), getattr(k, "inner", None))
project = sorted({name(fn) for fn in compiled
                  if fn.__module__.split(".")[0] in PROJECT_PACKAGES and own(fn)})
print(json.dumps({"planned": planned, "compiled": project,
                  "cached_after": len(uncached_kernels(f.qdcm)),
                  "bar": list(console.compile_counts())}))
"""


def _run(tmp_path, progress):
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path / "numba"), UVISI_PROGRESS=progress)
    res = subprocess.run([sys.executable, "-c", SCRIPT], capture_output=True, text=True,
                         timeout=300, env=env)
    assert res.returncode == 0, res.stderr
    return json.loads(res.stdout), res.stderr


def test_the_bar_counts_what_numba_compiles_against_the_code_s_total(tmp_path):
    out, err = _run(tmp_path, "1")
    planned, compiled = set(out["planned"]), set(out["compiled"])
    assert "flightsw.tp.f1750.qdcm" in compiled and len(compiled) >= 5
    assert compiled <= planned, sorted(compiled - planned)
    # the bar counted every kernel compiled, of the total read from the code (its last state
    # need not be drawn: tqdm redraws at most every 0.1 s, and the bar is cleared at the end)
    assert out["bar"] == [len(compiled), len(planned)]
    assert f"/{len(planned)} kernels [" in err
    assert "compiling (first run only, cached after)" in err
    assert "<" not in err and "?" not in err             # no time estimate, no rate
    assert out["cached_after"] == 0          # qdcm's cached code holds all it calls


def test_without_a_terminal_one_line_says_it(tmp_path):
    from hil_harness.console import COMPILE_NOTE
    _, err = _run(tmp_path, "0")
    assert err.count(COMPILE_NOTE) == 1 and "kernels [" not in err


def test_the_plan_reads_no_attribute_of_another_package(recwarn):
    """The plan follows the attributes a kernel takes of a project module, and reads none of
    another package's module: numpy 1.26 warns on ``np.bool`` (FutureWarning), which a first run
    printed three times. Here a module of another package whose every attribute read warns, and
    a function of ours that names it beside a project module's kernel."""
    import types
    import warnings

    import flightsw.tp.f1750 as f
    from hil_harness.compile_plan import reachable_kernels

    class Noisy(types.ModuleType):
        def __getattr__(self, name):
            warnings.warn(f"{name} read", FutureWarning)
            raise AttributeError(name)

    source = "def run(R):\n    noisy.bool\n    return f1750.qdcm(1, 1, 1, 1, R)\n"
    space = {"noisy": Noisy("otherpkg"), "f1750": f, "__name__": "hil_harness.example"}
    exec(compile(source, "<example>", "exec"), space)
    found = reachable_kernels(space["run"])
    assert f.qdcm in found                                  # through the project module
    assert not [w for w in recwarn if issubclass(w.category, FutureWarning)]
