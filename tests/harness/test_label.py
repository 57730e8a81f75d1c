"""``uvisi label`` without a browser: the labels file against the project's own reader
(:func:`hil_harness.tuning.data.load_labels`) and ``hashlib``; the atomic rewrite; resuming; the
hash check; the server's routes and refusals over HTTP; the command end to end in a process of its
own (a label posted as the page posts it, then Done; then Ctrl-C); its one-line errors."""
from __future__ import annotations

import hashlib
import http.client
import json
import os
import re
import signal
import socket
import subprocess
import sys
import threading
from datetime import datetime
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from hil_harness.cli import main
from hil_harness.label import LabelInputs, LabelSession, make_server
from hil_harness.tuning.data import load_labels

ROOT = Path(__file__).resolve().parents[2]
TOOL = "uvisi label test"


@pytest.fixture
def images(tmp_path):
    """A 3-frame NPZ sequence (48 x 64) and a single 8-bit PNG (30 x 40)."""
    rng = np.random.default_rng(7)
    seq = rng.normal(100, 5, (3, 48, 64)).astype(np.float32)
    np.savez(tmp_path / "seq.npz", img=seq)
    Image.fromarray(rng.integers(0, 256, (30, 40), dtype=np.uint8)).save(tmp_path / "one.png")
    return tmp_path / "seq.npz", tmp_path / "one.png"


def session(images, out, labeller="ada", **kw):
    return LabelSession(LabelInputs(images), out, labeller, TOOL, "l", **kw)


def test_the_file_reads_back_through_the_tuning_reader(images, tmp_path):
    out = tmp_path / "labels" / "l.csv"                  # its folder made on the first write
    s = session(images, out)
    assert not out.exists()                              # nothing written before a change
    s.set_label(0, "point", 12.345, 60.5)                # seq.npz frame 0 (kept to 0.01 px)
    s.set_label(2, "absent")                             # seq.npz frame 2
    s.set_label(3, "point", 29.999, 0.0)                 # one.png frame 0: the frame's edges
    s.set_label(1, "point", 1.0, 2.0)
    s.set_label(1, "clear")                              # cleared: no row at all
    assert load_labels(out) == {("seq.npz", 0): (12.35, 60.5), ("seq.npz", 2): None,
                                ("one.png", 0): (30.0, 0.0)}
    assert s.counts() == {"labelled": 2, "absent": 1, "unlabelled": 1}
    text = out.read_text()
    assert "\nseq.npz,2,,\n" in text                     # absent: blank row and col
    head = [ln for ln in text.splitlines() if ln.startswith("#")]
    assert "# labeller: ada" in head and f"# tool: {TOOL}" in head and "# channel: l" in head
    date = next(ln for ln in head if ln.startswith("# date: "))[8:]
    assert abs((datetime.now().astimezone() - datetime.fromisoformat(date)).total_seconds()) < 60
    hashes = dict(re.findall(r"^# image: (\S+) sha256=([0-9a-f]{64})$", text, re.M))
    assert hashes == {p.name: hashlib.sha256(p.read_bytes()).hexdigest() for p in images}


def test_out_of_range_changes_are_refused_and_change_nothing(images, tmp_path):
    s = session(images, tmp_path / "l.csv")
    for g, kind, row, col in ((4, "point", 1, 1), (-1, "absent", None, None),
                              (True, "absent", None, None), (0, "point", 48.01, 3),
                              (0, "point", 3, float("nan")), (0, "point", "3", 3),
                              (0, "moved", None, None)):
        with pytest.raises(ValueError):
            s.set_label(g, kind, row, col)
    assert not (tmp_path / "l.csv").exists()


def test_an_interrupted_rewrite_leaves_the_previous_file_whole(images, tmp_path, monkeypatch):
    out = tmp_path / "l.csv"
    s = session(images, out)
    s.set_label(0, "point", 5, 6)
    before = out.read_bytes()

    def power_cut(fd):
        raise OSError(5, "Input/output error")
    monkeypatch.setattr(os, "fsync", power_cut)           # the new text written, not yet renamed
    with pytest.raises(OSError):
        s.set_label(1, "point", 7, 8)
    assert out.read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["l.csv", "one.png", "seq.npz"]
    assert s.label(1) == "unlabelled"                    # the session keeps what the file holds


def test_a_reader_never_sees_a_partial_file(images, tmp_path):
    """A reader polling the file while it is rewritten 100 times finds every version whole."""
    out = tmp_path / "l.csv"
    s = session(images, out)
    s.set_label(0, "point", 1, 1)
    seen, stop, bad = [], threading.Event(), []

    def poll():
        while not stop.is_set():
            try:
                seen.append(len(load_labels(out)))
            except Exception as exc:       # noqa: BLE001 - any failure is what the test looks for
                bad.append(repr(exc))
    t = threading.Thread(target=poll)
    t.start()
    try:
        for i in range(100):
            s.set_label(i % 4, "point", 1 + i % 25, 2)
    finally:
        stop.set()
        t.join()
    assert bad == [] and len(seen) > 10 and set(seen) <= {1, 2, 3, 4}


def test_resume_shows_and_keeps_the_labels(images, tmp_path):
    out = tmp_path / "l.csv"
    s = session(images, out)
    s.set_label(0, "point", 10, 20)
    s.set_label(1, "absent")
    text = out.read_text()
    out.write_text("# made by hand, then resumed\n" + text)
    r = session(images, out, labeller="bob")             # resumed
    assert [r.label(g) for g in range(4)] == [(10.0, 20.0), None, "unlabelled", "unlabelled"]
    r.set_label(2, "point", 3.5, 4.5)
    again = out.read_text()
    assert again.startswith("# made by hand, then resumed\n# labeller: ada\n# labeller: bob\n")
    assert load_labels(out) == {("seq.npz", 0): (10.0, 20.0), ("seq.npz", 1): None,
                                ("seq.npz", 2): (3.5, 4.5)}
    only_png = session([images[1]], out)                 # one image now: the others' rows stay
    only_png.set_label(0, "absent")
    assert len(load_labels(out)) == 4 and "3 rows of other images kept" in only_png.summary()


def test_a_changed_image_is_refused_in_one_line(images, tmp_path, capsys):
    out = tmp_path / "l.csv"
    session(images, out).set_label(0, "point", 10, 20)
    seq = np.load(images[0])["img"]
    seq[1, 5, 5] += 1
    np.savez(images[0], img=seq)
    with pytest.raises(ValueError, match="image seq.npz: the SHA-256 recorded"):
        session(images, out)
    assert main(["label", *map(str, images), "-o", str(out), "--port", "0"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "seq.npz" in err[0] and "--accept-changed-images" in err[0], err
    kept = session(images, out, accept_changed=True)
    assert kept.label(0) == (10.0, 20.0) and "has changed" in kept.notes[0]
    kept.set_label(1, "absent")
    want = hashlib.sha256(images[0].read_bytes()).hexdigest()
    assert f"# image: seq.npz sha256={want}\n" in out.read_text()


def test_a_name_the_reader_could_take_for_a_comment_is_quoted(tmp_path):
    img = tmp_path / "#3, night.png"
    Image.fromarray(np.zeros((20, 20), np.uint8)).save(img)
    out = tmp_path / "l.csv"
    s = session([img], out)
    s.set_label(0, "point", 1.25, 2.5)
    assert load_labels(out) == {("#3, night.png", 0): (1.25, 2.5)}
    assert session([img], out).label(0) == (1.25, 2.5)


def test_a_file_holding_only_its_header_resumes_empty(images, tmp_path):
    out = tmp_path / "l.csv"
    s = session(images, out)
    s.set_label(0, "absent")
    s.set_label(0, "clear")
    assert session(images, out).counts()["unlabelled"] == 4


def test_frames_evicted_from_memory_are_read_again(images):
    inputs = LabelInputs(images, cache_bytes=1)         # keeps one file's frames at a time
    seq = np.load(images[0])["img"]
    png = np.asarray(Image.open(images[1]), np.float32)
    for g in (3, 1, 3, 0, 2):
        want = png if g == 3 else seq[g]
        assert inputs.frame(g).dtype == np.float32 and np.array_equal(inputs.frame(g), want)


# ---------------------------------------------------------------- the server over HTTP
@pytest.fixture
def served(images, tmp_path):
    s = session(images, tmp_path / "l.csv")
    srv = make_server(s, 0)
    t = threading.Thread(target=srv.serve_forever, daemon=True)
    t.start()
    yield srv
    srv.shutdown()
    srv.server_close()


def request(srv, method, path, body=None, host=None, origin="own", ctype="application/json"):
    port = srv.server_address[1]
    c = http.client.HTTPConnection("127.0.0.1", port, timeout=10)
    headers = {"Host": host or f"127.0.0.1:{port}"}
    if method == "POST":
        headers["Content-Type"] = ctype
        if origin:
            headers["Origin"] = f"http://127.0.0.1:{port}" if origin == "own" else origin
    c.request(method, path, body=None if body is None else json.dumps(body), headers=headers)
    r = c.getresponse()
    return r.status, r.read(), r.getheader("Content-Security-Policy")


def test_the_routes_answer_and_foreign_requests_are_refused(served, images):
    status, page, csp = request(served, "GET", "/")
    assert status == 200 and b"uvisi label" in page and "script-src 'sha256-" in csp
    status, body, _ = request(served, "GET", "/data.json")
    data = json.loads(body)
    assert data["frames"] == [[0, 0, 48, 64], [0, 1, 48, 64], [0, 2, 48, 64], [1, 0, 30, 40]]
    want = np.load(images[0])["img"][1]
    status, body, _ = request(served, "GET", "/frames/1")
    assert status == 200 and np.array_equal(np.frombuffer(body, "<f4").reshape(48, 64), want)
    assert request(served, "GET", "/frames/4")[0] == 404
    status, body, _ = request(served, "POST", "/label", {"frame": 1, "kind": "point", "row": 2.5,
                                                          "col": 3.25})
    assert status == 200 and json.loads(body)["label"] == [2.5, 3.25]
    assert load_labels(served.session.out) == {("seq.npz", 1): (2.5, 3.25)}
    status, body, _ = request(served, "POST", "/label", {"frame": 1, "kind": "point", "row": -1,
                                                          "col": 3})
    assert status == 400 and "row -1" in json.loads(body)["error"]
    change = {"frame": 0, "kind": "absent"}
    assert request(served, "GET", "/", host="evil.example:80")[0] == 403
    assert request(served, "POST", "/label", change, origin="http://evil.example")[0] == 403
    assert request(served, "POST", "/label", change, origin=None)[0] == 403
    assert request(served, "POST", "/label", change, ctype="text/plain")[0] == 403
    assert served.session.label(0) == "unlabelled"       # none of them changed anything
    status, body, _ = request(served, "POST", "/done", {})
    assert status == 200 and "1 labelled, 0 absent, 3 unlabelled" in json.loads(body)["summary"]
    assert served.done.wait(5)


# ---------------------------------------------------------------- the command
def start(argv, tmp_path):
    """``uvisi label ARGV`` in a process of its own, with Ctrl-C's signal at its default as a
    terminal gives it (a suite started in the background by a non-interactive shell ignores
    SIGINT, and its children would inherit that) -> (process, port)."""
    env = dict(os.environ, PYTHONPATH=str(ROOT), UVISI_PROGRESS="0")
    p = subprocess.Popen([sys.executable, "-m", "hil_harness.cli", "label", *argv],
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env,
                         cwd=tmp_path,
                         preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    line = p.stdout.readline()
    m = re.search(r"open http://127\.0\.0\.1:(\d+)/", line)
    assert m, (line, p.stderr.read() if p.poll() is not None else "")
    return p, int(m.group(1))


def post(port, path, body):
    c = http.client.HTTPConnection("127.0.0.1", port, timeout=10)
    c.request("POST", path, json.dumps(body), {"Content-Type": "application/json",
                                               "Origin": f"http://127.0.0.1:{port}"})
    r = c.getresponse()
    return r.status, json.loads(r.read())


def test_the_command_ends_with_done_or_ctrl_c(images, tmp_path):
    out = tmp_path / "l.csv"
    p, port = start([*map(str, images), "-o", str(out), "--port", "0", "--labeller", "cy"], tmp_path)
    try:
        assert post(port, "/label", {"frame": 3, "kind": "point", "row": 4, "col": 5})[0] == 200
        assert post(port, "/done", {})[0] == 200
        stdout, stderr = p.communicate(timeout=30)
    finally:
        p.kill()
    assert p.returncode == 0, stderr
    assert stdout.strip().endswith("1 labelled, 0 absent, 3 unlabelled frames (4 frames in 2 files)")
    assert load_labels(out) == {("one.png", 0): (4.0, 5.0)}
    p, port = start([*map(str, images), "-o", str(out), "--port", "0"], tmp_path)   # resumed
    try:
        assert post(port, "/label", {"frame": 0, "kind": "absent"})[0] == 200
        p.send_signal(signal.SIGINT)
        stdout, stderr = p.communicate(timeout=30)
    finally:
        p.kill()
    assert p.returncode == 0 and "1 labelled, 1 absent, 2 unlabelled" in stdout, stderr
    assert load_labels(out) == {("one.png", 0): (4.0, 5.0), ("seq.npz", 0): None}


def test_bad_inputs_are_one_line_errors(images, tmp_path, capsys):
    seq, png = map(str, images)
    (tmp_path / "file").write_text("x")
    (tmp_path / "sub").mkdir()
    Image.fromarray(np.zeros((20, 20), np.uint8)).save(tmp_path / "sub" / "one.png")
    (tmp_path / "bad.csv").write_text("image,frame,row,col\nseq.npz,x,1,2\nseq.npz,1,1,2\n")
    (tmp_path / "far.csv").write_text("image,frame,row,col\nseq.npz,7,1,2\n")
    (tmp_path / "bin.csv").write_bytes(bytes(range(256)))
    busy = socket.socket()
    busy.bind(("127.0.0.1", 0))
    busy.listen()
    port = busy.getsockname()[1]
    cases = [
        ([seq, "-o", f"{tmp_path}/file/l.csv"], "is a file"),
        ([seq, "-o", str(tmp_path / "sub")], "is a folder"),
        ([str(tmp_path / "nope.fits"), "-o", f"{tmp_path}/l.csv"], "nope.fits: no such file"),
        ([str(tmp_path / "file"), "-o", f"{tmp_path}/l.csv"], "file: unsupported format"),
        ([png, f"{tmp_path}/sub/one.png", "-o", f"{tmp_path}/l.csv"], "same file name"),
        ([seq, "-o", f"{tmp_path}/bad.csv"], "bad.csv: line 2: frame 'x'"),
        ([seq, "-o", f"{tmp_path}/far.csv"], "far.csv: image seq.npz frame 7"),
        ([seq, "-o", f"{tmp_path}/bin.csv"], "bin.csv: not a text CSV file"),
        ([seq, "-o", f"{tmp_path}/l.csv", "--port", str(port)], f"--port {port}: cannot listen"),
        ([seq, "-o", f"{tmp_path}/l.csv", "--labeller", " "], "--labeller"),
    ]
    try:
        for argv, expect in cases:
            assert main(["label", *argv]) == 2, argv
            err = capsys.readouterr().err.strip().splitlines()
            assert len(err) == 1 and expect in err[0] and "Traceback" not in err[0], (argv, err)
    finally:
        busy.close()
    assert not (tmp_path / "l.csv").exists()
