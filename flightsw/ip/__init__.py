"""The UVISI image processor (flight code): the flight module :class:`ImageProcessor`, its one
compiled pipeline (:mod:`flightsw.ip.pipeline`) and the stage kernels it runs."""
from flightsw.ip.preprocess import FRAME_SHAPE, Subimage, compact, window, window_origin
from flightsw.ip.filters import (DEFAULT_KERNELS, correlate_q15, filter_cycles, gaussian_taps_q15,
                                 matched_kernel, smoothing_kernel, validate_kernel)
from flightsw.ip.detrend import (detrend_highpass, detrend_none, detrend_polynomial,
                                 highpass_cycles, polynomial_cycles)
from flightsw.ip.threshold import AlphaController, threshold_cycles
from flightsw.ip.sequence import (PHASE_FEATURES, PHASE_FRONT, PHASE_LABEL, PHASE_RANK,
                                  PHASE_THRESHOLD, STEP_REGISTRY, FieldError, IPConfig,
                                  ProcessingSequence, SequenceError, Stage, load_default_sequence)
from flightsw.ip.cycles import frontend_cycle_table
from flightsw.ip.fftfilter import fft_correlate, fft_filter_cycles, gaussian_kernel_q15
from flightsw.ip.colour import label  # noqa: E402  (issue 4 back end)
from flightsw.ip.features import features  # noqa: E402
from flightsw.ip.backend import backend  # noqa: E402
from flightsw.ip.frame import process_frame, process_window  # noqa: E402
from flightsw.ip.pipeline import FramePlan, FrameResult  # noqa: E402
from flightsw.ip.processor import ImageProcessor, IPOutput, UplinkVerdict  # noqa: E402
from flightsw.ip.sequence_words import sequence_from_words, sequence_to_words  # noqa: E402
