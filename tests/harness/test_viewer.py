"""The event viewer without a browser: what the page carries, read back and compared with the
recording read by h5py (the oracle), the frame packing undone by plain numpy + zlib, the covariance
ellipse against its closed form, ``uvisi view`` errors, partial and ``--no-frames`` recordings, and
``--serve`` answered over HTTP."""
from __future__ import annotations

import json
import re
import shutil
import threading
import urllib.error
import urllib.request
import zlib

import h5py
import numpy as np
import pytest

from hil_harness.cli import main as cli
from hil_harness.event.checksum import attrs_digest
from hil_harness.event.io import EventWriter, run_event
from hil_harness.view import make_server, open_recording, write_page
from hil_harness.view.codec import pack
from hil_harness.view.data import covariance_ellipse, extract

FRAMES = 24


@pytest.fixture(scope="module")
def event(tmp_path_factory):
    """A 24-frame event with its figures and view.html (the lock comes at frame 14)."""
    out = tmp_path_factory.mktemp("view") / "ev"
    run_event("satellite_over_stars", frames=FRAMES, out=out, figures=True)
    return out


def unpack(blob: bytes, shape, dtype) -> np.ndarray:
    """The inverse of the page's packing, written here from its definition: inflate, then byte j of
    pixel i is at j * n + i, little-endian."""
    dt = np.dtype(dtype).newbyteorder("<")
    n = shape[0] * shape[1]
    planes = np.frombuffer(zlib.decompress(blob), np.uint8).reshape(dt.itemsize, n)
    return planes.T.copy().view(dt).reshape(shape)


def page_parts(html: str) -> tuple[dict, dict]:
    def block(name):
        m = re.search(rf'<script type="application/json" id="{name}">(.*?)</script>', html, re.S)
        return json.loads(m.group(1).replace("<\\/", "</"))
    return block("uvisi-data"), block("uvisi-images")


def test_pack_is_lossless_for_every_page_dtype():
    rng = np.random.default_rng(3)
    for dtype, lo, hi in ((np.uint16, 0, 4096), (np.int16, -32768, 32768),
                          (np.int32, -2**31, 2**31), (np.uint8, 0, 256)):
        a = rng.integers(lo, hi, size=(37, 53)).astype(dtype)
        assert np.array_equal(unpack(pack(a), a.shape, dtype), a), dtype
    with pytest.raises(ValueError, match="integer images"):
        pack(np.zeros((4, 4), np.float32))


def test_event_writes_view_html_and_page_matches_recording(event):
    page = event / "view.html"
    assert page.stat().st_size > 100_000
    data, images = page_parts(page.read_text())
    with h5py.File(event / "recording.h5", "r") as f:
        frames = f["arrays/frames"][()]
        fr = f["tables/frames"][()]
        cand = f["tables/candidates"][()]
        mw, cw = f["arrays/message_words"][()], f["arrays/command_words"][()]
    assert data["recording"]["complete"] and data["recording"]["frames_held"] == FRAMES
    for k in (0, 13, FRAMES - 1):                      # the 12-bit frames, bit for bit
        e = images["frames"][k]
        import base64
        got = unpack(base64.b64decode(e["data"]), e["shape"], np.uint16)
        assert np.array_equal(got, frames[k])
    for k in range(FRAMES):
        mine = cand[cand["k"] == k]
        rows = data["candidates"][k]
        assert [r[0] for r in rows] == list(mine["rank"])
        gi = data["candidate_columns"].index("gof")
        np.testing.assert_allclose([r[gi] for r in rows], mine["gof"], rtol=1e-6)
        for name in data["feature_names"]:
            j = data["candidate_columns"].index(name)
            np.testing.assert_allclose([r[j] for r in rows], mine[name], rtol=1e-6, atol=1e-12)
        # the window and the TP's choice, from the bus words as docs/formats.md lays them out
        w = mw[k]
        assert data["frames"]["window"]["row0"][k] == int(np.int16(w[7]))
        assert data["frames"]["window"]["rows"][k] == int(w[9])
        c = cw[k]
        want = int(c[12]) if c[8] & 0x40 else -1
        assert data["frames"]["object_index"][k] == want
        assert data["frames"]["locked"][k] == int(fr["locked"][k])
    assert any(i >= 0 for i in data["frames"]["object_index"])


def test_budget_sums_to_the_frames_cycles(event):
    with open_recording(event / "recording.h5") as rec:
        data = extract(rec)
        fr = rec.table("frames")
    stages, per = data["budget"]["stages"], data["budget"]["frames"]
    for k in (0, FRAMES - 1):
        for proc, col in (("dsp", "dsp_cycles"), ("ip1750", "ip1750_cycles"),
                          ("tp1750", "tp1750_cycles")):
            ms = sum(v for i, v in per[k] if stages[i].startswith(proc + "/"))
            want = 1e3 * int(fr[col][k]) / data["processors"][proc]["clock_hz"]
            assert ms == pytest.approx(want, rel=1e-4), (k, proc)


def test_stars_recorded_and_stages_replayed_for_every_frame(event):
    data, images = page_parts((event / "view.html").read_text())
    with h5py.File(event / "recording.h5", "r") as f:
        n_stars = f["tables/truth"]["n_stars"]
        sk = f.attrs["stage_frame"]
        recorded = {name[len("stage_"):]: f["arrays"][name][0] for name in f["arrays"]
                    if name.startswith("stage_")}
    assert [len(s) for s in data["stars"]] == list(n_stars)
    assert data["stage_mismatch"] is None
    assert sorted(int(k) for k in images["stages"]) == list(range(FRAMES))
    import base64
    replayed = {e["name"]: unpack(base64.b64decode(e["data"]), e["shape"], e["dtype"])
                for e in images["stages"][str(sk)]}
    assert set(replayed) == set(recorded)                # the replay reproduces the recorded stages
    for name, img in recorded.items():
        assert np.array_equal(replayed[name], img), name


def test_page_of_a_recording_replay_cannot_run(event, tmp_path):
    path = tmp_path / "recording.h5"
    shutil.copy(event / "recording.h5", path)
    with h5py.File(path, "r+") as f:               # a configuration replay cannot rebuild
        cfg = json.loads(f.attrs["config"])
        del cfg["sequence"]
        f.attrs["config"] = json.dumps(cfg)
        sk = int(f.attrs["stage_frame"])
    with pytest.raises(ValueError, match="root attributes: changed since they were written"):
        write_page(path)                             # an edit of the attributes is seen ...
    with h5py.File(path, "r+") as f:                 # ... unless resealed, as a writer would
        f.attrs["attrs_sha256"] = attrs_digest(dict(f.attrs))
    data, images = page_parts(write_page(path).read_text())
    assert list(images["stages"]) == [str(sk)]      # the recording's own stage frame, and why
    assert "could not be replayed" in data["stage_note"] and data["stage_error"]
    assert data["candidates"] and len(images["frames"]) == FRAMES


def test_replay_that_differs_is_said(event, tmp_path):
    path = tmp_path / "recording.h5"
    shutil.copy(event / "recording.h5", path)
    with h5py.File(path, "r+") as f:               # one recorded command word changed
        w = f["arrays/command_words"][7]
        w[3] ^= 1
        f["arrays/command_words"][7] = w
    with pytest.raises(ValueError, match="arrays/command_words row 7 .frame 7."):
        write_page(path)                             # the checksum catches it first
    data, _ = page_parts(write_page(path, checksums="ignore").read_text())
    assert data["stage_mismatch"] == 7 and "from frame 7" in data["stage_note"]


def test_covariance_ellipse_closed_form():
    from groundsim.imagers import get_imager
    im = get_imager("wfov_vis")
    rng_m, sy, sz = 1.0e6, 300.0, 120.0                  # object 1000 km along the boresight
    e = covariance_ellipse(im, [1.0, 0, 0, 0], np.zeros(3), [rng_m, 0, 0],
                           np.diag([5000.0 ** 2, sy ** 2, sz ** 2]))
    row0, col0 = im.vec_to_pixel(np.array([1.0, 0, 0]))
    assert e[0] == pytest.approx(float(row0)) and e[1] == pytest.approx(float(col0))
    a_px, b_px = sy / rng_m / im.scale_col, sz / rng_m / im.scale_row   # small-angle closed form
    assert (e[2], e[3]) == pytest.approx((max(a_px, b_px), min(a_px, b_px)), rel=1e-3)
    assert covariance_ellipse(im, [1.0, 0, 0, 0], np.zeros(3), [-rng_m, 0, 0], np.eye(3)) is None


def test_partial_and_no_frames_recordings_open(tmp_path, monkeypatch):
    real = EventWriter.__call__

    def stop_at_13(self, o):
        if o.k == 13:
            raise KeyboardInterrupt
        real(self, o)

    monkeypatch.setattr(EventWriter, "__call__", stop_at_13)
    with pytest.raises(KeyboardInterrupt):
        run_event("satellite_over_stars", frames=20, out=tmp_path / "cut", figures=False,
                  flush_every=5)
    monkeypatch.undo()
    partial = tmp_path / "cut" / "recording.partial.h5"
    assert cli(["-q", "view", str(partial), "-o", str(tmp_path / "cut.html")]) == 0
    data, images = page_parts((tmp_path / "cut.html").read_text())
    assert data["recording"]["complete"] is False and data["recording"]["frames_held"] == 13
    assert data["recording"]["frames_planned"] == 20 and len(images["frames"]) == 13
    run_event("satellite_over_stars", frames=6, out=tmp_path / "nf", figures=False,
              record_frames=False)
    path = write_page(tmp_path / "nf" / "recording.h5")
    data, images = page_parts(path.read_text())
    assert data["recording"]["has_frames"] is False and images["frames"] == [None] * 6
    assert "--no-frames" in data["stage_note"] and len(data["candidates"]) == 6


def test_cli_errors_are_one_line(tmp_path, capsys, event):
    bad = tmp_path / "x.h5"
    with h5py.File(bad, "w") as f:
        f.attrs["format"] = "something else"
    (tmp_path / "junk.h5").write_text("not hdf5")
    cases = [([str(tmp_path / "none.h5")], "no such recording"), ([str(bad)], "not a uvisi recording"),
             ([str(tmp_path / "junk.h5")], "not a readable HDF5"), ([str(tmp_path)], "is a folder"),
             ([str(event / "recording.h5"), "--port", "9"], "--port is for --serve"),
             ([str(event / "recording.h5"), "-o", str(tmp_path / "junk.h5" / "p.html")],
              "junk.h5 is a file, not a folder")]
    for argv, msg in cases:
        assert cli(["view"] + argv) == 2, argv
        err = capsys.readouterr().err.strip()
        assert err.startswith("uvisi view: error:") and msg in err and "\n" not in err, err
    assert not list(tmp_path.glob("*.tmp"))
    # a missing folder is made, as every writer does
    assert cli(["view", str(event / "recording.h5"), "-o", str(tmp_path / "no" / "p.html")]) == 0
    assert (tmp_path / "no" / "p.html").stat().st_size > 1000


def _get(url):
    try:
        with urllib.request.urlopen(url, timeout=30) as r:
            return r.status, r.read()
    except urllib.error.HTTPError as exc:
        return exc.code, exc.read()


def test_serve_fetches_frames_on_demand(event, tmp_path, capsys):
    rec_path = tmp_path / "recording.h5"
    shutil.copy(event / "recording.h5", rec_path)
    srv = make_server(rec_path, port=0)
    assert srv.server_address[0] == "127.0.0.1"
    th = threading.Thread(target=srv.serve_forever, daemon=True)
    th.start()
    try:
        status, page = _get(srv.url)
        assert status == 200 and len(page) < 400_000            # no frame inside the page
        data, images = page_parts(page.decode())
        assert images == {"mode": "serve"} and data["recording"]["frames_held"] == FRAMES
        with h5py.File(rec_path, "r") as f:
            want = f["arrays/frames"][7]
            stage_k = int(f.attrs["stage_frame"])
            stage_names = {n[len("stage_"):] for n in f["arrays"] if n.startswith("stage_")}
        status, blob = _get(srv.url + "frames/7")
        assert status == 200 and np.array_equal(unpack(blob, want.shape, np.uint16), want)
        status, body = _get(srv.url + f"stages/{stage_k}")
        st = json.loads(body)
        assert status == 200 and {e["name"] for e in st["stages"]} == stage_names
        assert st["mismatch"] is None
        with h5py.File(rec_path, "r") as f:
            st = f["tables/stars"][()]
        st = st[st["k"] == 9]
        got = np.array(json.loads(_get(srv.url + "stars/9")[1]))
        assert data["stars"] == [] and len(got) == len(st) > 50        # stars come per frame
        np.testing.assert_allclose(got[:, 0], st["row"], atol=0.005)
        np.testing.assert_allclose(got[:, 2], st["mag"], atol=0.05)
        assert _get(srv.url + f"frames/{FRAMES}")[0] == 404
        assert _get(srv.url + "etc/passwd")[0] == 404
        assert json.loads(_get(srv.url + "data.json")[1])["recording"]["frames_held"] == FRAMES
        port = str(srv.server_address[1])                  # a second server on the same port
        assert cli(["view", str(rec_path), "--serve", "--port", port]) == 2
        assert "cannot listen on 127.0.0.1" in capsys.readouterr().err
    finally:
        srv.shutdown()
        srv.server_close()


# ---------------------------------------------------------------- a recording's text is data
def test_served_page_answers_only_its_own_host_names(event, tmp_path):
    """DNS rebinding: a page of another site that resolves to 127.0.0.1 sends its own Host."""
    import http.client
    rec_path = tmp_path / "recording.h5"
    shutil.copy(event / "recording.h5", rec_path)
    srv = make_server(rec_path, port=0)
    assert srv.server_address[0] == "127.0.0.1"               # loopback only
    port = srv.server_address[1]
    threading.Thread(target=srv.serve_forever, daemon=True).start()

    def get(path, host):
        c = http.client.HTTPConnection("127.0.0.1", port, timeout=30)
        c.putrequest("GET", path, skip_host=True)
        if host is not None:
            c.putheader("Host", host)
        c.endheaders()
        r = c.getresponse()
        body = r.read()
        c.close()
        return r.status, body, r.getheader("Content-Security-Policy") or ""

    try:
        for host in ("evil.example", f"evil.example:{port}", "127.0.0.1", f"127.0.0.1:{port + 1}",
                     f"localhost.evil.example:{port}", "", None):
            for path in ("/", "/data.json", "/frames/3", "/stages/3", "/stars/3"):
                status, body, _ = get(path, host)
                assert 400 <= status < 500 and b"Host" in body and len(body) < 200, (host, path)
        for host in (f"127.0.0.1:{port}", f"localhost:{port}", f"LOCALHOST:{port}"):
            status, body, csp = get("/data.json", host)
            assert status == 200 and json.loads(body)["recording"]["frames_held"] == FRAMES
            assert "script-src 'sha256-" in csp and "frame-ancestors 'none'" in csp
        for path in ("/../recording.h5", "/recording.h5", "/etc/passwd", "/frames/../data.json",
                     "/frames/-1", f"/frames/{FRAMES}", "//etc/passwd"):
            assert get(path, f"127.0.0.1:{port}")[0] == 404, path
    finally:
        srv.shutdown()
        srv.server_close()


def test_page_inserts_text_never_html():
    """page.js builds every element with its text helper: no HTML parsing of any string; the
    template's placeholders are filled in one pass, and the JSON cannot end its script element."""
    from importlib.resources import files
    from hil_harness.view.page import page_html, script_json
    js = files("hil_harness.view").joinpath("page.js").read_text()
    for sink in ("innerHTML", "outerHTML", "insertAdjacentHTML", "document.write", "eval(",
                 "new Function", "srcdoc", "DOMParser", "createContextualFragment"):
        assert sink not in js, sink
    x = '</script><img src=x onerror=alert(1)> __DATA__ __JS__ & <!--'
    text = script_json({"a": x})
    assert json.loads(text) == {"a": x} and not set("<>&") & set(text)
    data = {"recording": {"scenario": x, "name": "__CSP__"}, "v": x}
    page = page_html(data, {"mode": "serve"})
    assert page_parts(page) == (data, {"mode": "serve"})      # each value where it belongs
    script = re.search(r"<script>\n(.*)\n</script>", page, re.S).group(1)
    assert script == js
    title = re.search(r"<title>(.*?)</title>", page, re.S).group(1)
    assert title == ("uvisi view: &lt;/script&gt;&lt;img src=x onerror=alert(1)&gt; __DATA__ "
                     "__JS__ &amp; &lt;!-- (__CSP__)")
    assert page.count("<img") == 0 and page.count("</script>") == 3
