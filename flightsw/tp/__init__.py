"""MSX track processor (flight code, issue 7): boresight geometry, star/object velocity filtering
with alpha-beta gates and the paper's four rules, the 6-state EKF (RK4 plant, sequential scalar
updates), targets of opportunity, and the track command -- all in emulated MIL-STD-1750A float.

Public surface::

    from flightsw.tp import TrackProcessor, TPConfig, ImagerGeometry, NominalTrajectory, alpha_beta_step
    tp = TrackProcessor(TPConfig(imagers={"wfov_vis": geom}, nominal=nominal)); tp.reset()
    cmd = tp.step(candidate_message_or_words, attitude_data, ledger=None)   # -> TrackCommand
    words = cmd.to_words()                                   # the bus form (uint16, CRC)
    verdict = tp.uplink(encode_uplink(gate_px=3.0))          # -> UplinkVerdict, next frame
"""
from flightsw.tp.alphabeta import alpha_beta_step, step_response_frames
from flightsw.tp.config import TPConfig
from flightsw.tp.dynamics import NominalTrajectory
from flightsw.tp.ekf import EKF1750
from flightsw.tp.geometry import (ImagerGeometry, body_to_pixel, imager_unit_vector, pixel_to_body,
                                  pixel_to_tangent, tangent_to_pixel)
from flightsw.tp.state import STAGES
from flightsw.tp.processor import TrackProcessor
from flightsw.tp.uplink import UplinkVerdict, decode_uplink, encode_uplink

__all__ = ["TrackProcessor", "UplinkVerdict", "encode_uplink",
           "decode_uplink", "TPConfig", "ImagerGeometry", "NominalTrajectory", "alpha_beta_step",
           "step_response_frames", "EKF1750", "STAGES", "pixel_to_tangent", "tangent_to_pixel",
           "pixel_to_body", "body_to_pixel", "imager_unit_vector"]
