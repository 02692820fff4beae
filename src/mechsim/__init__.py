"""mechsim: planar multibody mechanisms with sympy-generated constraints.

>>> import mechsim as ms
>>> mech = ms.examples.double_four_bar()
>>> res = mech.simulate(t_end=0.1, rtol=1e-8, atol=1e-10)
>>> res.status
'success'

Heavy dependencies load only when used: sympy when a model is not in the cache, scipy when a
simulation starts, matplotlib when a plot is drawn, meshio when a result is exported.
"""

from importlib import import_module as _import_module

from .model import (AssemblyError, Body, Channel, LoadError, DofReport, Driver, FlexibleBeam, Force, Friction, Gear, Ground, Joint,
                    ModelError, Parameter, PointOnCurve, Prismatic, Revolute, RigidBody,
                    RotationalSpring, Spring, Stop, Torque)

from .facade import Mechanism

__version__ = "0.1.0"

_LAZY_MODULES = {"examples", "codegen", "formulations", "integrators", "run", "app",
                 "results", "linear", "shooting", "engineering", "study",
                 "assembly", "design", "objectives"}
_LAZY_NAMES = {"SimulationResult": "results", "load_result": "app.loading",
               "load_scene": "app.scene", "load_mechanism": "app.scene", "LinearSystem": "linear",
               "sweep": "study",
               "Study": "study", "optimize": "design", "PathPoints": "objectives",
               "FunctionPoints": "objectives",
               "EffortNorm": "objectives", "TransmissionAngle": "objectives",
               "JointForceNorm": "objectives", "GrashofCrank": "objectives",
               "multistart": "design"}
_ALIASES = {"solver": "run.solver", "scene": "app.scene", "bench": "app.bench",
            "rotor": "linear.rotor", "analysis": "linear.analysis",
            "oscillators": "shooting.oscillators"}


def __getattr__(name):
    if name in _LAZY_MODULES:
        return _import_module(f".{name}", __name__)
    if name in _ALIASES:
        return _import_module(f".{_ALIASES[name]}", __name__)
    if name in _LAZY_NAMES:
        return getattr(_import_module(f".{_LAZY_NAMES[name]}", __name__), name)
    raise AttributeError(f"module 'mechsim' has no attribute {name!r}")


def __dir__():
    """The public names, those loaded on first use included."""
    return sorted(set(__all__) | _LAZY_MODULES | set(_ALIASES) | {"__version__"})


__all__ = ["AssemblyError", "Body", "Channel", "LoadError", "DofReport", "Driver", "FlexibleBeam", "Force", "Friction", "Gear", "Ground", "Joint",
           "LinearSystem", "Mechanism", "ModelError", "Parameter", "PointOnCurve", "Prismatic", "Revolute", "RigidBody",
           "RotationalSpring", "SimulationResult", "Spring", "Stop", "Study", "Torque", "load_mechanism", "optimize", "PathPoints", "FunctionPoints", "EffortNorm", "TransmissionAngle", "multistart", "JointForceNorm", "GrashofCrank",
           "load_result", "load_scene", "sweep"]
