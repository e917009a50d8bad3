"""Pure, vectorized kinematic analysis of the classic mechanisms (no I/O, no database)."""

from kinematics.fourbar import (
    FourBarMotion,
    GrashofType,
    RockerLimits,
    check_lengths,
    crank_range,
    fourbar_motion,
    grashof_type,
    rocker_limits,
    transmission_angle,
)
from kinematics.fourbar_stats import CvMinimum, OutputSpeedStats, minimise_cv, output_speed_stats
from kinematics.shaper import ShaperMotion, check_shaper, shaper_limits, shaper_motion
from kinematics.slider_crank import (
    SliderBranch,
    SliderCrankMotion,
    SliderLimits,
    check_finite,
    check_slider_branch,
    slider_crank_limits,
    slider_crank_motion,
    slider_crank_range,
    slider_limits_from,
    slider_time_ratio,
)
from kinematics.status import AssemblyError, Branch, Status, describe_status
from kinematics.timing import crank_speed, time_derivatives

__all__ = [
    "AssemblyError",
    "Branch",
    "CvMinimum",
    "FourBarMotion",
    "GrashofType",
    "OutputSpeedStats",
    "RockerLimits",
    "ShaperMotion",
    "SliderBranch",
    "SliderCrankMotion",
    "SliderLimits",
    "Status",
    "check_finite",
    "check_lengths",
    "check_shaper",
    "check_slider_branch",
    "crank_range",
    "crank_speed",
    "describe_status",
    "fourbar_motion",
    "grashof_type",
    "minimise_cv",
    "output_speed_stats",
    "rocker_limits",
    "shaper_limits",
    "shaper_motion",
    "slider_crank_limits",
    "slider_crank_motion",
    "slider_crank_range",
    "slider_limits_from",
    "slider_time_ratio",
    "time_derivatives",
    "transmission_angle",
]
