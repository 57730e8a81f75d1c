"""The viewer page: the template (``page.html``, ``page.css``, ``page.js``, package data) filled with
a recording's data (:func:`.data.extract`) and, for a self-contained page, every frame packed by
:mod:`.codec` (base64 in a JSON script tag; the page inflates each frame when it is shown)."""
from __future__ import annotations

import base64
import json
import math
import re
from importlib.resources import files

import numpy as np

from hil_harness.webpage import page_document

from .codec import pack
from .data import extract
from .stages import recorded_stages, stage_entries, stage_note, stages_by_frame

#: bytes above which ``uvisi view`` suggests ``--serve`` (a browser holds the whole page in memory)
LARGE_PAGE_BYTES = 100_000_000


def _clean(o):
    """``o`` with every non-finite float replaced by None (strict JSON)."""
    if isinstance(o, float):
        return o if math.isfinite(o) else None
    if isinstance(o, dict):
        return {k: _clean(v) for k, v in o.items()}
    if isinstance(o, (list, tuple)):
        return [_clean(v) for v in o]
    if isinstance(o, np.generic):
        return _clean(o.item())
    return o


def script_json(o) -> str:
    """Strict JSON safe inside a ``<script>`` element: ``<``, ``>`` and ``&`` (which JSON holds only
    inside strings) written as ``\\u003c``, ``\\u003e``, ``\\u0026``, so no text of a recording
    can end the element or open a comment in it."""
    text = json.dumps(_clean(o), allow_nan=False, separators=(",", ":"))
    return text.replace("<", "\\u003c").replace(">", "\\u003e").replace("&", "\\u0026")


#: the template's placeholders, filled in one pass (a value is never searched for another)
_PLACEHOLDER = re.compile(r"__(DATA|IMAGES)__")


def _resource(name: str) -> str:
    return files("hil_harness.view").joinpath(name).read_text(encoding="utf-8")


def page_js() -> str:
    """The page's script (``page.js``), as the page holds it."""
    return _resource("page.js")


def page_html(data: dict, images: dict) -> str:
    """The page of ``data`` (:func:`.data.extract`) with ``images``: ``{"mode": "inline", "frames":
    [packed or None] * n, "stages": {frame: [packed + "name"]}}`` or ``{"mode": "serve"}`` (the
    page fetches ``frames/<k>`` and ``stages/<k>`` from its server), in the harness's page document
    (:func:`hil_harness.webpage.page_document`)."""
    title = f"uvisi view: {data['recording']['scenario']} ({data['recording']['name']})"
    values = {"DATA": script_json(data), "IMAGES": script_json(images)}
    body = _PLACEHOLDER.sub(lambda m: values[m.group(1)], _resource("page.html"))
    return page_document(title, _resource("page.css"), body, page_js())


def frame_bytes(rec, k: int) -> bytes:
    """Frame ``k`` of a recording, packed (:func:`.codec.pack`)."""
    return pack(np.asarray(rec.array("frames")[k]))


def inline_images(rec, data: dict, stages: dict, progress: bool = False) -> dict:
    """Every frame held, packed and base64-encoded, and the stage images by frame."""
    n = data["recording"]["frames_held"]
    frames = [None] * n
    if data["recording"]["has_frames"]:
        ds = rec.array("frames")
        it = range(n)
        if progress:
            from tqdm import tqdm
            it = tqdm(it, desc="uvisi view: packing frames", unit="frame", leave=False)
        for k in it:
            frames[k] = base64.b64encode(pack(np.asarray(ds[k]))).decode("ascii")
    shape, code = data["image_shape"], "u2"
    return {"mode": "inline",
            "frames": [None if f is None else {"shape": shape, "dtype": code, "data": f}
                       for f in frames],
            "stages": {str(k): v for k, v in stages.items()}}


def build(rec, progress: bool = False, replay_stages: bool = True) -> str:
    """The self-contained page of an open recording."""
    data = extract(rec)
    stages = stages_by_frame(rec, data, progress=progress) if replay_stages else {}
    replayed = bool(stages)
    if not replayed:
        k, st = recorded_stages(rec)
        if st:
            stages = {k: stage_entries(st)}
    data["stage_note"] = stage_note(data, replayed)
    return page_html(data, inline_images(rec, data, stages, progress))
