"""Detection on image files, the ground side of ``uvisi detect``: the flight IP's stage kernels run
over large frames.

==================  ================================================================================
:mod:`.fullframe`   a large image seen through overlapping flight windows: the flight front end once
                    on the frame, a pixel kept where any window's threshold passes it, the flight
                    back end once (:mod:`.frame_k`, :mod:`.union`: its compiled kernels)
:mod:`.jobs`        the jobs ``uvisi detect`` offers (star, streak, aurora): sequence, record, tile
                    size and the star job's significance gate
:mod:`.noise`       the frame's pixel noise (``hil_harness.images.noise_sigma``'s number), compiled
:mod:`.photometry`  the star job's aperture photometry and ground ordering
==================  ================================================================================

Reading the image files themselves is :mod:`hil_harness.images` (shared with ``uvisi track`` and
the tuning sets).
"""
