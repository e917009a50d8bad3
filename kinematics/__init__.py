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
from kinematics.status import AssemblyError, Branch, Status, describe_status
from kinematics.timing import crank_speed, time_derivatives

__all__ = [
    "AssemblyError",
    "Branch",
    "FourBarMotion",
    "GrashofType",
    "RockerLimits",
    "Status",
    "check_lengths",
    "crank_range",
    "crank_speed",
    "describe_status",
    "fourbar_motion",
    "grashof_type",
    "rocker_limits",
    "time_derivatives",
    "transmission_angle",
]
