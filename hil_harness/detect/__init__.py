"""Detection on image files, the ground side of ``uvisi detect``: the flight IP run unchanged over
large frames.

=================  =================================================================================
:mod:`.fullframe`  a large image cut into overlapping flight windows, duplicates merged, every blob
                   ranked together by the flight ranking routine
:mod:`.jobs`       the jobs ``uvisi detect`` offers (star, streak, aurora): sequence, record, tile
                   size and the star job's significance gate
=================  =================================================================================

Reading the image files themselves is :mod:`hil_harness.images` (shared with ``uvisi track`` and
the tuning sets).
"""
