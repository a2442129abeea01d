"""Vehicle and tyre parameters: validated frozen types and the bundled presets."""

from flatfree.vehicles.params import (
    TP,
    VP,
    TireParams,
    VehicleParams,
    load_tire,
    load_vehicle,
    tire_names,
    vehicle_names,
)

__all__ = [
    "TP",
    "VP",
    "TireParams",
    "VehicleParams",
    "load_tire",
    "load_vehicle",
    "tire_names",
    "vehicle_names",
]
