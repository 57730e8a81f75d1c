"""Real imagery through the same iterator as :meth:`groundsim.Scenario.frames`: ``(t, frame, truth)``.

``RealSequence.load(path=None)`` reads ``data/real/wic_20000828_0928-0957_15frames.npz`` (IMAGE FUV-WIC,
256 x 256 float32 counts up to ~16000; see data/real/SOURCES.md) by default, or a ``.tif/.tiff`` star
frame. Frames become 12-bit ``uint16[244, 256]``:

* rows: the central 244 of 256 (6 dropped at the top and bottom); columns kept (256);
* counts: ``DN = round(img * 4095 / scale)`` clipped to [0, 4095], NaN -> 0, where ``scale`` is the
  maximum over the whole sequence (one fixed gain for the sequence, as an instrument has);
  for TIFFs from the tetra3 data (12-bit shifted left by 4) ``DN = value >> 4`` (``shift4=True``).

There is no truth: ``truth`` carries ``real=True``, the imager id ``"real"``, the source time stamp,
an empty star list and a NaN target. ``t`` advances at the 2 Hz frame cadence (the real cadence is in
``truth["time_utc"]``).
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .render import STAR_DTYPE

DATA_REAL = Path(__file__).resolve().parents[1] / "data" / "real"
DEFAULT_WIC = DATA_REAL / "wic_20000828_0928-0957_15frames.npz"


@dataclass
class RealSequence:
    frames_dn: np.ndarray          # uint16 [n, 244, 256]
    times_utc: list
    source: Path
    imager: str = "real"
    compaction: int = 2

    @classmethod
    def load(cls, path=None, compaction: int = 2, shift4=None) -> "RealSequence":
        p = Path(path) if path is not None else DEFAULT_WIC
        if not p.exists():
            raise FileNotFoundError(f"{p}: no such real-data file")
        if p.suffix == ".npz":
            with np.load(p, allow_pickle=False) as z:
                if "img" not in z.files:
                    raise ValueError(f"{p}: key 'img' missing (keys: {z.files})")
                img = np.asarray(z["img"], np.float64)
                times = [str(x) for x in z["time_utc"]] if "time_utc" in z.files else [""] * len(img)
            if img.ndim == 2:
                img = img[None]
            img = np.nan_to_num(img, nan=0.0)
            scale = float(img.max()) if img.max() > 0 else 1.0
            dn = np.clip(np.rint(img * (4095.0 / scale)), 0, 4095)
        elif p.suffix.lower() in (".tif", ".tiff"):
            import tifffile
            img = np.asarray(tifffile.imread(p))
            if img.ndim == 2:
                img = img[None]
            if shift4 is None:
                shift4 = bool(img.max() > 4095)
            dn = (img.astype(np.int64) >> 4) if shift4 else np.clip(img, 0, 4095)
            times = [""] * len(dn)
        else:
            raise ValueError(f"{p}: unsupported real-data format (expected .npz or .tif)")
        return cls(_to_frame_shape(dn).astype(np.uint16), times, p, compaction=compaction)

    def __len__(self):
        return len(self.frames_dn)

    def frames(self):
        for k, fr in enumerate(self.frames_dn):
            truth = dict(t=0.5 * k, frame_index=k, imager=self.imager, real=True, time_utc=self.times_utc[k],
                         source=str(self.source), stars=np.empty(0, STAR_DTYPE),
                         target=dict(type=None, row=np.nan, col=np.nan, in_field=False, los_eci=np.full(3, np.nan)))
            yield 0.5 * k, fr.copy(), truth


def _to_frame_shape(a: np.ndarray) -> np.ndarray:
    """[n, H, W] -> [n, 244, 256]: centre crop, or zero-pad, then nearest resample if still wrong."""
    n, h, w = a.shape
    out = np.zeros((n, 244, 256), a.dtype)
    if h >= 244 and w >= 256 and h <= 2 * 244 and w <= 2 * 256 and (h, w) == (256, 256):
        r0 = (h - 244) // 2
        c0 = (w - 256) // 2
        return a[:, r0:r0 + 244, c0:c0 + 256]
    # general case: nearest-neighbour resample of the whole frame
    ri = np.minimum((np.arange(244) + 0.5) * h / 244, h - 1).astype(int)
    ci = np.minimum((np.arange(256) + 0.5) * w / 256, w - 1).astype(int)
    out[:] = a[:, ri][:, :, ci]
    return out
