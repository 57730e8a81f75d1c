"""The aurora / Earth-glow renderer (``groundsim.aurora``) against a fixture of its earlier output, so
that a faster renderer is shown to draw the same scene (issue 45 item 1).

Fixture ``tests/data/aurora_render_fixture.npz`` (compressed; each array stored as its byte planes,
which deflate to 70 % of the plain arrays: 1.2 MB), made at commit 1c93833 (the renderer before the
issue) from the repository root with::

    PYTHONPATH=. python tests/groundsim/test_aurora_fixture.py --write

For each case below (open loop: the scenario's pointing profile, its seed) the extended image the
world hands the frame renderer (float32 [244, 256], electrons per integration, what
``AuroraScene.image`` returns) and the frame ``World.render()`` makes of it (uint16 [244, 256], DN):

* ``aurora_surge_wfov_uv`` frames 0, 30, 60, 90, 120 (t = 0 ... 60 s): arcs, the surge from its
  start to its full bulge, the hot spot, night airglow under every pixel;
* ``aurora_train_dusk_dayglow`` frame 0: the night limb, the sunlit Earth (dayglow) and aurora in
  one field;
* ``launch_nfov`` frame 0: a satellite-style scene's Earth glow alone
  (``AuroraScene(..., include_aurora=False)``), in another imager (NFOV).

Tolerances (from the noise model, ``groundsim.render``):

* electrons: ``|new - old| <= 0.01 sqrt(old) + 1e-3`` per pixel. ``old`` is the pixel's mean
  signal, whose photon noise is ``sqrt(old)``: a difference of 1 % of that changes the pixel's
  noise variance by 1e-4 of itself, far below anything a frame can show; the 1e-3 e- floor is
  rounding (float32 keeps ~1e-4 e- at 1000 e-).
* frames: the same noise stream turns ``mean`` into ``floor(bias + (mean + sigma z) / gain + 0.5)``
  with gain 4 e-/DN, so a mean moved by ``d`` e- moves the pre-rounding value by ~``d / 4`` DN and
  changes the DN (by one) with probability ~``|d| / 4``; below the electron tolerance
  (``d`` < 0.5 e- here) no pixel can move by 2 DN. At least 99.9 % of the pixels identical asks for a
  mean ``|d|`` below ~4e-3 e-: the renderer must be the same scene, not merely within the noise.
"""
from __future__ import annotations

import contextlib
import sys
from pathlib import Path

import numpy as np
import pytest

FIXTURE = Path(__file__).resolve().parents[1] / "data" / "aurora_render_fixture.npz"
#: (scenario, frame indices rendered): see the module docstring
CASES = (("aurora_surge_wfov_uv", (0, 30, 60, 90, 120)),
         ("aurora_train_dusk_dayglow", (0,)),
         ("launch_nfov", (0,)))
E_REL, E_ABS = 0.01, 1e-3          # electron tolerance: E_REL * sqrt(old) + E_ABS
MIN_SAME_DN = 0.999                # fraction of the frame's pixels with the same DN
MAX_DN = 1                         # largest DN difference allowed anywhere
#: the stored arrays' dtype by key suffix; every one is [244, 256]
DTYPES = {"extended": np.dtype("<f4"), "frame": np.dtype("<u2")}
SHAPE = (244, 256)


def _to_planes(a: np.ndarray) -> np.ndarray:
    """uint8 [itemsize, a.size]: byte j of every element in row j (smooth images deflate better)."""
    return np.ascontiguousarray(a.reshape(-1).view(np.uint8).reshape(-1, a.itemsize).T)


def _from_planes(p: np.ndarray, dtype: np.dtype) -> np.ndarray:
    return np.ascontiguousarray(p.T).view(dtype).reshape(SHAPE)


@contextlib.contextmanager
def _captured_extended(out: list):
    """Within the block, every ``AuroraScene.image`` result is also appended (a copy) to ``out``."""
    from groundsim.aurora import AuroraScene
    real = AuroraScene.image

    def image(self, *args):
        img = real(self, *args)
        out.append(np.array(img, np.float32))
        return img

    AuroraScene.image = image
    try:
        yield
    finally:
        AuroraScene.image = real


def render_case(name: str, frames) -> dict:
    """``{"<name>__<k>__extended": float32 [244, 256], "<name>__<k>__frame": uint16 [244, 256]}``
    for the frame indices ``frames`` of scenario ``name`` in the open loop."""
    from groundsim import Scenario
    w = Scenario.load(name).world()
    w.reset()
    out = {}
    for k in range(max(frames) + 1):
        if k in frames:
            ext = []
            with _captured_extended(ext):
                frame, truth = w.render()
            assert truth["frame_index"] == k and len(ext) == 1, (name, k, len(ext))
            out[f"{name}__{k}__extended"] = ext[0]
            out[f"{name}__{k}__frame"] = frame.copy()
        w.advance()
    return out


def write_fixture(path: Path = FIXTURE) -> None:
    data = {}
    for name, frames in CASES:
        for key, a in render_case(name, frames).items():
            assert a.shape == SHAPE and a.dtype == DTYPES[key.rsplit("__", 1)[1]], key
            data[key] = _to_planes(a)
    np.savez_compressed(path, **data)
    print(f"wrote {path} ({path.stat().st_size / 1e6:.2f} MB, {len(data)} arrays)")


@pytest.fixture(scope="module")
def stored():
    with np.load(FIXTURE) as z:
        return {k: _from_planes(z[k], DTYPES[k.rsplit("__", 1)[1]]) for k in z.files}


@pytest.mark.parametrize("name, frames", CASES)
def test_renderer_draws_the_fixture_scene(stored, name, frames):
    new = render_case(name, frames)
    assert sorted(new) == sorted(k for k in stored if k.startswith(name + "__"))
    for k in frames:
        key = f"{name}__{k}__"
        old_e, new_e = stored[key + "extended"].astype(float), new[key + "extended"].astype(float)
        tol = E_REL * np.sqrt(np.maximum(old_e, 0.0)) + E_ABS
        err = np.abs(new_e - old_e)
        worst = np.unravel_index(np.argmax(err - tol), err.shape)
        over = int((err > tol).sum())
        assert over == 0, f"{key}: {over} pixels over; worst {worst}: {old_e[worst]} -> {new_e[worst]} e-"
        d = np.abs(new[key + "frame"].astype(int) - stored[key + "frame"].astype(int))
        moved = int((d != 0).sum())
        assert d.max() <= MAX_DN, f"{key}: a pixel moved by {d.max()} DN"
        assert moved <= (1.0 - MIN_SAME_DN) * d.size, f"{key}: {moved} pixels changed DN"


def test_the_fixture_covers_the_glow_paths(stored):
    """The cases reach what the renderer draws: aurora far above the airglow in every surge frame,
    the low night limb (one plateau value, ``limb_kR * e_per_kR``, over >= 1 % of the dusk field)
    beside sunlit Earth and aurora, and the Earth glow alone (airglow, < 1 e-) in the NFOV."""
    surge = [stored[f"aurora_surge_wfov_uv__{k}__extended"] for k in CASES[0][1]]
    assert all(img.max() > 50 * np.median(img) for img in surge)
    dusk = stored["aurora_train_dusk_dayglow__0__extended"]
    values, counts = np.unique(dusk, return_counts=True)
    assert counts.max() > 0.01 * dusk.size and dusk.max() > 2 * values[np.argmax(counts)]
    glow = stored["launch_nfov__0__extended"]
    assert glow.min() > 0 and glow.max() < 1.0


if __name__ == "__main__":
    if sys.argv[1:] != ["--write"]:
        sys.exit(f"usage: PYTHONPATH=. python {sys.argv[0]} --write")
    write_fixture()
