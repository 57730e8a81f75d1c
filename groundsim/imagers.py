"""The four UVISI imagers (MSX paper: 13.1 x 10.5 deg wide and 1.6 x 1.3 deg narrow fields, visible and
ultraviolet, 256 x 244 pixels, 12-bit output at 2 Hz).

Pixel model (shared with ``flightsw``): pixel ``(row, col)`` with centres at +0.5 maps to the imager-frame
direction ``(1, x, y)`` normalised, ``x = (col - 128) * scale_col``, ``y = (row - 122) * scale_row``
(gnomonic; ``scale = 2 tan(fov/2) / npix`` tangent-plane radians per pixel). Imager frame -> body by
``align`` (quaternion imager -> body; the onboard value ``align_onboard`` may differ from the truth).

Radiometry (electrons; constants below are this simulator's, chosen so that, as on UVISI, a WFOV visible
frame shows stars to about magnitude 8 and the brightest stars saturate and bloom):

=========  ===========  =====  ====  =====  ====  ====  =====  ======  =====  ====  =====
imager     zp e-/s      t_int  psf   read   dark  sky   gain   bias    full   mag   band
           (mag 0)      s      px    e-     e-/s  e-/s  e-/DN  DN      well   lim
=========  ===========  =====  ====  =====  ====  ====  =====  ======  =====  ====  =====
wfov_vis   8.0e5        0.25   0.70  6.0    20    120   4.0    40      16800  8.0   vis
nfov_vis   2.0e7        0.25   0.80  6.0    20    30    4.0    40      16800  11.0  vis
wfov_uv    1.0e5        0.25   0.75  4.0    5     40    4.0    40      16800  6.0   uv
nfov_uv    2.5e6        0.25   0.85  4.0    5     10    4.0    40      16800  9.0   uv
=========  ===========  =====  ====  =====  ====  ====  =====  ======  =====  ====  =====

A pixel's mean signal is ``(dark + sky) * t_int`` plus sources (electrons); the detected signal is Poisson
(Gaussian with the same mean and variance above 12 e-), charge above the full well blooms along its
column, read noise (Gaussian) is added, then ``DN = round(bias + e / gain)`` clipped to ``[0, 4095]``.
With gain 4 the ADC saturates at (4095 - 40) * 4 = 16220 e-, just below the full well.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from functools import cached_property

import numpy as np

from .quat import q_normalize, q_to_dcm

N_ROWS = 244
N_COLS = 256
ROW0 = 122.0
COL0 = 128.0
ADC_MAX = 4095
IMAGER_IDS = ("wfov_vis", "nfov_vis", "wfov_uv", "nfov_uv")


@dataclass(frozen=True)
class Imager:
    id: str
    band: str                   # "vis" or "uv": the passband of the counts model (groundsim.sky)
    fov_col_deg: float          # full field across columns
    fov_row_deg: float          # full field across rows
    zp_e_per_s: float           # electrons per second from a point source of band magnitude 0
    t_int: float = 0.25         # integration time, s (centred on the frame time tag)
    psf_sigma_px: float = 0.7   # Gaussian PSF sigma, pixels
    read_noise_e: float = 6.0
    dark_e_per_s: float = 20.0
    sky_e_per_s: float = 100.0  # uniform background per pixel
    gain_e_per_dn: float = 4.0
    bias_dn: float = 40.0
    full_well_e: float = 16800.0
    adc_max: int = ADC_MAX
    mag_limit: float = 8.0      # faintest band magnitude rendered
    align: tuple = (1.0, 0.0, 0.0, 0.0)          # truth imager -> body
    align_onboard: tuple = (1.0, 0.0, 0.0, 0.0)  # what the flight code believes
    n_rows: int = N_ROWS
    n_cols: int = N_COLS

    def __post_init__(self):
        for name in ("fov_col_deg", "fov_row_deg", "zp_e_per_s", "t_int", "psf_sigma_px", "gain_e_per_dn",
                     "full_well_e"):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0):
                raise ValueError(f"imager {self.id!r}: {name} must be a positive number, got {v!r}")
        for name in ("read_noise_e", "dark_e_per_s", "sky_e_per_s", "bias_dn"):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and math.isfinite(v) and v >= 0):
                raise ValueError(f"imager {self.id!r}: {name} must be a number >= 0, got {v!r}")
        if self.band not in ("vis", "uv"):
            raise ValueError(f"imager {self.id!r}: band must be 'vis' or 'uv', got {self.band!r}")
        object.__setattr__(self, "align", tuple(float(x) for x in q_normalize(self.align)))
        object.__setattr__(self, "align_onboard", tuple(float(x) for x in q_normalize(self.align_onboard)))

    # -- geometry ---------------------------------------------------------------------------------
    # derived geometry, computed once per (frozen) imager: the renderer reads it every frame
    @cached_property
    def scale_col(self) -> float:
        return 2.0 * math.tan(math.radians(self.fov_col_deg) / 2.0) / self.n_cols

    @cached_property
    def scale_row(self) -> float:
        return 2.0 * math.tan(math.radians(self.fov_row_deg) / 2.0) / self.n_rows

    @cached_property
    def half_diagonal(self) -> float:
        """Angle (rad) from the boresight to a frame corner."""
        return math.atan(math.hypot(COL0 * self.scale_col, ROW0 * self.scale_row))

    @cached_property
    def align_dcm(self) -> np.ndarray:
        """(3, 3) float64 imager -> body matrix of the truth alignment (read-only)."""
        m = q_to_dcm(self.align)
        m.flags.writeable = False
        return m

    def pixel_to_vec(self, row, col) -> np.ndarray:
        """Imager-frame unit vector(s) of pixel coordinates (arrays broadcast); shape (..., 3)."""
        x = (np.asarray(col, float) - COL0) * self.scale_col
        y = (np.asarray(row, float) - ROW0) * self.scale_row
        v = np.stack(np.broadcast_arrays(np.ones_like(x), x, y), axis=-1)
        return v / np.linalg.norm(v, axis=-1, keepdims=True)

    def vec_to_pixel(self, v):
        """(row, col) of imager-frame vector(s) v (..., 3); NaN behind the imager."""
        v = np.asarray(v, float)
        with np.errstate(divide="ignore", invalid="ignore"):
            fwd = v[..., 0] > 0
            col = np.where(fwd, v[..., 1] / v[..., 0] / self.scale_col + COL0, np.nan)
            row = np.where(fwd, v[..., 2] / v[..., 0] / self.scale_row + ROW0, np.nan)
        return row, col

    def adc_saturation_e(self) -> float:
        return (self.adc_max - self.bias_dn) * self.gain_e_per_dn

    def with_(self, **kw) -> "Imager":
        return replace(self, **kw)


IMAGERS = {
    "wfov_vis": Imager("wfov_vis", "vis", 13.1, 10.5, zp_e_per_s=8.0e5, psf_sigma_px=0.70, read_noise_e=6.0,
                       dark_e_per_s=20.0, sky_e_per_s=120.0, mag_limit=8.0),
    "nfov_vis": Imager("nfov_vis", "vis", 1.6, 1.3, zp_e_per_s=2.0e7, psf_sigma_px=0.80, read_noise_e=6.0,
                       dark_e_per_s=20.0, sky_e_per_s=30.0, mag_limit=11.0),
    "wfov_uv": Imager("wfov_uv", "uv", 13.1, 10.5, zp_e_per_s=1.0e5, psf_sigma_px=0.75, read_noise_e=4.0,
                      dark_e_per_s=5.0, sky_e_per_s=40.0, mag_limit=6.0),
    "nfov_uv": Imager("nfov_uv", "uv", 1.6, 1.3, zp_e_per_s=2.5e6, psf_sigma_px=0.85, read_noise_e=4.0,
                      dark_e_per_s=5.0, sky_e_per_s=10.0, mag_limit=9.0),
}


def get_imager(imager_id: str, **overrides) -> Imager:
    """One of ``IMAGER_IDS``, optionally with fields overridden (e.g. ``align=...``)."""
    if imager_id not in IMAGERS:
        raise ValueError(f"unknown imager {imager_id!r}; expected one of {list(IMAGER_IDS)}")
    im = IMAGERS[imager_id]
    return replace(im, **overrides) if overrides else im
