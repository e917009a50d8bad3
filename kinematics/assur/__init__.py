"""General planar linkages from Assur groups: description files, decomposition, every
assembly configuration, velocities and accelerations, limit positions.

Typical use::

    linkage = linkage_from_text(path.read_text())          # validated, DOF checked
    start = configurations(linkage, [np.radians(30)])[0]    # configuration 1 at 30°
    asm = assemble(linkage, inputs, start)                  # followed over a sweep
    motion = linkage_motion(linkage, asm, rates=[omega])    # J·q̇ = E, J·q̈ = C
"""

from kinematics.assur.limits import LimitPosition, OutputLimits, limit_positions, output_at, output_series
from kinematics.assur.linkage_file import linkage_from_mapping, linkage_from_text
from kinematics.assur.model import (
    GROUND,
    Input,
    Link,
    Linkage,
    LinkageFileError,
    Output,
    PrismaticPair,
    RevolutePair,
)
from kinematics.assur.positions import (
    MAX_CONFIGURATIONS,
    Assembly,
    ConfigurationLimit,
    assemble,
    configurations,
    loop_closure,
)
from kinematics.assur.topology import AssurGroup, Body, Decomposition, decompose
from kinematics.assur.transmission import TransmissionMinimum, transmission_angles, transmission_minima
from kinematics.assur.velocity import LinkageMotion, linkage_motion

__all__ = [
    "MAX_CONFIGURATIONS",
    "ConfigurationLimit",
    "GROUND",
    "Assembly",
    "AssurGroup",
    "Body",
    "Decomposition",
    "Input",
    "LimitPosition",
    "Link",
    "Linkage",
    "LinkageFileError",
    "LinkageMotion",
    "Output",
    "OutputLimits",
    "PrismaticPair",
    "RevolutePair",
    "TransmissionMinimum",
    "assemble",
    "configurations",
    "decompose",
    "limit_positions",
    "linkage_from_mapping",
    "linkage_from_text",
    "linkage_motion",
    "loop_closure",
    "output_at",
    "output_series",
    "transmission_angles",
    "transmission_minima",
]
