"""Recordings that cannot be quietly edited (issue 39, item 5).

The root attributes that describe the run are sealed by a SHA-256 digest (``attrs_sha256``); rows by
their Adler-32 checksums. Oracles: the targeted edits of the issue (each root attribute, the format,
the checksums), and a sweep of byte flips over the whole file where every flip must either be
refused by ``uvisi replay`` (exit != 0) or have changed nothing the file means (every dataset and
attribute read back equal to the original's, compared with h5py).
"""
from __future__ import annotations

import json
import os
import shutil

import h5py
import numpy as np
import pytest

from hil_harness.cli import main

ATTRS = ("summary", "config", "seed", "n_frames", "complete", "run_id", "scenario", "versions",
         "scenario_raw", "uplink_words", "record_words", "record_frames", "flush_every")


@pytest.fixture(scope="module")
def sealed(tmp_path_factory):
    from hil_harness.event.io import run_event
    d = tmp_path_factory.mktemp("seal")
    run_event("satellite_over_stars", frames=8, out=d / "ev", figures=False)
    return d / "ev" / "recording.h5"


def _replay(path, capsys, *extra) -> int:
    capsys.readouterr()
    rc = main(["replay", str(path), *extra])
    capsys.readouterr()
    return rc


def _edited(value):
    if isinstance(value, (bool, np.bool_)):
        return not value
    if isinstance(value, (int, np.integer)):
        return int(value) + 1
    if isinstance(value, str) and value[:1] in "[{":
        v = json.loads(value)
        if isinstance(v, dict):
            v["edited"] = 1
        else:
            v.append(0)
        return json.dumps(v)
    return str(value) + "x"


def test_a_sealed_recording_replays_and_passes(sealed, capsys):
    assert _replay(sealed, capsys) == 0


@pytest.mark.parametrize("key", ATTRS)
def test_every_edited_root_attribute_is_refused(sealed, tmp_path, capsys, key):
    p = tmp_path / "r.h5"
    shutil.copy(sealed, p)
    with h5py.File(p, "r+") as f:
        assert key in f.attrs
        f.attrs[key] = _edited(f.attrs[key])
    assert _replay(p, capsys) != 0


@pytest.mark.parametrize("edit", ["downgrade", "downgrade_no_checksums", "no_checksums",
                                  "no_digest"])
def test_a_downgrade_or_missing_seal_is_refused(sealed, tmp_path, capsys, edit):
    p = tmp_path / "r.h5"
    shutil.copy(sealed, p)
    with h5py.File(p, "r+") as f:
        if edit.startswith("downgrade"):
            f.attrs["format"] = "uvisi-recording/1" if "no_checksums" in edit \
                else "uvisi-recording/2"
            del f.attrs["attrs_sha256"]
        if "no_checksums" in edit:
            del f["checksums"]
        if edit == "no_digest":
            del f.attrs["attrs_sha256"]
    assert _replay(p, capsys) != 0
    if edit.startswith("downgrade"):                 # an older format: readable when accepted
        assert _replay(p, capsys, "--accept-unverified") == 0


def _content(path) -> dict:
    out = {}
    with h5py.File(path, "r") as f:
        out["attrs"] = {k: np.asarray(v).tobytes() if not isinstance(v, str) else v
                        for k, v in f.attrs.items()}

        def visit(name, obj):
            if isinstance(obj, h5py.Dataset):
                out[name] = (obj.dtype.str, obj[()].tobytes())
                out[name + "@attrs"] = {k: str(v) for k, v in obj.attrs.items()}
        f.visititems(visit)
    return out


def test_byte_flips_are_refused_or_change_nothing(sealed, tmp_path, capsys):
    """Single-bit flips over the file (seeded; 64, or ``UVISI_FLIPS``): each is refused by replay,
    or the file reads back exactly as before (the flip hit bytes HDF5 does not use)."""
    raw = sealed.read_bytes()
    want = _content(sealed)
    rng = np.random.default_rng(39)
    refused = quiet = 0
    for i, pos in enumerate(rng.integers(0, len(raw), int(os.environ.get("UVISI_FLIPS", 64)))):
        b = bytearray(raw)
        b[int(pos)] ^= 1 << int(rng.integers(0, 8))
        p = tmp_path / f"f{i}.h5"
        p.write_bytes(bytes(b))
        if _replay(p, capsys) != 0:
            refused += 1
            continue
        try:
            got = _content(p)
        except Exception:                            # unreadable after all: a change unseen
            got = None
        assert got == want, f"a flip at byte {int(pos)} changed the file and replay passed"
        quiet += 1
    assert refused > 0
