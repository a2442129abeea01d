"""flatfree: flatness-based and model-free longitudinal and lateral control of autonomous cars.

Conventions: ISO 8855 axes (x forward, y left, z up), SI units inside, reference point the CoG.

The names below are the curated public API. They are imported on first use (PEP 562), so
``import flatfree`` stays cheap (9-13 ms in a fresh process, of which the check below takes
~1-3 ms: benchmarks/bench_import.py) and its one side effect is on numba's cache: when the
package's sources changed since the last import, their stale compiled functions are cleared
(:mod:`flatfree._jitcache`). Subpackages hold the rest:
:mod:`flatfree.vehicles`, :mod:`flatfree.tires`, :mod:`flatfree.models`,
:mod:`flatfree.estimators`, :mod:`flatfree.controllers`, :mod:`flatfree.tracks`.
"""

from __future__ import annotations

import importlib
from types import ModuleType
from typing import Any

__version__ = "0.1.0.dev0"

# before any compiled function is loaded (every submodule imports this package first)
importlib.import_module("flatfree._jitcache").guard()

_API = {
    # vehicles and tyres
    "VehicleParams": "flatfree.vehicles",
    "TireParams": "flatfree.vehicles",
    "load_vehicle": "flatfree.vehicles",
    "load_tire": "flatfree.vehicles",
    # models
    "TenDoF": "flatfree.models.tendof",
    "Bicycle3DoFParams": "flatfree.models.bicycle3dof",
    # estimation
    "differentiate": "flatfree.estimators",
    # control
    "IP": "flatfree.controllers.intelligent",
    "IPI": "flatfree.controllers.intelligent",
    "IPD": "flatfree.controllers.intelligent",
    "IPID": "flatfree.controllers.intelligent",
    "IntelligentParams": "flatfree.controllers.intelligent",
    "FlatnessController": "flatfree.controllers.flatness_control",
    "FlatnessControlParams": "flatfree.controllers.flatness_control",
    "FlatReference": "flatfree.controllers.flatness_control",
    "flat_reference": "flatfree.controllers.flatness_control",
    "gains_from_poles": "flatfree.controllers.flatness_control",
    "NaturalOutputController": "flatfree.controllers.vehicle",
    "MfcNaturalSettings": "flatfree.controllers.vehicle",
    "FlatOutputController": "flatfree.controllers.flat_output",
    "FlatOutputStatus": "flatfree.controllers.flat_output",
    "NaturalOutputStatus": "flatfree.controllers.vehicle",
    "MfcFlatSettings": "flatfree.controllers.vehicle",
    "FlatnessSettings": "flatfree.controllers.vehicle",
    "ActuatorParams": "flatfree.actuators",
    # references
    "load_track": "flatfree.tracks",
    "load_recording": "flatfree.tracks",
    "make_reference": "flatfree.tracks",
    "lateral_deviation_acceleration": "flatfree.tracks",
    "SpeedLimits": "flatfree.tracks",
    # evaluation
    "Scenario": "flatfree.scenario",
    "load_scenario": "flatfree.scenario",
    "named_scenario": "flatfree.scenarios",
    "simulate": "flatfree.simulation",
    "Trajectory": "flatfree.trajectory",
    "compute_metrics": "flatfree.metrics",
}

# built from _API, the one list of the lazily imported names; a list at run time, which is all
# `from flatfree import *` needs (ruff wants a literal it can read without running the code)
__all__ = [*sorted(_API), "__version__"]  # noqa: PLE0604


#: The public subpackages and modules, imported on first use too (``flatfree.scenarios.
#: SCENARIO_NAMES`` without an ``import flatfree.scenarios`` first).
_MODULES = frozenset({
    "actuators", "cli", "controllers", "demo", "estimators", "metrics", "models", "plotting",
    "report", "scenario", "scenarios", "sensors", "simulation", "tires", "tracks",
    "trajectory", "units", "vehicles"})


def __getattr__(name: str) -> Any:
    if name in _MODULES:
        return importlib.import_module(f"flatfree.{name}")  # (sets the attribute itself)
    try:
        module = _API[name]
    except KeyError:
        raise AttributeError(f"module 'flatfree' has no attribute {name!r}") from None
    value = getattr(importlib.import_module(module), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    """The public names and the public subpackages imported so far (not this module's own
    imports: ``importlib``, ``Any``, ``annotations``, ``_jitcache``)."""
    subpackages = {n for n, v in globals().items()
                   if isinstance(v, ModuleType) and v.__name__.startswith("flatfree.")
                   and not n.startswith("_")}
    return sorted(set(__all__) | subpackages)
