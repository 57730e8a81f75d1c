"""Make (or re-check) the aurora labels of the two THEMIS Gillam sequences; see README.md here.

    .venv/bin/python data/labels/make_gill_labels.py [--plot DIR]

One point per frame on the brightest auroral structure, or blank when none is seen. A procedure
proposes the point; every frame was then looked at (the plots ``--plot`` writes) and the frames
where the procedure's point is not on an auroral structure are written blank (``NO_AURORA``).

**Gillam 2008-03-09** (``data/real/themis_gill_20080309_0435-0450_150frames.npz``, 8-bit rendering):

1. stars removed with a 5x5 median filter; the contrast is a Gaussian of sigma 3 px minus one of
   sigma 15 px (compact brightenings against their surroundings: the fold, hook and spiral of the
   onset, the brightest rays and bands of the breakup);
2. only pixels within 0.7 of the field radius of its centre count (the fisheye circle found by
   ``hil_harness.field.find_field`` on frame 0, row 131.6, col 126.6, radius 121.2 px, i.e.
   elevations above ~27 deg for an equidistant lens): the horizon ring, brightened by the long
   slant path through the emitting layer, by obstructions and by the rendering, is not a target;
3. the structure is the 8-connected region of contrast >= 50 % of the frame's maximum that holds
   the maximum; the label is its contrast-weighted centroid (0-based, pixel centres at +0.5).

Every frame shows auroral forms, so none is blank. The point jumps between structures while the
sky breaks up (04:42-04:46): that is the brightest structure moving, as a person clicking the
brightest one would have it.

**Gillam 2014-03-10** (``data/real/themis_gill_20140310_0600-0606_60frames.npz``, raw counts): the
aurora is a weak thin arc low along the northern rim; the Moon and its halo are the brightest thing
in every frame.

1. a 3x3 median filter; the contrast is a Gaussian of sigma 1.5 px minus one of sigma 5 px (a thin
   arc against the smooth moonlit sky);
2. only the northern sky where the arc lies counts: rows 15-41, cols 50-169, and at least 8 px
   inside the field circle (row 129.5, col 133.3, radius 122.5 px, found on frame 0), which keeps the
   rim's edge out;
3. region and centroid as for 2008.

Frames 0-37 are blank: no arc stands out there; the procedure's maximum falls on the rim's edge or
on the broad ring of the lens' vignetting. From frame 38 (06:03:48) the arc is seen and the point
lies on it.
"""
from __future__ import annotations

import argparse
import csv
import hashlib
import sys
from pathlib import Path

import numpy as np
from scipy import ndimage

ROOT = Path(__file__).resolve().parents[2]
HERE = Path(__file__).resolve().parent
DATE = "2026-11-29"

#: name -> (images, label CSV, median size, (sigma small, sigma large), no-aurora frames, title)
NIGHTS = {
    "2008": (ROOT / "data/real/themis_gill_20080309_0435-0450_150frames.npz",
             HERE / "themis_gill_20080309_aurora.csv", 5, (3.0, 15.0), frozenset(),
             "THEMIS Gillam 2008-03-09: brightest auroral structure"),
    "2014": (ROOT / "data/real/themis_gill_20140310_0600-0606_60frames.npz",
             HERE / "themis_gill_20140310_arc.csv", 3, (1.5, 5.0), frozenset(range(38)),
             "THEMIS Gillam 2014-03-10: the northern arc"),
}


def search_region(night: str, shape, field) -> np.ndarray:
    """bool [H, W]: where the label may lie (step 2 of the module docstring)."""
    rr, cc = np.indices(shape)
    rad = np.hypot(rr + 0.5 - field.row, cc + 0.5 - field.col)
    if night == "2008":
        return rad <= 0.7 * field.radius
    return (rr >= 15) & (rr < 42) & (cc >= 50) & (cc < 170) & (rad <= field.radius - 8.0)


def brightest_structure(frame, region, median: int, sigmas) -> tuple[float, float, int]:
    """(row, col, region px) of the brightest structure of one frame (steps 1-3)."""
    a = ndimage.median_filter(np.asarray(frame, np.float64), median)
    con = ndimage.gaussian_filter(a, sigmas[0]) - ndimage.gaussian_filter(a, sigmas[1])
    con = np.where(region, con, 0.0)
    r, c = np.unravel_index(int(np.argmax(con)), con.shape)
    reg, _ = ndimage.label(con >= 0.5 * con[r, c], structure=np.ones((3, 3)))
    w = con * (reg == reg[r, c])
    rr, cc = np.indices(con.shape)
    return (float((w * (rr + 0.5)).sum() / w.sum()), float((w * (cc + 0.5)).sum() / w.sum()),
            int((w > 0).sum()))


def night_labels(night: str) -> list[tuple[int, float | None, float | None]]:
    """[(frame, row or None, col or None)] for one night."""
    sys.path.insert(0, str(ROOT))
    from hil_harness.field import find_field
    images, _, median, sigmas, blank, _ = NIGHTS[night]
    img = np.load(images, allow_pickle=False)["img"]
    region = search_region(night, img.shape[1:], find_field(img[0].astype(np.float64)))
    out = []
    for i, frame in enumerate(img):
        r, c, _ = brightest_structure(frame, region, median, sigmas)
        out.append((i, None, None) if i in blank else (i, r, c))
    return out


def write_csv(night: str, labels, out: Path) -> None:
    images, _, _, _, _, title = NIGHTS[night]
    digest = hashlib.sha256(images.read_bytes()).hexdigest()
    with open(out, "w", newline="") as fh:
        fh.write(f"# {title}; blank row/col = none seen in the frame\n"
                 "# labeller: the procedure of data/labels/make_gill_labels.py, every frame "
                 "checked by eye (see README.md)\n"
                 "# tool: data/labels/make_gill_labels.py\n"
                 f"# date: {DATE}\n"
                 f"# image: {images.name} sha256={digest}\n")
        w = csv.writer(fh)
        w.writerow(["image", "frame", "row", "col"])
        for i, r, c in labels:
            w.writerow([images.name, i, "" if r is None else f"{r:.1f}",
                        "" if c is None else f"{c:.1f}"])


def plot(night: str, labels, out: Path) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    images, _, _, _, _, title = NIGHTS[night]
    z = np.load(images, allow_pickle=False)
    img, times = z["img"].astype(np.float64), z["time_utc"]
    cols = 10
    rows = -(-len(img) // cols)
    fig, axs = plt.subplots(rows, cols, figsize=(2.0 * cols, 2.1 * rows))
    for ax in axs.flat:
        ax.axis("off")
    for ax, (i, r, c) in zip(axs.flat, labels):
        lo, hi = np.percentile(img[i], [1, 99.8])
        ax.imshow(img[i], cmap="gray", vmin=lo, vmax=hi)
        if r is None:
            ax.set_title(f"{i} {str(times[i])[11:19]} none", fontsize=7)
        else:
            ax.plot(c - 0.5, r - 0.5, "+", color="#ff2020", ms=10, mew=1.2)
            ax.set_title(f"{i} {str(times[i])[11:19]} ({r:.0f},{c:.0f})", fontsize=7)
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    fig.savefig(out, dpi=40, pil_kwargs={"quality": 80})
    plt.close(fig)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--plot", default=None, metavar="DIR",
                    help="write one JPEG per night with the labels over every frame")
    args = ap.parse_args(argv)
    for night, (_, csv_path, *_rest) in NIGHTS.items():
        labels = night_labels(night)
        write_csv(night, labels, csv_path)
        print(f"wrote {csv_path}")
        if args.plot:
            jpg = Path(args.plot) / csv_path.with_suffix(".jpg").name
            plot(night, labels, jpg)
            print(f"wrote {jpg}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
