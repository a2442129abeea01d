"""The common Python door of the compiled controllers (DESIGN.md "Speed by design").

Each built-in controller is a pure compiled step over a parameter array and a state array; its
Python class holds the frozen parameters and those two arrays. This base class carries that
shared part; subclasses add ``reset()``, ``step(...)`` and ``status``.
"""

from __future__ import annotations

from typing import Any

import numpy as np

__all__ = ["CompiledController"]


class CompiledController:
    """Frozen parameters plus the compiled kernel's parameter and state arrays."""

    __slots__ = ("_params", "_p", "_s")

    def __init__(self, params: Any, params_type: type, make_state) -> None:
        if not isinstance(params, params_type):
            raise ValueError(f"params = {params!r}: expected {params_type.__name__}")
        self._params = params
        self._p = params.to_array()
        self._s = make_state(self._p)

    @property
    def params(self) -> Any:
        """The frozen parameters."""
        return self._params

    @property
    def params_array(self) -> np.ndarray:
        """The compiled kernel's parameter array (read it, do not modify it)."""
        return self._p

    @property
    def state_array(self) -> np.ndarray:
        """The compiled kernel's state array (mutated by every step)."""
        return self._s
