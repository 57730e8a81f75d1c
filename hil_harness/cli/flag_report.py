"""Bad-frame flags on the console: one line for each kind of flagged frame, not one a frame.

A real sequence can flag many frames alike (58 of the 150 Gillam 2008 frames are flagged
``saturated``); the commands that read sequences (``uvisi track``, ``uvisi detect``) print one line
for each kind, naming the frames as runs of a cube's indices, and leave every frame's flags to
their JSON.
"""
from __future__ import annotations

import re

__all__ = ["flag_lines", "FLAG_LINE_ITEMS"]

#: the most frames or runs of frames one flag line names; the JSON has every frame's flags
FLAG_LINE_ITEMS = 12


def flag_lines(names: list, flags: list, skip, why) -> list[str]:
    """One line for each kind of flagged frame (the same flags, unusable or not), in the order the
    kinds first occur: the frame (``x.npz[2]: flagged blank (...)``) or, for several, how many
    and which (``58 of 150 frames flagged saturated (...): x.npz[54-57, 60-71]``; a cube's frames
    as runs of indices, at most :data:`FLAG_LINE_ITEMS` runs or files, then how many more).

    ``names``: each frame's input name (``file[k]`` for the frames of a cube); ``flags``: each
    frame's flag names (:func:`hil_harness.images.frame_flags`); ``skip``: whether each is
    unusable; ``why(unusable, several)``: what the flag means for the command's answer, in
    words."""
    groups: dict = {}
    for k, (f, s) in enumerate(zip(flags, skip)):
        if f:
            groups.setdefault((tuple(f), bool(s)), []).append(k)
    out = []
    for (f, s), ks in groups.items():
        if len(ks) == 1:
            out.append(f"{names[ks[0]]}: flagged {', '.join(f)} ({why(s, False)})")
        else:
            out.append(f"{len(ks)} of {len(names)} frames flagged {', '.join(f)} "
                       f"({why(s, True)}): {_frame_list([names[k] for k in ks])}")
    return out


def _frame_list(names: list) -> str:
    """``names`` shortened: a cube's consecutive frames ``x[3]``, ``x[4]``, ``x[5]`` as
    ``x[3-5]``; at most :data:`FLAG_LINE_ITEMS` runs or files named, then how many frames
    more."""
    items: list = []                    # [base, [[first, last], ...]] or [name, None]
    for n in names:
        m = re.fullmatch(r"(.*)\[(\d+)\]", n)
        if m is None:
            items.append([n, None])
            continue
        base, k = m.group(1), int(m.group(2))
        if not items or items[-1][0] != base or items[-1][1] is None:
            items.append([base, []])
        runs = items[-1][1]
        if runs and runs[-1][1] == k - 1:
            runs[-1][1] = k
        else:
            runs.append([k, k])
    parts, left, shown = [], FLAG_LINE_ITEMS, 0
    for base, runs in items:
        if left == 0:
            break
        if runs is None:
            parts.append(base)
            left, shown = left - 1, shown + 1
            continue
        runs = runs[:left]
        left -= len(runs)
        shown += sum(b - a + 1 for a, b in runs)
        parts.append(base + "[" + ", ".join(str(a) if a == b else f"{a}-{b}" for a, b in runs)
                     + "]")
    more = f" and {len(names) - shown} more" if shown < len(names) else ""
    return ", ".join(parts) + more + " (each frame's flags are in the JSON)"
