"""Figures of an event, as plain functions over arrays (matplotlib, Agg backend).

Each function writes one PNG (or GIF) and returns its path. They take arrays, not recordings, so the
CLI, tests and notebooks can all call them; :mod:`hil_harness.event` feeds them from a recording.
"""
from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

FRAME_PERIOD_MS = 500.0


def _save(fig, path) -> Path:
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(path.stem + ".tmp" + path.suffix)
    fig.savefig(tmp, dpi=110, bbox_inches="tight")
    plt.close(fig)
    tmp.replace(path)
    return path


#: stage names whose images are blob labels (drawn in a categorical colour map, 0 = background)
LABEL_STAGES = ("colour", "labels", "labelled", "blob colouring")


def label_colours(labels: np.ndarray):
    """An RGB image [H, W, 3] float in 0..1 of a label image: background (0) black, each label a
    colour of a categorical map (tab20, cycled), so neighbouring blobs look different."""
    lab = np.asarray(labels, dtype=np.int64)
    cmap = plt.get_cmap("tab20")
    rgb = np.asarray(cmap((lab - 1) % 20))[..., :3]
    rgb[lab <= 0] = 0.0
    return rgb


def _is_labels(name: str, img: np.ndarray) -> bool:
    n = name.lower()
    return any(k in n for k in LABEL_STAGES) and np.issubdtype(np.asarray(img).dtype, np.integer)


def rank_centroids(ranked: np.ndarray, k: int = 10) -> list[tuple[int, float, float]]:
    """(rank, row, col) of the pixel centroids of ranks 1..k in a rank image (value = rank)."""
    out = []
    for i in range(1, k + 1):
        rr, cc = np.nonzero(ranked == i)
        if rr.size:
            out.append((i, float(rr.mean()), float(cc.mean())))
    return out


def stages(images: list[tuple[str, np.ndarray]], path, title: str = "") -> Path:
    """The processing stages of one frame side by side, like the paper's Figure 3.

    images : list of (stage name, 2-D array) in processing order. A blob-colouring label image
        (integer, 0 = background) is drawn in a categorical colour map; a ``rank`` image (each blob's
        pixels hold its rank, 0 = not ranked) is drawn as the window with the ten best candidates
        circled and numbered by rank.
    """
    n = len(images)
    if n == 0:
        raise ValueError("stages(): no stage images to draw")
    cols = min(n, 4)
    rows = (n + cols - 1) // cols
    fig, axes = plt.subplots(rows, cols, figsize=(3.2 * cols, 3.4 * rows), squeeze=False)
    for ax in axes.flat:
        ax.axis("off")
    first = None
    for ax, (name, img) in zip(axes.flat, images):
        if name.lower().startswith("rank") and np.issubdtype(np.asarray(img).dtype, np.integer):
            if first is not None:
                _grey(ax, first)
            top = rank_centroids(np.asarray(img))
            for i, r, c in top:
                ax.plot(c, r, "o", mfc="none", mec="gold", ms=9, mew=1.2)
                ax.annotate(str(i), (c, r), xytext=(5, 4), textcoords="offset points", color="gold",
                            fontsize=8, fontweight="bold")
            ax.set_title(f"{name}: top {len(top)} of {int(np.max(img)) if np.size(img) else 0}",
                         fontsize=9)
        elif _is_labels(name, img):
            ax.imshow(label_colours(img), interpolation="nearest")
            ax.set_title(f"{name} ({int(np.max(img)) if np.size(img) else 0} blobs)", fontsize=9)
        else:
            img = np.asarray(img, dtype=np.float64)
            first = img if first is None else first
            _grey(ax, img)
            ax.set_title(name, fontsize=9)
    if title:
        fig.suptitle(title, fontsize=10)
    return _save(fig, path)


def _grey(ax, img) -> None:
    lo, hi = np.percentile(img, [1, 99.7]) if img.size else (0, 1)
    ax.imshow(img, cmap="gray", vmin=lo, vmax=hi if hi > lo else lo + 1, interpolation="nearest")


def centroid_track(t, rows, cols, path, truth_rows=None, truth_cols=None,
                   shape=(244, 256), title: str = "Tracked object centroid",
                   zoom: bool = False) -> Path:
    """The tracked object's centroid over the frames in imager pixels, like the paper's Figure 6.

    ``zoom``: limits to where most points are (2nd-98th percentile plus a margin of 15 % of that
    span, at least half a pixel; points beyond are counted in the corner) instead of the whole imager. With truth, a second panel shows
    the centroid minus the true position (px), centred on zero.
    """
    t, rows, cols = (np.asarray(x, float) for x in (t, rows, cols))
    has_truth = truth_rows is not None and np.isfinite(np.asarray(truth_rows, float)).any()
    fig, axes = plt.subplots(1, 2 if has_truth else 1, figsize=(11 if has_truth else 6, 5),
                             squeeze=False, layout="constrained")   # labels never overlap
    ax = axes[0, 0]
    sc = ax.scatter(cols, rows, c=t, cmap="viridis", s=14, marker="+")
    ax.plot([], [], "+", color="tab:green", label="tracked centroid (colour: time)")
    if has_truth:
        ax.plot(truth_cols, truth_rows, "-", color="tab:red", lw=1, label="truth")
    ax.set_xlim(0, shape[1])
    ax.set_ylim(shape[0], 0)
    if zoom:
        _zoom(ax, cols, rows, truth_cols, truth_rows)
    ax.set_xlabel("column (px)")
    ax.set_ylabel("row (px)")
    ax.set_aspect("equal")
    fig.colorbar(sc, ax=ax, label="time (s)")
    ax.legend(loc="best", fontsize=8)
    ax.set_title(title, fontsize=10)
    if has_truth:
        ax2 = axes[0, 1]
        dr = rows - np.asarray(truth_rows, float)
        dc = cols - np.asarray(truth_cols, float)
        ok = np.isfinite(dr) & np.isfinite(dc)
        ax2.scatter(dc[ok], dr[ok], c=t[ok], cmap="viridis", s=14, marker="+")
        lim = max(0.5, float(np.percentile(np.abs(np.r_[dr[ok], dc[ok]]), 98)) * 1.2) if ok.any() else 1
        ax2.axhline(0, color="0.7", lw=0.8)
        ax2.axvline(0, color="0.7", lw=0.8)
        ax2.set_xlim(-lim, lim)
        ax2.set_ylim(lim, -lim)
        ax2.set_aspect("equal")
        out = int((ok & ((np.abs(dr) > lim) | (np.abs(dc) > lim))).sum())
        ax2.set_title(f"centroid minus truth (px), {int(ok.sum())} frames" +
                      (f", {out} outside" if out else ""), fontsize=10)
        ax2.set_xlabel("column offset (px)")
        ax2.set_ylabel("row offset (px)")
    return _save(fig, path)


def _zoom(ax, cols, rows, truth_cols, truth_rows) -> None:
    pts_c = np.concatenate([np.ravel(cols), np.ravel(truth_cols if truth_cols is not None else [])])
    pts_r = np.concatenate([np.ravel(rows), np.ravel(truth_rows if truth_rows is not None else [])])
    ok = np.isfinite(pts_c) & np.isfinite(pts_r)
    if not ok.any():
        return
    c0, c1 = np.percentile(pts_c[ok], [2, 98])
    r0, r1 = np.percentile(pts_r[ok], [2, 98])
    pad = max(0.5, 0.15 * max(c1 - c0, r1 - r0))
    c0, c1, r0, r1 = c0 - pad, c1 + pad, r0 - pad, r1 + pad
    h = max(c1 - c0, r1 - r0) / 2
    cc, rc = (c0 + c1) / 2, (r0 + r1) / 2
    ax.set_xlim(cc - h, cc + h)
    ax.set_ylim(rc + h, rc - h)
    out = int((ok & ((np.abs(pts_c - cc) > h) | (np.abs(pts_r - rc) > h))).sum())
    if out:
        ax.text(0.02, 0.02, f"{out} point{'s' if out > 1 else ''} outside the view",
                transform=ax.transAxes, fontsize=8)


def track_error(t, err_urad, path, pixel_urad: float | None = None, lock_t: float | None = None) -> Path:
    """Track error against truth (urad) over time, with its 99.7th percentile
    (:func:`draw_track_error` on a new figure, saved to ``path``)."""
    fig, ax = plt.subplots(figsize=(7, 3.5))
    draw_track_error(ax, t, err_urad, pixel_urad, lock_t)
    return _save(fig, path)


def draw_track_error(ax, t, err_urad, pixel_urad: float | None = None, lock_t: float | None = None):
    """Draw the track error on ``ax``.

    The percentile and its n are computed from the same frames as the event summary: those at or
    after ``lock_t`` (all frames when None); frames before lock are drawn grey. The error axis is
    linear from 0, or logarithmic when the errors span more than two decades (an error is never
    negative, so no axis shows negative values).
    """
    t = np.asarray(t, float)
    e = np.asarray(err_urad, float)
    after = np.ones(len(t), bool) if lock_t is None else t >= lock_t
    if (~after).any():
        ax.plot(t[~after], e[~after], ".", color="0.6", ms=3, label="before lock")
    ax.plot(t[after], e[after], ".-", lw=0.8, ms=3, color="tab:blue",
            label="after lock" if lock_t is not None else "track error")
    ok = np.isfinite(e) & after
    pos = e[np.isfinite(e) & (e > 0)]
    log = pos.size > 0 and np.percentile(pos, 99) > 100 * max(np.percentile(pos, 5), 1e-9)
    if ok.any():
        p997 = np.percentile(e[ok], 99.7)
        scope = " after lock" if lock_t is not None else ""
        ax.axhline(p997, color="tab:red", ls="--", lw=1,
                   label=f"99.7th pct {p997:.1f} urad (n = {int(ok.sum())}{scope})")
    if pixel_urad:
        ax.axhline(pixel_urad, color="gray", ls=":", lw=1, label=f"1 processed px = {pixel_urad:.0f} urad")
    if lock_t is not None:
        ax.axvline(lock_t, color="k", lw=0.8, alpha=0.5)
    ax.set_xlabel("time (s)")
    ax.set_ylabel("track error (urad)")
    if log:
        ax.set_yscale("log")
    else:
        ax.set_ylim(bottom=0)
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3)
    return ax


def gate_history(t, n_star, n_object, path, decision_t=None) -> Path:
    """Live star and object gates per frame, with the star/object decision time."""
    fig, ax = plt.subplots(figsize=(7, 3))
    ax.step(t, n_star, where="post", label="star gates")
    ax.step(t, n_object, where="post", label="object gates")
    if decision_t is not None and np.isfinite(decision_t):
        ax.axvline(decision_t, color="k", ls="--", lw=1, label=f"object verified t={decision_t:.1f} s")
    ax.set_xlabel("time (s)")
    ax.set_ylabel("live gates")
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3)
    return _save(fig, path)


#: a colour map per processor: each processor's stages are shades of its own hue
PROCESSOR_CMAPS = {"dsp": "Blues", "ip1750": "Oranges", "tp1750": "Greens"}


def stage_colours(names: list[str]) -> dict:
    """A distinct colour for each ``"processor/stage"`` name: shades of the processor's hue
    (:data:`PROCESSOR_CMAPS`; others grey), darkest first, so no two stages share a colour."""
    groups: dict[str, list] = {}
    for n in names:
        groups.setdefault(n.split("/", 1)[0], []).append(n)
    out = {}
    for proc, members in groups.items():
        cmap = plt.get_cmap(PROCESSOR_CMAPS.get(proc, "Greys"))
        for i, n in enumerate(members):
            out[n] = cmap(0.9 - 0.6 * i / max(1, len(members) - 1))
    return out


def stacked_bars(frames, per_stage_ms: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """The rectangles of a stacked bar chart, one bar a frame, one layer a stage, in the order
    given: ``{name: float64 (n, 4, 2)}``, each rectangle's corners (x, y) counter-clockwise from
    the lower left, x from ``frame - 0.5`` to ``frame + 0.5``, y from the stages below to them plus
    this one's ms. A stage's zero-height bars are left out (they draw nothing), and so are the
    bars of a frame from its first stage whose ms is not a number on (as ``ax.bar`` draws them).

    frames : (n,) frame numbers; per_stage_ms : {"processor/stage": (n,) ms per frame}
    """
    x = np.asarray(frames, float)
    bottom = np.zeros(len(x))
    out = {}
    for name, ms in per_stage_ms.items():
        top = bottom + np.asarray(ms, float)
        keep = np.isfinite(top) & (top != bottom)
        x0, x1, y0, y1 = x[keep] - 0.5, x[keep] + 0.5, bottom[keep], top[keep]
        out[name] = np.stack([np.stack([x0, y0], 1), np.stack([x1, y0], 1),
                              np.stack([x1, y1], 1), np.stack([x0, y1], 1)], 1)
        bottom = top
    return out


def budget(frames, per_stage_ms: dict[str, np.ndarray], path, title: str = "",
           period_ms: float = FRAME_PERIOD_MS) -> Path:
    """Per-frame budget use stacked by stage against the 500 ms line.

    per_stage_ms : {"processor/stage": array of ms per frame}

    Each stage is one collection of rectangles (:func:`stacked_bars`): a bar patch per frame and
    stage took matplotlib ~3 s for an event's 181 frames and 15 stages."""
    from matplotlib.collections import PolyCollection

    fig, ax = plt.subplots(figsize=(8, 4))
    colours = stage_colours(list(per_stage_ms))
    shown = [ax.axhline(period_ms, color="tab:red", lw=1.5, label=f"{period_ms:.0f} ms frame")]
    for name, verts in stacked_bars(frames, per_stage_ms).items():
        layer = PolyCollection(verts, facecolors=[colours[name]], linewidths=0, label=name)
        layer.sticky_edges.y.append(0.0)            # the bars stand on the axis, as ax.bar's do
        shown.append(ax.add_collection(layer))
    ax.autoscale_view()
    ax.set_xlabel("frame")
    ax.set_ylabel("emulated time (ms)")
    ax.set_title(title or "Flight processor budget per frame")
    ax.legend(handles=shown, fontsize=7, ncol=2, loc="upper right")
    return _save(fig, path)


def budget_bars(stage_ms: dict[str, float], path, title: str = "",
                period_ms: float = FRAME_PERIOD_MS) -> Path:
    """One processing sequence's emulated time per stage as horizontal bars, against the period."""
    names = list(stage_ms)
    vals = np.array([stage_ms[n] for n in names], float)
    fig, ax = plt.subplots(figsize=(7, 0.4 * len(names) + 1.5))
    ax.barh(names, vals, color="tab:blue")
    ax.axvline(period_ms, color="tab:red", lw=1.5, label=f"{period_ms:.0f} ms frame")
    ax.invert_yaxis()
    ax.set_xlabel("emulated time (ms)")
    ax.set_title(title)
    ax.legend(fontsize=8)
    return _save(fig, path)


#: the GIF's marks and their colours (drawn in its legend band)
GIF_KEYS = (("candidate", (255, 200, 0)), ("TP gate", (0, 160, 255)), ("truth", (255, 60, 60)),
            ("tracked", (0, 255, 0)))


def _gif_legend(d, y: int) -> None:
    x = 4
    for name, colour in GIF_KEYS:
        d.rectangle([x, y + 3, x + 7, y + 10], outline=colour)
        d.text((x + 11, y + 1), name, fill=colour)
        x += 11 + 6 * len(name) + 10


def event_gif(frames, path, marks=None, fps: int = 4, max_frames: int = 240, scale: int = 2) -> Path:
    """An animated GIF of the event: frames with candidates, gates and the tracked object marked, a
    time stamp on every frame and a legend band under it.

    frames : sequence of 2-D uint16 arrays (12-bit).
    marks : per frame a dict with optional keys ``candidates`` (K, 2) [row, col] array,
        ``tracked`` (row, col), ``gate`` (row, col, radius_px), ``truth`` (row, col), ``t`` (s),
        ``frame`` (index) and ``label`` (extra text after the time stamp).
    scale : int
        Display pixels per imager pixel (1 keeps the file small).
    """
    from PIL import Image, ImageDraw

    frames = list(frames)[:max_frames]
    if not frames:
        raise ValueError("event_gif(): no frames")
    marks = list(marks or [{}] * len(frames))
    stack = np.stack([np.asarray(f, float) for f in frames])
    lo, hi = np.percentile(stack, [1, 99.8])
    hi = hi if hi > lo else lo + 1
    band = 14
    pictures = []
    for img, m in zip(stack, marks):
        g = np.clip((img - lo) / (hi - lo) * 255, 0, 255).astype(np.uint8)
        w, h = img.shape[1] * scale, img.shape[0] * scale
        im = Image.new("RGB", (max(w, 300), h + band))
        im.paste(Image.fromarray(g).convert("RGB").resize((w, h), Image.NEAREST), (0, 0))
        d = ImageDraw.Draw(im)
        for r, c in np.asarray(m.get("candidates", np.zeros((0, 2))), float).reshape(-1, 2):
            d.rectangle([scale * c - 5, scale * r - 5, scale * c + 5, scale * r + 5], outline=GIF_KEYS[0][1])
        if m.get("gate") is not None:
            r, c, rad = m["gate"]
            d.ellipse([scale * (c - rad), scale * (r - rad), scale * (c + rad), scale * (r + rad)],
                      outline=GIF_KEYS[1][1])
        if m.get("truth") is not None and np.all(np.isfinite(m["truth"])):
            r, c = m["truth"]
            d.ellipse([scale * c - 3, scale * r - 3, scale * c + 3, scale * r + 3], outline=GIF_KEYS[2][1])
        if m.get("tracked") is not None and np.all(np.isfinite(m["tracked"])):
            r, c = m["tracked"]
            d.line([scale * c - 9, scale * r, scale * c + 9, scale * r], fill=GIF_KEYS[3][1], width=2)
            d.line([scale * c, scale * r - 9, scale * c, scale * r + 9], fill=GIF_KEYS[3][1], width=2)
        stamp = []
        if m.get("t") is not None:
            stamp.append(f"t = {float(m['t']):6.1f} s")
        if m.get("frame") is not None:
            stamp.append(f"frame {int(m['frame'])}")
        if m.get("label"):
            stamp.append(str(m["label"]))
        if stamp:
            text = "  ".join(stamp)
            d.rectangle([2, 2, 8 + 6 * len(text), 15], fill=(0, 0, 0))
            d.text((4, 3), text, fill=(255, 255, 255))
        _gif_legend(d, h)
        pictures.append(im)
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(path.stem + ".tmp.gif")
    pictures[0].save(tmp, save_all=True, append_images=pictures[1:], duration=int(1000 / fps),
                     loop=0, optimize=False)
    tmp.replace(path)
    return path
