"""The declarative model: what the user builds. Imports nothing heavier than numpy."""

from .checks import LoadError, ModelError
from .bodies import Body, Ground, RigidBody
from .channels import Channel
from .drivers import Driver
from .flexible_beam import FlexibleBeam
from .forces import Force, RotationalSpring, Spring, Torque
from .gears import Gear
from .friction import Friction
from .stops import Stop
from .joints import Joint, PointOnCurve, Prismatic, Revolute
from .mechanism import AssemblyError, AssemblyReport, DofReport, MechanismModel
from .parameters import Dual, Parameter

__all__ = ["AssemblyError", "LoadError", "AssemblyReport", "Body", "Channel", "DofReport", "Driver", "Dual", "FlexibleBeam", "Force", "Friction", "Gear", "Ground",
           "Joint", "MechanismModel", "ModelError", "Parameter", "PointOnCurve", "Prismatic", "Revolute", "RigidBody", "RotationalSpring", "Spring",
           "Stop", "Torque"]
