"""Vehicle models: the paper's 3DoF design model and the 10DoF validation model."""

from flatfree.models.bicycle3dof import (
    Bicycle3DoFParams,
    BicycleInput,
    BicyclePoseState,
    BicycleState,
)
from flatfree.models.tendof import TenDoF, TenDoFInput, TenDoFOptions, TenDoFState, Wheel

__all__ = [
    "Bicycle3DoFParams",
    "BicycleInput",
    "BicyclePoseState",
    "BicycleState",
    "TenDoF",
    "TenDoFInput",
    "TenDoFOptions",
    "TenDoFState",
    "Wheel",
]
