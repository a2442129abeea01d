"""flatfree: flatness-based and model-free longitudinal and lateral control of autonomous cars.

Conventions: ISO 8855 axes (x forward, y left, z up), SI units inside, reference point the CoG.
"""

from flatfree.vehicles import TireParams, VehicleParams, load_tire, load_vehicle

__version__ = "0.1.0.dev0"

__all__ = ["TireParams", "VehicleParams", "load_tire", "load_vehicle", "__version__"]
