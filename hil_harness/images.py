"""Real image files -> frames, the flight's 12-bit counts, and bad-frame flags.

Public API (used by ``uvisi detect`` and ``uvisi track``):

* :func:`read_images` ``(paths) -> list[InputFrame]``: every frame of every file, in order;
* :func:`to_counts` ``(data, *, no_scale=False) -> (uint16 [H, W], mapping dict)``;
* :func:`frame_flags` ``(data) -> list[str]``: "blank", "constant", "nan", "saturated", "missing";
* :class:`InputFrame`, :class:`ImageError` (a ``ValueError`` naming the file).

Formats: FITS (astropy; every image HDU, a cube gives one frame per plane; ``DATE-OBS`` is the time
tag), TIFF (tifffile; a multi-page stack gives one frame per page; the ``DateTime`` tag), PNG/JPEG/
BMP/GIF (pillow) and NPY/NPZ (never with pickles; in an NPZ the key ``img`` if present, else every
numeric 2-D/3-D array; an NPZ ``time_utc`` array gives each plane its time tag).

Colour: a colour image (a Pillow colour mode, or an array ``[H, W, 3|4]`` in any format) becomes
one frame: by default its luma by ITU-R BT.601, ``Y = 0.299 R + 0.587 G + 0.114 B`` on the stored
(gamma-encoded) values, the rule JPEG's own Y'CbCr uses; or one channel (``channel="r"|"g"|"b"``,
the command option ``--channel``; auroral green, 557.7 nm, is ``g``). An 8-bit colour image keeps
the 8-bit rule of :func:`to_counts` (``rint(16 Y)``). A greyscale image is read as it is whatever
the channel (its R, G and B are the same). A camera raw file or a Bayer-mosaic TIFF/FITS is refused
with a one-line error saying how to demosaic it first.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

__all__ = ["InputFrame", "ImageError", "read_images", "sniff", "to_counts", "scale_note", "frame_flags",
           "unusable", "colour_plane", "CHANNELS", "LUMA_BT601", "robust_stats", "safe_unit", "noise_sigma", "pixel_noise", "MIN_LINE", "UNUSABLE", "WARNINGS",
           "SKY_COUNTS", "NOISE_COUNTS", "MIN_NOISE_COUNTS", "HEADROOM_PERCENTILE",
           "LOW_PERCENTILE", "LOW_MARGIN_SIGMA", "MISSING_FRACTION", "SATURATED_FRACTION",
           "BLANK_MARGIN_SIGMA", "FLAG_NAMES"]

#: robust map: the sky background goes to this level (12-bit counts)
SKY_COUNTS = 200.0
#: robust map: the pixel noise (noise_sigma) becomes this many counts, unless that clips more than
#: the brightest (100 - HEADROOM_PERCENTILE) % of the pixels
NOISE_COUNTS = 8.0
#: ... and never fewer than this many counts per noise sigma (the sky noise stays measurable)
MIN_NOISE_COUNTS = 2.0
#: percentile of the finite pixels that must still fit below 4095 (when the noise floor allows)
HEADROOM_PERCENTILE = 99.5
#: the LOW_PERCENTILE percentile of the pixels is kept LOW_MARGIN_SIGMA noise sigmas above 0
LOW_PERCENTILE = 0.1
LOW_MARGIN_SIGMA = 5.0
#: frame_flags thresholds (see frame_flags)
MISSING_FRACTION = 0.5
SATURATED_FRACTION = 0.05
BLANK_MARGIN_SIGMA = 1.5
#: a row or column counts for "missing" only with at least this many finite field pixels
MIN_LINE = 8
FLAG_NAMES = ("blank", "constant", "nan", "saturated", "missing")
#: the two kinds of flag: an unusable frame does not reach the TP; a warning is reported only
UNUSABLE = ("nan", "missing", "constant", "blank")
WARNINGS = ("saturated",)

_MAX12 = 4095
_FULL_SCALE = {2 ** k - 1 for k in (8, 10, 12, 14, 16, 32)} | {_MAX12 << 4}


class ImageError(ValueError):
    """An unreadable or unusable image; the message starts with the file (and plane)."""


@dataclass
class InputFrame:
    """One 2-D frame of an input file.

    ``name``: ``"<file>"``, ``"<file>[i]"`` (plane i of a stack), ``"<file>[key]"`` /
    ``"<file>[key][i]"`` (an NPZ array) or ``"<file>[hduN]..."`` (a FITS extension);
    ``data``: 2-D array as read (any dtype, not scaled); ``time_utc``: ISO-8601 time tag where the
    input has one (NPZ ``time_utc``, FITS ``DATE-OBS``, TIFF ``DateTime``), else None; ``bits``:
    the bit depth the file states for an 8-bit or 1-bit image (:func:`to_counts` maps those by
    rule 0), else None.
    """

    name: str
    data: np.ndarray
    time_utc: str | None = None
    bits: int | None = None         # the bit depth a PNG/JPEG states (8 for "L", 1 for "1")


# ------------------------------------------------------------------------------------------------
# reading
# ------------------------------------------------------------------------------------------------
def read_images(paths, channel: str = "l") -> list[InputFrame]:
    """Every frame of every file in ``paths`` (a path or a sequence of paths), in order.

    ``channel``: what a colour image becomes: ``"l"`` (BT.601 luma, the default), ``"r"``,
    ``"g"`` or ``"b"`` (see the module docstring).

    Raises :class:`ImageError` naming the file for a missing, unreadable or unsupported file, an
    array that is not 2-D/3-D numeric, or an NPY/NPZ that would need pickles.
    """
    if isinstance(paths, (str, Path)):
        paths = [paths]
    if channel not in CHANNELS:
        raise ImageError(f"--channel {channel!r}: expected one of {', '.join(CHANNELS)}")
    out: list[InputFrame] = []
    for path in paths:
        p = Path(path)
        if not p.exists():
            raise ImageError(f"{p}: no such file")
        if p.is_dir():
            raise ImageError(f"{p}: is a directory, not an image file")
        try:
            frames = _read_one(p, channel)
        except ImageError:
            raise
        except Exception as exc:       # noqa: BLE001 -- any library failure becomes one line
            if "pickle" in str(exc):
                raise ImageError(f"{p}: holds Python objects (pickled data), which are never "
                                 f"loaded: save the image as a plain numeric array") from None
            raise ImageError(f"{p}: cannot read: {type(exc).__name__}: "
                             f"{str(exc).splitlines()[0] if str(exc) else 'damaged'}") from None
        if not frames:
            raise ImageError(f"{p}: no 2-D image in the file")
        if not any(_has_finite(f.data) for f in frames):
            raise ImageError(f"{p}: no finite pixel in the file (every pixel NaN or infinite)")
        out += frames
    return out


#: leading bytes of each format read here (content first, the extension only when none matches)
MAGIC = ((b"SIMPLE  ", "fits"), (b"II*\x00", "tiff"), (b"MM\x00*", "tiff"), (b"\x89PNG", "png"),
         (b"\xff\xd8\xff", "png"), (b"\x93NUMPY", "npy"), (b"PK\x03\x04", "npz"),
         (b"PK\x05\x06", "npz"))                        # the last: an archive with no member
_KIND_OF_SUFFIX = {".fits": "fits", ".fit": "fits", ".fts": "fits", ".tif": "tiff", ".tiff": "tiff",
                   ".png": "png", ".jpg": "png", ".jpeg": "png", ".bmp": "png", ".gif": "png",
                   ".npy": "npy", ".npz": "npz"}


def sniff(p: Path) -> str | None:
    """The format of a file from its first bytes ("fits", "tiff", "png" for any Pillow image,
    "npy", "npz"), None when they match none of them."""
    with open(p, "rb") as fh:
        head = fh.read(8)
    if not head:
        raise ImageError(f"{p}: empty file")
    return next((kind for magic, kind in MAGIC if head.startswith(magic)), None)


def _has_finite(a: np.ndarray) -> bool:
    return not np.issubdtype(a.dtype, np.floating) or bool(np.isfinite(a).any())


#: the colour rule: luma weights (ITU-R BT.601) and the channels a command may ask for
LUMA_BT601 = (0.299, 0.587, 0.114)
CHANNELS = ("l", "r", "g", "b")
#: camera raw formats (a Bayer mosaic before demosaicing): refused with what to do
RAW_SUFFIXES = (".cr2", ".cr3", ".crw", ".nef", ".nrw", ".arw", ".srf", ".sr2", ".dng", ".raf",
                ".orf", ".rw2", ".pef", ".srw", ".x3f", ".3fr", ".erf", ".kdc", ".mef", ".mos",
                ".raw", ".rwl", ".iiq")
_DEMOSAIC = ("demosaic it first (e.g. rawpy.imread(path).postprocess(), or your camera "
             "software) and save a TIFF/PNG/FITS, then give that file, with --channel to choose a "
             "colour")


def _read_one(p: Path, channel: str = "l") -> list[InputFrame]:
    name = p.name.lower()
    suf = p.suffix.lower()
    if suf in RAW_SUFFIXES:
        raise ImageError(f"{p}: a camera raw file (Bayer mosaic): {_DEMOSAIC}")
    kind = sniff(p)
    if kind is None and _KIND_OF_SUFFIX.get(suf) in ("npy", "npz", "png", "tiff"):
        raise ImageError(f"{p}: not a {suf[1:].upper()} file (its first bytes match no image or "
                         f"array format this reads: FITS, TIFF, PNG/JPEG, NPY, NPZ)")
    if kind is not None and kind != _KIND_OF_SUFFIX.get(suf, kind):
        suf = {"fits": ".fits", "tiff": ".tiff", "png": ".png", "npy": ".npy", "npz": ".npz"}[kind]
    if suf in (".fits", ".fit", ".fts") or name.endswith((".fits.gz", ".fit.gz", ".fts.gz")):
        return _read_fits(p, channel)
    if suf in (".tif", ".tiff"):
        return _read_tiff(p, channel)
    if suf in (".png", ".jpg", ".jpeg", ".bmp", ".gif"):
        return _read_pillow(p, channel)
    if suf == ".npy":
        return _planes(np.load(p, allow_pickle=False), str(p), None, channel)
    if suf == ".npz":
        return _read_npz(p, channel)
    raise ImageError(f"{p}: unsupported format {suf or p.name!r} (FITS, TIFF, PNG/JPEG, NPY, NPZ)")


def _read_pillow(p: Path, channel: str) -> list[InputFrame]:
    from PIL import Image
    with Image.open(p) as im:
        if im.mode in ("1", "L", "I", "I;16", "I;16B", "I;16L", "F"):
            frames = _planes(np.asarray(im), str(p), None, channel)
            bits = {"1": 1, "L": 8}.get(im.mode)
            return [InputFrame(f.name, f.data, f.time_utc, bits) for f in frames]
        if im.mode == "LA":
            return [InputFrame(str(p), np.asarray(im.getchannel("L")), None, 8)]
        if im.mode == "P" and _palette_is_grey(im):
            return [InputFrame(str(p), np.asarray(im.convert("L")), None, 8)]
        rgb = np.asarray(im.convert("RGB"))                  # P, RGBA, CMYK, YCbCr, LAB, HSV
    return _planes(rgb, str(p), None, channel)


def _palette_is_grey(im) -> bool:
    pal = np.asarray(im.convert("RGB"))
    return bool(np.all(pal[..., 0] == pal[..., 1]) and np.all(pal[..., 1] == pal[..., 2]))


def _read_fits(p: Path, channel: str = "l") -> list[InputFrame]:
    import warnings

    from astropy.io import fits
    with warnings.catch_warnings(record=True) as said:
        warnings.simplefilter("always")
        try:
            return _fits_frames(fits, p, channel)
        except (TypeError, ValueError, OSError) as exc:
            short = [str(w.message) for w in said if "truncated" in str(w.message)]
            if short:                       # astropy's "File may have been truncated: ..."
                raise ImageError(f"{p}: a truncated FITS file ({short[0].split(': ', 1)[-1]})") \
                    from None
            raise ImageError(f"{p}: cannot read the FITS file: {exc}") from None


def _fits_frames(fits, p: Path, channel: str) -> list[InputFrame]:
    out = []
    with fits.open(p) as hdul:
        images = [(i, h) for i, h in enumerate(hdul)
                  if getattr(h, "is_image", False) and h.data is not None and h.data.ndim >= 2]
        for i, h in images:
            label = str(p) if len(images) == 1 else f"{p}[hdu{i}]"
            if any(k in h.header for k in ("BAYERPAT", "CFA-PAT", "BAYOFFX")):
                raise ImageError(f"{label}: a Bayer-mosaic frame (header BAYERPAT): {_DEMOSAIC}")
            t = h.header.get("DATE-OBS") or hdul[0].header.get("DATE-OBS")
            if t is not None and "T" not in str(t) and h.header.get("TIME-OBS"):
                t = f"{t}T{h.header['TIME-OBS']}"
            out += _planes(np.array(h.data), label, None if t is None else str(t), channel)
    return out


def _read_tiff(p: Path, channel: str = "l") -> list[InputFrame]:
    import tifffile
    with tifffile.TiffFile(p) as tf:
        if len(tf.pages) and (tf.pages[0].photometric == 32803 or "CFAPattern" in tf.pages[0].tags):
            raise ImageError(f"{p}: a Bayer-mosaic (CFA) TIFF: {_DEMOSAIC}")
        a = tf.asarray()
        t = None
        tag = tf.pages[0].tags.get("DateTime") if len(tf.pages) else None
        if tag is not None and isinstance(tag.value, str) and len(tag.value) >= 19:
            v = tag.value.strip()
            t = f"{v[0:4]}-{v[5:7]}-{v[8:10]}T{v[11:19]}"
    return _planes(np.asarray(a), str(p), t, channel)


def _read_npz(p: Path, channel: str = "l") -> list[InputFrame]:
    out = []
    with np.load(p, allow_pickle=False) as z:
        keys = ["img"] if "img" in z.files else [k for k in z.files if k != "time_utc"]
        times = np.atleast_1d(z["time_utc"]).astype(str) if "time_utc" in z.files else None
        for k in keys:
            a = np.asarray(z[k])
            if a.ndim not in (2, 3) or not (np.issubdtype(a.dtype, np.number)
                                            or a.dtype == np.bool_):
                if k == "img":
                    raise ImageError(f"{p}: key 'img' is not a 2-D/3-D numeric array "
                                     f"(shape {a.shape}, dtype {a.dtype})")
                continue
            label = str(p) if k == "img" or len(keys) == 1 else f"{p}[{k}]"
            out += _planes(a, label, times, channel)
        if not z.files:
            raise ImageError(f"{p}: an NPZ archive with no array in it")
    return out


def _planes(a: np.ndarray, label: str, times, channel: str = "l") -> list[InputFrame]:
    """Split an array into 2-D frames; ``times``: None, one tag, or one tag per plane; a colour
    image ``[H, W, 3|4]`` -> one frame by ``channel`` (:func:`colour_plane`)."""
    a = np.asarray(a)
    if a.dtype == object or not (np.issubdtype(a.dtype, np.number) or a.dtype == np.bool_):
        raise ImageError(f"{label}: pixels of type {a.dtype} are not numbers")
    if np.iscomplexobj(a):
        raise ImageError(f"{label}: complex pixels are not an image")
    if a.ndim == 3 and a.shape[-1] in (3, 4) and a.shape[0] > 4:     # colour -> one plane
        bits = 8 if a.dtype == np.uint8 else None
        return [InputFrame(label, colour_plane(a, channel), _time(times, 0, 1), bits)]
    if a.ndim == 2:
        return [InputFrame(label, a, _time(times, 0, 1))]
    if a.ndim == 3:
        return [InputFrame(f"{label}[{i}]", a[i], _time(times, i, a.shape[0]))
                for i in range(a.shape[0])]
    raise ImageError(f"{label}: expected a 2-D image or a [n, H, W] stack, got shape {a.shape}")


def colour_plane(rgb, channel: str = "l") -> np.ndarray:
    """One plane of a colour image: ``rgb`` [H, W, 3|4] (any numeric dtype; a 4th, alpha, plane
    is ignored) -> float64 [H, W] in the input's units: the BT.601 luma
    ``0.299 R + 0.587 G + 0.114 B`` for ``channel "l"``, else the R, G or B plane."""
    a = np.asarray(rgb)
    if a.ndim != 3 or a.shape[-1] not in (3, 4):
        raise ImageError(f"expected a colour image [H, W, 3|4], got shape {a.shape}")
    if channel == "l":
        return a[..., :3].astype(np.float64) @ np.array(LUMA_BT601)
    if channel not in CHANNELS:
        raise ImageError(f"--channel {channel!r}: expected one of {', '.join(CHANNELS)}")
    return a[..., "rgb".index(channel)].astype(np.float64)


def _time(times, i, n):
    if times is None:
        return None
    if isinstance(times, str):
        return times
    times = list(times)
    if len(times) == n:
        return str(times[i])
    return str(times[0]) if len(times) == 1 else None


# ------------------------------------------------------------------------------------------------
# 12-bit counts
# ------------------------------------------------------------------------------------------------
def _is_counts(a: np.ndarray) -> bool:
    """True when every pixel is an integer in 0..4095 (whatever the dtype)."""
    if a.size == 0:
        return False
    if a.dtype == np.bool_:
        return True
    if np.issubdtype(a.dtype, np.integer):
        return int(a.min()) >= 0 and int(a.max()) <= _MAX12
    if not np.all(np.isfinite(a)):
        return False
    return float(a.min()) >= 0 and float(a.max()) <= _MAX12 and bool(np.all(a == np.rint(a)))


def _common_shift(a: np.ndarray) -> int:
    """Trailing zero bits shared by every pixel of a non-negative integer array (0 if none)."""
    v = int(np.bitwise_or.reduce(a.astype(np.uint64).ravel()))
    if v == 0:
        return 0
    return (v & -v).bit_length() - 1


def _shifted_reading(a: np.ndarray) -> tuple[int, int]:
    """``(k, n_full)`` for a non-negative integer image that is a 12-bit reading stored ``<< k``:
    every pixel's low ``k`` bits are zero, except ``n_full`` pixels at the dtype's full scale (a
    saturated reading written as all ones, e.g. 0xFFFF from a 12-bit sensor stored << 4), and
    the dtype holds exactly 12 + k bits. ``(0, 0)`` when the image is not one."""
    k = _common_shift(a)
    if k > 0 and (int(a.max()) >> k) <= _MAX12:
        return k, 0
    full = np.iinfo(a.dtype).max
    at_full = a == full
    n_full = int(np.count_nonzero(at_full))
    if n_full == 0 or n_full == a.size:
        return 0, 0
    k = _common_shift(a[~at_full])
    if k > 0 and (int(full) >> k) == _MAX12:
        return k, n_full
    return 0, 0


def safe_unit(v: np.ndarray) -> float:
    """An exact power of two to multiply ``v`` (finite float64 values) by so that squares of it
    cannot overflow (1.0 unless some value exceeds 1e100): statistics are then taken on the scaled
    values and divided back, bit for bit the same for any ordinary image."""
    big = float(np.max(np.abs(v)))
    return 2.0 ** -math.ceil(math.log2(big)) if big > 1e100 else 1.0


def robust_stats(values: np.ndarray, kappa: float = 3.0, iters: int = 5) -> tuple[float, float]:
    """Background (median) and noise (1.4826 MAD) of the finite values, kappa-sigma clipped.

    ``values``: any-shape array (float64 used internally); returns ``(background, noise)`` in the
    input's units; ``noise`` falls back to the clipped standard deviation when the MAD is 0 (more
    than half the pixels equal) and is 0 only for a constant set. NaN, NaN when nothing is finite.
    """
    v = np.asarray(values, dtype=np.float64).ravel()
    v = v[np.isfinite(v)]
    if v.size == 0:
        return math.nan, math.nan
    if v.size > 1 << 20:                                   # a regular subsample is plenty
        v = v[:: v.size // (1 << 20) + 1]
    med = float(np.median(v))
    sig = 1.4826 * float(np.median(np.abs(v - med)))
    for _ in range(iters):
        if sig <= 0:
            break
        keep = v[np.abs(v - med) <= kappa * sig]
        new_med = float(np.median(keep))
        new_sig = 1.4826 * float(np.median(np.abs(keep - new_med)))
        if new_med == med and new_sig == sig:
            break
        med, sig = new_med, new_sig
    if sig <= 0 and v.size > 1:
        unit = safe_unit(v)
        w, m = v * unit, med * unit
        sig = float(np.std(w[np.abs(w - m) <= 5 * np.std(w)])) / unit
    elif sig <= 0:
        sig = 0.0
    return med, sig


def noise_sigma(data, mask=None) -> float:
    """Pixel noise of a 2-D image from neighbouring pixels: ``1.4826 MAD(d) / sqrt(6)`` over the
    horizontal and vertical second differences ``d = x[i-1] - 2 x[i] + x[i+1]`` of the finite
    pixels.

    Unlike the MAD of the pixels it ignores smooth structure (vignetting, a sky gradient, extended
    glow; a linear gradient cancels exactly): only pixel-to-pixel scatter counts. ``data``: 2-D
    array, any numeric dtype; ``mask``: optional bool [H, W], only differences whose three pixels
    are inside count (the instrument's field, :mod:`hil_harness.field`); returns the noise in the
    input's units (0 when most differences are 0, NaN when no three finite pixels lie in a line).
    Assumes uncorrelated noise (smoothed data read lower).
    """
    d = _second_differences(data, mask)
    if d.size == 0:
        return math.nan
    return 1.4826 * float(np.median(np.abs(d - np.median(d)))) / math.sqrt(6.0)


def pixel_noise(data, mask=None) -> float:
    """:func:`noise_sigma`, or where that is 0 (more than half the second differences are 0: a
    quantised low-noise frame, such as an 8-bit rendering of a dark sky) the 3-sigma-clipped RMS
    of the second differences over ``sqrt(6)``. ``data``: 2-D array; ``mask``: optional bool
    [H, W] as in :func:`noise_sigma`. Input units; 0 only when every kept difference is 0, NaN
    when there is none."""
    s = noise_sigma(data, mask)
    if not s == 0.0:
        return s
    d = _second_differences(data, mask)
    rms = float(np.sqrt(np.mean(d * d)))
    for _ in range(5):
        keep = d[np.abs(d) <= 3.0 * rms]
        new = float(np.sqrt(np.mean(keep * keep))) if keep.size else 0.0
        if new == rms:
            break
        rms = new
    return rms / math.sqrt(6.0)


def _second_differences(data, mask=None) -> np.ndarray:
    """float64 [n]: the finite horizontal and vertical second differences of a 2-D image (those
    with all three pixels inside ``mask`` when given), regularly subsampled to at most 2^21."""
    x = np.asarray(data, dtype=np.float64)
    if x.ndim != 2:
        raise ImageError(f"expected a 2-D image, got shape {x.shape}")
    dh = x[:, :-2] - 2 * x[:, 1:-1] + x[:, 2:]
    dv = x[:-2] - 2 * x[1:-1] + x[2:]
    if mask is not None:
        m = np.asarray(mask, bool)
        dh = dh[m[:, :-2] & m[:, 1:-1] & m[:, 2:]]
        dv = dv[m[:-2] & m[1:-1] & m[2:]]
    d = np.concatenate([dh.ravel(), dv.ravel()])
    d = d[np.isfinite(d)]
    if d.size > 1 << 21:
        d = d[:: d.size // (1 << 21) + 1]
    return d


def to_counts(data, *, no_scale: bool = False, bits: int | None = None,
              field=None) -> tuple[np.ndarray, dict]:
    """The flight's 12-bit counts from any 2-D image, and the mapping used (JSON-able dict).

    ``data``: 2-D array, any numeric dtype, as read. Returns ``(counts, mapping)``: ``counts`` is
    uint16 ``[H, W]`` in 0..4095. Rules, in order:

    0. an 8-bit or 1-bit image (``bits`` from :class:`InputFrame`, as a PNG/JPEG states it): 8-bit
       values are shifted up to the 12-bit scale, ``counts = value << 4`` (0..4080; the luminance
       or channel of an 8-bit colour image, 0..255 with fractions, is ``rint(16 value)``),
       ``{"method": "shift_up", "shift": 4, "from_bits": 8}``; 1-bit pixels become 0 or 4095,
       ``{"method": "binary", "from_bits": 1, "on": 4095}``. ``no_scale`` does not apply;

    1. already counts -- every pixel an integer in 0..4095 (integer, bool, or integer-valued float
       data): unchanged, ``{"method": "none"}``;
    2. integers wider than 12 bits, all >= 0, whose low ``k`` bits are zero in every pixel and whose
       maximum fits 12 bits after ``>> k`` (a 12-bit reading stored ``<< 4``, like the star-tracker
       TIFF): exact right shift, ``{"method": "shift", "shift": k}``. Pixels at the dtype's full
       scale (0xFFFF in uint16) are a saturated reading written as all ones: they are allowed when
       the dtype holds exactly 12 + k bits, map to 4095, and are counted in
       ``"full_scale_pixels"``;
    3. anything else: a robust linear map ``counts = offset + gain * value`` with
       ``{"method": "robust", "background", "noise", "offset", "gain", "sky_counts",
       "noise_counts", "clipped_low", "clipped_high"}`` (background and noise in input units,
       noise_counts = gain * noise, clip fractions of the pixels). ``background`` is the
       3-sigma-clipped median of the finite pixels (:func:`robust_stats`), ``noise`` the pixel
       noise from neighbouring pixels (:func:`noise_sigma`: vignetting or a sky gradient is not
       noise; where it is 0, the clipped MAD of the pixels).

       * Level: the background goes to ``SKY_COUNTS`` (200), or higher where the darkest 0.1 % of
         the pixels (``LOW_PERCENTILE``) would otherwise come closer than ``LOW_MARGIN_SIGMA`` (5)
         noise sigmas to 0 (a vignetted or graded sky keeps its dark corners).
       * Gain: ``NOISE_COUNTS / noise`` (8 counts per noise sigma). When the frame's maximum would
         still fit under 4095 with a larger gain, that gain is used (a low-contrast frame keeps all
         its range); when the brightest 0.5 % of the pixels (``HEADROOM_PERCENTILE``, 99.5) would
         clip, the gain is lowered until they fit (an extended bright scene; a few saturated stars
         may clip), but never below ``MIN_NOISE_COUNTS / noise`` (2 counts per sigma).

       Rounded and clipped to 0..4095; non-finite pixels become the sky level. A frame with no
       finite pixel gives zeros; a constant frame maps to the sky level (gain 1).

    Not the maximum stretch: a single bright star does not crush the sky noise.
    ``no_scale=True`` accepts rule 1 only and raises :class:`ImageError` otherwise.

    ``field``: optional bool [H, W], the instrument's field (:mod:`hil_harness.field`). Pixels
    outside it take part in no statistic: before any rule they are set to the field's median
    pixel (the lower median of its finite pixels: a value the frame holds, so the exact rules
    still apply), recorded as ``"outside_value"`` in the mapping, and the robust map's background,
    noise and percentiles are those of the field. So the flight IP sees a flat sky outside the
    field, at the field's background level (about ``SKY_COUNTS`` after rule 3).
    """
    a = np.asarray(data)
    if a.ndim != 2:
        raise ImageError(f"expected a 2-D image, got shape {a.shape}")
    if a.size == 0:
        raise ImageError("empty image")
    if not (np.issubdtype(a.dtype, np.number) or a.dtype == np.bool_) or np.iscomplexobj(a):
        raise ImageError(f"unsupported pixel type {a.dtype}")
    mask = None if field is None else np.asarray(field, bool)
    extra = {}
    if mask is not None:
        if mask.shape != a.shape:
            raise ImageError(f"field mask {mask.shape} does not match the image {a.shape}")
        if mask.all():
            mask = None
        else:
            a, fill = _fill_outside(a, mask)
            extra = {"outside_value": fill}
    counts, m = _rules(a, no_scale, bits, mask)
    m.update(extra)
    return counts, m


def _fill_outside(a: np.ndarray, mask: np.ndarray):
    """``a`` with the pixels outside ``mask`` set to the lower median of the finite pixels inside
    (0 when none is finite), and that value as a Python number."""
    v = a[mask]
    if np.issubdtype(a.dtype, np.floating):
        v = v[np.isfinite(v)]
    fill = np.sort(v)[(v.size - 1) // 2] if v.size else a.dtype.type(0)
    out = a.copy()
    out[~mask] = fill
    return out, fill.item()


def _rules(a, no_scale, bits, mask):
    """Rules 0-3 of :func:`to_counts` on a frame whose outside pixels are already filled."""
    if bits == 8 and _within(a, 255):
        return (np.rint(a.astype(np.float64) * 16)).astype(np.uint16), \
            {"method": "shift_up", "shift": 4, "from_bits": 8}
    if bits == 1:
        return (a.astype(bool).astype(np.uint16) * _MAX12), {"method": "binary", "from_bits": 1,
                                                             "on": _MAX12}
    if _is_counts(a):
        return a.astype(np.uint16), {"method": "none"}
    if no_scale:
        raise ImageError(f"pixels are not 12-bit counts ({_describe(a)}); drop --no-scale to map "
                         f"them to counts")
    if np.issubdtype(a.dtype, np.integer) and int(a.min()) >= 0:
        k, n_full = _shifted_reading(a)
        if k > 0:
            m = {"method": "shift", "shift": k}
            if n_full:
                m["full_scale_pixels"] = n_full
            return (a.astype(np.uint64) >> np.uint64(k)).astype(np.uint16), m
    return _robust_map(a, mask)


def _within(a: np.ndarray, top: int) -> bool:
    """True when every pixel is finite and in 0..top (an 8-bit image, or its luminance)."""
    if a.dtype == np.bool_:
        return True
    if np.issubdtype(a.dtype, np.floating) and not np.all(np.isfinite(a)):
        return False
    return float(a.min()) >= 0 and float(a.max()) <= top


def scale_note(name: str, scale: dict) -> str | None:
    """The one-line note a command prints when an image was not 12-bit counts to begin with and was
    mapped by a fixed rule (8-bit or 1-bit); None otherwise."""
    if scale.get("method") == "shift_up":
        return f"{name}: 8-bit image: mapped to 12-bit counts as value << 4 (0..4080)"
    if scale.get("method") == "binary":
        return f"{name}: 1-bit image: mapped to 12-bit counts 0 / 4095"
    return None


def _describe(a: np.ndarray) -> str:
    f = a[np.isfinite(a)] if np.issubdtype(a.dtype, np.floating) else a
    if f.size == 0:
        return f"{a.dtype}, no finite pixel"
    lo, hi = float(f.min()), float(f.max())
    kind = "non-integer " if np.issubdtype(a.dtype, np.floating) and np.any(f != np.rint(f)) \
        else ""
    nan = ", NaN pixels" if f.size < a.size else ""
    return f"{kind}{a.dtype} values {lo:.6g}..{hi:.6g}{nan}"


def _robust_map(a: np.ndarray, mask=None) -> tuple[np.ndarray, dict]:
    x = a.astype(np.float64)
    fin = np.isfinite(x)
    inside = fin if mask is None else fin & mask
    if not inside.any():
        return np.zeros(a.shape, np.uint16), {"method": "robust", "background": None,
                                              "noise": None, "offset": 0.0, "gain": 0.0,
                                              "sky_counts": SKY_COUNTS,
                                              "noise_counts": NOISE_COUNTS,
                                              "clipped_low": 0.0, "clipped_high": 0.0}
    # values near the float range (1e300) would overflow the statistics' squares: the map is
    # linear, so it is found on the frame scaled by an exact power of two and stated unscaled
    unit = safe_unit(x[inside])
    if unit != 1.0:
        x = x * unit
    bkg, noise = robust_stats(x[inside])
    dn = noise_sigma(x, mask)
    if dn > 0:
        noise = dn
    if noise > 0:
        v = x[inside]
        low = float(np.percentile(v, LOW_PERCENTILE)) - LOW_MARGIN_SIGMA * noise
        gain = NOISE_COUNTS / noise
        vmax = float(v.max())
        top = float(np.percentile(v, HEADROOM_PERCENTILE))
        g_max = _fit_gain(vmax, bkg, low)
        g_top = _fit_gain(top, bkg, low)
        if g_max > gain:
            gain = g_max                            # the whole frame fits with more counts/sigma
        elif g_top < gain:
            gain = max(g_top, MIN_NOISE_COUNTS / noise)
        offset = -gain * min(bkg - SKY_COUNTS / gain, low)
    else:
        gain, offset = 1.0, SKY_COUNTS - bkg
    y = np.where(fin, offset + gain * np.where(fin, x, 0.0), SKY_COUNTS)
    y = np.rint(y)
    lo, hi = float(np.mean(y < 0)), float(np.mean(y > _MAX12))
    counts = np.clip(y, 0, _MAX12).astype(np.uint16)
    return counts, {"method": "robust", "background": bkg / unit, "noise": noise / unit,
                    "offset": offset, "gain": gain * unit, "sky_counts": SKY_COUNTS,
                    "noise_counts": gain * noise, "clipped_low": lo, "clipped_high": hi}


def _fit_gain(v, bkg, low):
    """The largest gain that maps ``v`` to at most 4095 with the zero at ``min(bkg - SKY/gain,
    low)`` (see to_counts); inf when ``v`` is not above both."""
    g = math.inf
    if v > bkg:
        g = (_MAX12 - SKY_COUNTS) / (v - bkg)
    if v > low:
        g = min(g, _MAX12 / (v - low))
    return g


# ------------------------------------------------------------------------------------------------
# bad-frame flags
# ------------------------------------------------------------------------------------------------
def frame_flags(data, field=None) -> list[str]:
    """Bad-frame flags of one raw 2-D frame (as read, before :func:`to_counts`), measured inside
    the instrument's field only, in this order. Unusable (:data:`UNUSABLE`: the frame does not
    reach the TP):

    * ``"nan"``: every field pixel is NaN or infinite (nothing to measure);
    * ``"missing"``: at least ``MISSING_FRACTION`` (50 %) of the field's pixels are missing --
      non-finite, or on a row or column whose finite field pixels (``MIN_LINE`` (8) or more) all
      hold one value below the frame's maximum (a dropped line, a partial readout or a
      zero-filled block reads as constant lines; a line at the maximum is saturated, not missing);
    * ``"constant"``: every finite field pixel holds the same value;
    * ``"blank"``: nothing stands out of the pixel noise: the field is constant, or its brightest
      finite pixel is less than ``sqrt(2 ln n) + BLANK_MARGIN_SIGMA`` (1.5) noise sigmas above the
      background (n finite field pixels; sqrt(2 ln n) is the expected maximum of n Gaussian noise
      samples, so a pure noise frame -- a drop-out read as dark noise -- is blank and a frame with
      any real source is not). Background: the clipped median of the field pixels that are not
      missing (:func:`robust_stats`); noise: the *pixel* noise from second differences
      (:func:`pixel_noise`), not the spread of the pixel values, which in an all-sky frame is the
      scene (dark corners, sky glow, aurora).

    Warning (:data:`WARNINGS`: reported, the frame is still used):

    * ``"saturated"``: at least ``SATURATED_FRACTION`` (5 %) of the finite field pixels sit at the
      frame's maximum and that maximum is above the background (a flat-topped plateau: the
      detector's or the rendering's ceiling), or the field is constant at a full-scale value
      (2^k - 1 for k = 8, 10, 12, 14, 16, 32, or 4095 << 4).

    ``data``: 2-D array, any numeric dtype; ``field``: optional bool [H, W], True inside the field
    (:mod:`hil_harness.field`; default the whole frame). Returns a list of flag names (empty for a
    good frame).
    """
    a = np.asarray(data)
    if a.ndim != 2 or a.size == 0:
        raise ImageError(f"expected a non-empty 2-D image, got shape {a.shape}")
    inside = np.ones(a.shape, bool) if field is None else np.asarray(field, bool)
    if inside.shape != a.shape:
        raise ImageError(f"field mask {inside.shape} does not match the image {a.shape}")
    x = a.astype(np.float64)
    fin = np.isfinite(x) & inside
    if not fin.any():
        return ["nan", "missing"]
    flags = []
    v = x[fin]
    lo, hi = float(v.min()), float(v.max())
    missing = _missing_mask(x, fin, inside, hi if lo < hi else math.inf)
    if missing[inside].mean() >= MISSING_FRACTION:
        flags.append("missing")
    constant = lo == hi
    if constant:
        flags.append("constant")
    good = inside & ~missing
    if not good.any():
        good = fin
    bkg = robust_stats(x[good])[0]
    noise = pixel_noise(x, good)
    if constant or not noise > 0 or (hi - bkg) < noise * (math.sqrt(2 * math.log(max(v.size, 2)))
                                                          + BLANK_MARGIN_SIGMA):
        flags.append("blank")
    at_max = float(np.mean(v == hi))
    if (not constant and hi > bkg and at_max >= SATURATED_FRACTION) or \
            (constant and hi in _FULL_SCALE):
        flags.append("saturated")
    return flags


def unusable(flags) -> bool:
    """True when any of ``flags`` (names from :func:`frame_flags`) is an unusable kind
    (:data:`UNUSABLE`); warnings (:data:`WARNINGS`) alone leave the frame usable."""
    return any(f in UNUSABLE for f in flags)


def _missing_mask(x: np.ndarray, fin: np.ndarray, inside: np.ndarray, hi: float) -> np.ndarray:
    """bool [H, W]: field pixels that are non-finite or on a constant row or column of at least
    MIN_LINE finite field pixels below ``hi`` (the frame's maximum; inf for a constant frame,
    whose lines are all missing) (see frame_flags)."""
    missing = inside & ~fin
    if x.shape[0] >= 2 and x.shape[1] >= 2:
        big = np.where(fin, x, -np.inf)
        small = np.where(fin, x, np.inf)
        for ax in (1, 0):
            top, bottom, n = big.max(ax), small.min(ax), fin.sum(ax)
            const = ((top == bottom) & (n >= MIN_LINE) & (top < hi)) | (~fin.any(ax) & inside.any(ax))
            missing |= inside & (const[:, None] if ax == 1 else const[None, :])
    return missing
