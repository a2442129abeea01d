"""The common Python door of the compiled controllers (DESIGN.md "Speed by design").

Each built-in controller is a pure compiled step over a parameter array and a state array; its
Python class holds the frozen parameters and those two arrays. This base class carries that
shared part; subclasses add ``reset()``, ``step(...)`` and ``status``.

Arguments of ``step`` (called once per control period in users' Python loops) are checked at
the door, cheaply: a float (Python or NumPy float64) passes as it is, in one ``isinstance``
test (``x if isinstance(x, float) else real(...)``); anything else goes through
:func:`flatfree._validate.real`, which refuses text, ``None``, booleans and arrays with a
``ValueError`` naming the argument (the compiled kernels would give numba's
``TypeError``/``TypingError``). Non-finite values pass: each controller documents its policy
for a missing sample. A step
whose command comes out non-finite (the arithmetic overflowed: values of the order of 1e300)
raises :func:`nonfinite_command`'s ``ValueError`` instead of returning NaN.
"""

from __future__ import annotations

import copy
import math
from collections.abc import Mapping
from typing import Any

import numpy as np

__all__ = ["CompiledController", "nonfinite_command", "independent_copy"]


def nonfinite_command(owner: str, commands: Mapping[str, float], inputs: Mapping[str, object],
                      after: str) -> ValueError:
    """The ``ValueError`` of a step whose command came out non-finite (module docstring).

    ``commands`` maps each command's name to its value, in the order the step returns them
    (``{"torque": tw, "steer": delta}``, ``{"u": u}``); the error names the first non-finite
    one, its value and the step's ``inputs``; ``after`` says what the shell did to its state.
    At least one command must be non-finite (the caller's test).
    """
    bad = [(name, v) for name, v in commands.items() if not math.isfinite(v)]
    if not bad:
        raise ValueError(f"commands = {commands!r}: none is non-finite")
    command, value = bad[0]
    shown = ", ".join(f"{k} = {v!r}" for k, v in inputs.items())
    return ValueError(f"{owner}.step({shown}): the command {command} = {value!r} is not finite "
                      "(the control law overflowed: a value of the order of 1e300 in these "
                      f"inputs or still in the estimator's window); {after}")


def independent_copy(obj):
    """``copy.copy`` of a controller shell: a controller in the same state that steps on its
    own (the state arrays copied). The shallow copy Python makes by default would share them,
    and two controllers would step one state."""
    return copy.deepcopy(obj)


class CompiledController:
    """Frozen parameters plus the compiled kernel's parameter and state arrays.

    A controller is not safe to step from two threads at once (its state arrays are updated
    in place): give each loop its own. ``copy.copy`` gives an independent controller in the
    same state (:func:`independent_copy`), e.g. to try a step without disturbing the original.
    """

    __slots__ = ("_params", "_p", "_s")

    __copy__ = independent_copy

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
