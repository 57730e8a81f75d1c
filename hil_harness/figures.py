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


def stages(images: list[tuple[str, np.ndarray]], path, title: str = "") -> Path:
    """The processing stages of one frame side by side, like the paper's Figure 3.

    images : list of (stage name, 2-D array) in processing order.
    """
    n = len(images)
    if n == 0:
        raise ValueError("stages(): no stage images to draw")
    cols = min(n, 4)
    rows = (n + cols - 1) // cols
    fig, axes = plt.subplots(rows, cols, figsize=(3.2 * cols, 3.2 * rows), squeeze=False)
    for ax in axes.flat:
        ax.axis("off")
    for ax, (name, img) in zip(axes.flat, images):
        img = np.asarray(img, dtype=np.float64)
        lo, hi = np.percentile(img, [1, 99.7]) if img.size else (0, 1)
        ax.imshow(img, cmap="gray", vmin=lo, vmax=hi if hi > lo else lo + 1,
                  interpolation="nearest")
        ax.set_title(name, fontsize=9)
    if title:
        fig.suptitle(title, fontsize=10)
    return _save(fig, path)


def centroid_track(t, rows, cols, path, truth_rows=None, truth_cols=None,
                   shape=(244, 256), title: str = "Tracked object centroid",
                   zoom: bool = False) -> Path:
    """The tracked object's centroid over the frames in imager pixels, like the paper's Figure 6.
    ``zoom``: limits to the points (plus a 3-pixel margin) instead of the whole imager."""
    fig, ax = plt.subplots(figsize=(6, 5))
    sc = ax.scatter(cols, rows, c=t, cmap="viridis", s=14, marker="+", label="top candidate / track")
    if truth_rows is not None:
        ax.plot(truth_cols, truth_rows, "-", color="tab:red", lw=1, label="truth")
    ax.set_xlim(0, shape[1])
    ax.set_ylim(shape[0], 0)
    if zoom:
        pts_c = np.concatenate([np.ravel(cols), np.ravel(truth_cols if truth_cols is not None else [])])
        pts_r = np.concatenate([np.ravel(rows), np.ravel(truth_rows if truth_rows is not None else [])])
        ok = np.isfinite(pts_c) & np.isfinite(pts_r)
        if ok.any():
            c0, c1 = pts_c[ok].min() - 3, pts_c[ok].max() + 3
            r0, r1 = pts_r[ok].min() - 3, pts_r[ok].max() + 3
            h = max(c1 - c0, r1 - r0) / 2
            cc, rc = (c0 + c1) / 2, (r0 + r1) / 2
            ax.set_xlim(cc - h, cc + h)
            ax.set_ylim(rc + h, rc - h)
    ax.set_xlabel("column (px)")
    ax.set_ylabel("row (px)")
    ax.set_aspect("equal")
    fig.colorbar(sc, ax=ax, label="time (s)")
    ax.legend(loc="upper right", fontsize=8)
    ax.set_title(title)
    return _save(fig, path)


def track_error(t, err_urad, path, pixel_urad: float | None = None) -> Path:
    """Track error against truth (urad) over time, with its 99.7th percentile."""
    t = np.asarray(t, float)
    e = np.asarray(err_urad, float)
    fig, ax = plt.subplots(figsize=(7, 3.5))
    ax.plot(t, e, ".-", lw=0.8, ms=3)
    ok = np.isfinite(e)
    if ok.any():
        p997 = np.percentile(e[ok], 99.7)
        ax.axhline(p997, color="tab:red", ls="--", lw=1, label=f"99.7th pct {p997:.0f} urad")
    if pixel_urad:
        ax.axhline(pixel_urad, color="gray", ls=":", lw=1, label=f"1 processed px = {pixel_urad:.0f} urad")
    ax.set_xlabel("time (s)")
    ax.set_ylabel("track error (urad)")
    ax.set_yscale("symlog", linthresh=10)
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3)
    return _save(fig, path)


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


def budget(frames, per_stage_ms: dict[str, np.ndarray], path, title: str = "",
           period_ms: float = FRAME_PERIOD_MS) -> Path:
    """Per-frame budget use stacked by stage against the 500 ms line.

    per_stage_ms : {"processor/stage": array of ms per frame}
    """
    frames = np.asarray(frames)
    fig, ax = plt.subplots(figsize=(8, 4))
    bottom = np.zeros(len(frames))
    for name, ms in per_stage_ms.items():
        ms = np.asarray(ms, float)
        ax.bar(frames, ms, bottom=bottom, width=1.0, label=name, linewidth=0)
        bottom += ms
    ax.axhline(period_ms, color="tab:red", lw=1.5, label=f"{period_ms:.0f} ms frame")
    ax.set_xlabel("frame")
    ax.set_ylabel("emulated time (ms)")
    ax.set_title(title or "Flight processor budget per frame")
    ax.legend(fontsize=7, ncol=2, loc="upper right")
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


def event_gif(frames, path, marks=None, fps: int = 4, max_frames: int = 240, scale: int = 2) -> Path:
    """An animated GIF of the event: frames with candidates, gates and the tracked object marked.

    frames : sequence of 2-D uint16 arrays (12-bit).
    marks : per frame a dict with optional keys ``candidates`` (K, 2) [row, col] array,
        ``tracked`` (row, col), ``gate`` (row, col, radius_px), ``truth`` (row, col).
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
    pictures = []
    for img, m in zip(stack, marks):
        g = np.clip((img - lo) / (hi - lo) * 255, 0, 255).astype(np.uint8)
        im = Image.fromarray(g).convert("RGB").resize((img.shape[1] * scale, img.shape[0] * scale),
                                                      Image.NEAREST)
        d = ImageDraw.Draw(im)
        for r, c in np.asarray(m.get("candidates", np.zeros((0, 2))), float).reshape(-1, 2):
            d.rectangle([scale * c - 5, scale * r - 5, scale * c + 5, scale * r + 5], outline=(255, 200, 0))
        if m.get("gate") is not None:
            r, c, rad = m["gate"]
            d.ellipse([scale * (c - rad), scale * (r - rad), scale * (c + rad), scale * (r + rad)], outline=(0, 160, 255))
        if m.get("truth") is not None and np.all(np.isfinite(m["truth"])):
            r, c = m["truth"]
            d.ellipse([scale * c - 3, scale * r - 3, scale * c + 3, scale * r + 3], outline=(255, 60, 60))
        if m.get("tracked") is not None and np.all(np.isfinite(m["tracked"])):
            r, c = m["tracked"]
            d.line([scale * c - 9, scale * r, scale * c + 9, scale * r], fill=(0, 255, 0), width=2)
            d.line([scale * c, scale * r - 9, scale * c, scale * r + 9], fill=(0, 255, 0), width=2)
        if m.get("label"):
            d.text((4, 4), str(m["label"]), fill=(255, 255, 255))
        pictures.append(im)
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(path.stem + ".tmp.gif")
    pictures[0].save(tmp, save_all=True, append_images=pictures[1:], duration=int(1000 / fps),
                     loop=0, optimize=False)
    tmp.replace(path)
    return path
