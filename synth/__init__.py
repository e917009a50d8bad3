"""Curvature theory of the coupler motion (pole, inflection circle, cubic of stationary
curvature, Ball and double Ball points, line scanning), pure and vectorized: arrays in,
frozen struct-of-arrays dataclasses out, degenerate cases as :class:`kinematics.Status` flags.
"""

from synth.ball import BallPoint, ball_point, ball_point_offset, ball_point_offset_rate
from synth.double_ball import DoubleBallPoints, double_ball_points, theta4
from synth.inflection import CurvatureCentre, InflectionCircle, euler_savary, inflection_circle
from synth.line_scan import ConjugatePairs, line_scan
from synth.pole import Pole, loop_condition, pole

__all__ = [
    "BallPoint",
    "ConjugatePairs",
    "CurvatureCentre",
    "DoubleBallPoints",
    "InflectionCircle",
    "Pole",
    "ball_point",
    "ball_point_offset",
    "ball_point_offset_rate",
    "double_ball_points",
    "euler_savary",
    "inflection_circle",
    "line_scan",
    "loop_condition",
    "pole",
    "theta4",
]
