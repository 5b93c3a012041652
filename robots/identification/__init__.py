"""Identification of a robot's inertial parameters, friction and armature from its logs.

Modules: ``inertial`` (one body's 10 parameters, log-Cholesky, physical consistency),
``parameters`` (the parameter vector of a robot), ``samples`` (from a log to samples),
``regressor`` (the stacked equations, contacts projected out), ``identifiability`` (rank, base
parameters, why not, how strongly excited), ``estimate`` (the consistent MAP estimate),
``uncertainty`` (its residual-aware covariance), ``writeback`` (the identified MJCF),
``pipeline`` (``identify``: all of it), ``summary`` (each body and joint with its uncertainty and
how the data determined it: the report's numbers).
"""

from mbctl.robots.identification.exceptions import BadLogError, IdentificationError, InconsistentParameters
from mbctl.robots.identification.parameters import ParameterSet
from mbctl.robots.identification.pipeline import Identification, IdentifyOptions, identify, model_fingerprint
from mbctl.robots.identification.samples import RecordedLog, add_noise
from mbctl.robots.identification.summary import BodySummary, body_summary, com_covariance, joint_summaries
from mbctl.robots.identification.writeback import identified_spec, identified_xml

__all__ = [
    "BadLogError",
    "BodySummary",
    "Identification",
    "IdentificationError",
    "IdentifyOptions",
    "InconsistentParameters",
    "ParameterSet",
    "RecordedLog",
    "add_noise",
    "body_summary",
    "com_covariance",
    "identified_spec",
    "identified_xml",
    "identify",
    "joint_summaries",
    "model_fingerprint",
]
