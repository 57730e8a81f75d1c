"""Emulated ADSP-2100 cycles of the IP front end per step, for the budget tables.

:func:`frontend_cycle_table` runs a sequence (default: the shipped satellite sequence) on a synthetic
frame for each window size and reads the cycles back from the frame's
:class:`~flightsw.budget.Ledger`, so the table is what the pipeline actually charges.
"""
from __future__ import annotations

import numpy as np

from flightsw.budget import ADSP2100, ADSP2100A, Ledger

__all__ = ["frontend_cycle_table", "format_cycle_table"]


def frontend_cycle_table(windows=(32, 64, 96, 128), sequence="satellite", compaction=None):
    """Per-step DSP cycles of the front end for each window size.

    Parameters
    ----------
    windows : sizes of the (square) window in compacted pixels
    sequence : shipped sequence name or a :class:`~flightsw.ip.sequence.ProcessingSequence`
    compaction : override the sequence's compaction factor (1 lets windows up to 128 fit)

    Returns
    -------
    list of dict: ``{"window", "shape", "stages": {stage: cycles}, "total", "ms_8MHz",
    "ms_12MHz", "frame_fraction_8MHz"}`` (the 8.192 MHz ADSP-2100 and 12.5 MHz 2100A clocks).
    """
    from flightsw.ip.sequence import ProcessingSequence, load_default_sequence
    seq = load_default_sequence(sequence) if isinstance(sequence, str) else sequence
    rng = np.random.default_rng(0)
    frame = rng.poisson(100, (244, 256)).astype(np.uint16)
    rows = []
    for w in windows:
        d = seq.to_dict()
        d["preprocess"]["window"] = int(w)
        if compaction is not None:
            d["preprocess"]["compaction"] = int(compaction)
        s = ProcessingSequence.from_dict(d)
        led = Ledger()
        res = s.run_frame(frame, ledger=led)
        stages = led.stages("dsp")
        total = led.cycles("dsp")
        rows.append({"window": int(w), "shape": tuple(res.subimage.size), "stages": stages,
                     "total": total, "ms_8MHz": 1e3 * ADSP2100.seconds(total),
                     "ms_12MHz": 1e3 * ADSP2100A.seconds(total),
                     "frame_fraction_8MHz": ADSP2100.seconds(total) / led.period_s})
    return rows


def format_cycle_table(rows=None):
    """Markdown table of :func:`frontend_cycle_table` rows (stages as columns)."""
    rows = frontend_cycle_table() if rows is None else rows
    stages = list(rows[0]["stages"])
    head = "| window | " + " | ".join(stages) + " | total | ms @ 8.192 MHz | % of 500 ms |"
    sep = "|" + "---|" * (len(stages) + 4)
    lines = [head, sep]
    for r in rows:
        cells = [f"{r['stages'].get(s, 0):,}" for s in stages]
        lines.append(f"| {r['shape'][0]}x{r['shape'][1]} | " + " | ".join(cells)
                     + f" | {r['total']:,} | {r['ms_8MHz']:.2f} | "
                     f"{100 * r['frame_fraction_8MHz']:.1f} |")
    return "\n".join(lines)


if __name__ == "__main__":       # python -m flightsw.ip.cycles
    print(format_cycle_table())
