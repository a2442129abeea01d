"""copy.copy of a controller shell is a controller in the same state that steps on its own (a
shallow copy would share the state arrays: two controllers stepping one state)."""

from __future__ import annotations

import copy

import numpy as np

from flatfree.actuators import ActuatorParams
from flatfree.controllers.intelligent import IPD
from flatfree.controllers.vehicle import NaturalOutputController
from flatfree.vehicles import load_vehicle


def _ipd():
    return IPD(alpha=2.0, kp=4.0, kd=4.0, dt=0.01, window=10)


def _natural():
    c = NaturalOutputController(
        dt=0.001, actuators=ActuatorParams.from_vehicle(load_vehicle("peugeot406")))
    c.reset()
    return c


def _step_ipd(c, k):
    return c.step(y=0.01 * np.sin(0.3 * k), y_ref=0.0, y_ref_dot=0.0, y_ref_ddot=0.0)


def _step_natural(c, k):
    return c.step(vx=20.0 + 0.01 * k, r=0.01 * np.sin(0.1 * k), e_y=0.01 * np.cos(0.05 * k),
                  kappa=0.001, vx_ref=21.0)


def _check(make, step):
    a, twin = make(), make()
    for k in range(150):  # past the windows: the laws run
        assert step(a, k) == step(twin, k)
    b = copy.copy(a)
    # the copy starts where the original is and continues as it would ...
    assert [step(b, k) for k in range(150, 200)] == [step(twin, k) for k in range(150, 200)]
    # ... without touching the original, which continues from its own state (a second twin)
    fresh = make()
    for k in range(150):
        step(fresh, k)
    assert [step(a, k) for k in range(150, 200)] == [step(fresh, k) for k in range(150, 200)]


def test_a_copied_intelligent_controller_steps_on_its_own():
    _check(_ipd, _step_ipd)


def test_a_copied_natural_output_controller_steps_on_its_own():
    _check(_natural, _step_natural)
