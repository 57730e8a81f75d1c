"""Make (or re-check) the surge labels of the IMAGE FUV-WIC sequence; see README.md in this folder.

    .venv/bin/python data/labels/make_wic_labels.py [--plot data/labels/wic_20000828_surge.png]

Procedure, per frame of ``data/real/wic_20000828_0928-0957_15frames.npz``:

1. the frame's instrument counts (NaN -> 0) are smoothed with a Gaussian of sigma 3 px (``s``) and
   of sigma 15 px (``b``, the large-scale background: dayglow, oval glow); the contrast is ``s - b``;
2. only night-side auroral-zone pixels count: ``|mlat| >= 55 deg`` and magnetic local time in
   ``[18, 24) U [0, 6)`` h (the per-pixel ``mlat``/``mlt`` of the file; off-disk pixels are NaN and
   excluded) -- this removes the sunlit dayglow limb, the brightest thing in every frame;
3. the surge region is the 8-connected region of contrast >= 50 % of the frame's maximum
   contrast that contains the maximum;
4. the label is the contrast-weighted centroid of that region, 0-based ``(row, col)`` with pixel
   centres at +0.5 (the flight code's convention).

Frames listed in ``NO_SURGE`` are written with blank row/col (no object): they were judged by eye
(the plot) to show no surge -- frame 0 precedes the substorm onset and its maximum falls on the
dusk-side oval next to the dayglow terminator.
"""
from __future__ import annotations

import argparse
import csv
from pathlib import Path

import numpy as np
from scipy import ndimage

ROOT = Path(__file__).resolve().parents[2]
IMAGES = ROOT / "data" / "real" / "wic_20000828_0928-0957_15frames.npz"
OUT = Path(__file__).resolve().parent / "wic_20000828_surge.csv"
NO_SURGE = {0}


def surge_labels(path=IMAGES):
    """[(frame, row, col, region_px)] by the procedure in the module docstring."""
    z = np.load(path, allow_pickle=False)
    img = z["img"].astype(np.float64)
    mlat = z["mlat"].astype(np.float64)
    mlt = z["mlt"].astype(np.float64)
    out = []
    rr, cc = np.indices(img.shape[1:])
    for i in range(img.shape[0]):
        a = np.nan_to_num(img[i])
        con = ndimage.gaussian_filter(a, 3.0) - ndimage.gaussian_filter(a, 15.0)
        with np.errstate(invalid="ignore"):
            night = (np.abs(mlat[i]) >= 55.0) & ((mlt[i] >= 18.0) | (mlt[i] < 6.0))
        con = np.where(night, con, 0.0)
        r, c = np.unravel_index(int(np.argmax(con)), con.shape)
        reg, _ = ndimage.label(con >= 0.5 * con[r, c], structure=np.ones((3, 3)))
        m = reg == reg[r, c]
        w = con * m
        out.append((i, float((w * (rr + 0.5)).sum() / w.sum()),
                    float((w * (cc + 0.5)).sum() / w.sum()), int(m.sum())))
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", default=str(OUT))
    ap.add_argument("--plot", default=None, help="PNG with the labels over every frame")
    args = ap.parse_args(argv)
    labels = surge_labels()
    with open(args.out, "w", newline="") as fh:
        fh.write("# IMAGE FUV-WIC 2000-08-28 surge labels: made by data/labels/make_wic_labels.py "
                 "(see README.md); blank row/col = no surge in the frame\n")
        w = csv.writer(fh)
        w.writerow(["image", "frame", "row", "col"])
        for i, r, c, _ in labels:
            if i in NO_SURGE:
                w.writerow([IMAGES.name, i, "", ""])
            else:
                w.writerow([IMAGES.name, i, f"{r:.1f}", f"{c:.1f}"])
    print(f"wrote {args.out}")
    if args.plot:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        z = np.load(IMAGES, allow_pickle=False)
        fig, axs = plt.subplots(3, 5, figsize=(15, 8.4))
        for ax, (i, r, c, npx) in zip(axs.flat, labels):
            a = np.nan_to_num(z["img"][i])
            ax.imshow(a, cmap="gray", vmin=0, vmax=np.percentile(a, 99.5))
            if i in NO_SURGE:
                ax.plot(c, r, "x", color="#ff8800", ms=10)
                ax.set_title(f"{i} {str(z['time_utc'][i])[11:19]}: no surge", fontsize=9)
            else:
                ax.plot(c, r, "+", color="#ff2020", ms=14, mew=1.5)
                ax.add_patch(plt.Circle((c, r), 25.0, fill=False, color="#33ccff", lw=0.8))
                ax.set_title(f"{i} {str(z['time_utc'][i])[11:19]}: ({r:.0f}, {c:.0f})",
                             fontsize=9)
            ax.set_xticks([])
            ax.set_yticks([])
        fig.suptitle("IMAGE FUV-WIC 2000-08-28: surge labels (+) and the 25 px object radius",
                     fontsize=10)
        fig.tight_layout()
        fig.savefig(args.plot, dpi=55)
        print(f"wrote {args.plot}")


if __name__ == "__main__":
    main()
