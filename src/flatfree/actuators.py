"""Actuators of the sampled-data loop: steering and wheel torque, with limits, lag and dead time.

The controller commands a wheel torque T_w [N m] (positive drive, negative brake) and a road-wheel
steer angle delta [rad]. Between command and plant, :func:`actuate_step` applies, in order:

1. **dead time**: the command of ``delay_steps`` plant steps earlier (rounded to the nearest
   plant step, an exact half to the even number as Python's ``round``; a delay so moved is
   said in a warning by :meth:`ActuatorParams.to_array`);
2. **first-order lag** with time constant ``tau`` [s], discretised exactly for a command held over
   the step: ``y += (1 - exp(-dt / tau)) (u - y)`` (``tau = 0``: no lag);
3. **rate limit** (steering) [rad/s];
4. **range limit**: steer to [-max_steer, max_steer]; torque to
   [-max_brake_torque, min(max_drive_torque, max_power R_e / max(|v_drive|, v_power_min))].
   ``v_drive`` is the speed at which the drive torque works: R_e times the driven wheels'
   spin rates in their torque shares (:func:`flatfree.models.tendof.drive_speed`; the
   closed loop passes it for the 10DoF plant), so that a driven wheel spinning up takes its
   power too; the body speed where the wheels are not modelled (3DoF plant, a user's loop).

Limits come from the vehicle (:meth:`ActuatorParams.from_vehicle`) and may be overridden. Input
limits live here, never inside the vehicle's vector field.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit

from flatfree._validate import in_range, nonnegative, positive, whole_steps
from flatfree._vecmath import no_refcount
from flatfree._warn import warn
from flatfree.vehicles.params import VehicleParams

__all__ = ["ActuatorParams", "actuate_step", "actuator_state"]

#: Speed below which the power cap of the drive torque is not applied [m/s] (avoids P R / 0).
V_POWER_MIN = 1.0


@dataclass(frozen=True, slots=True, kw_only=True)
class ActuatorParams:
    """Steering and torque actuator settings (SI)."""

    max_steer: float  # [rad]
    max_steer_rate: float  # [rad/s]
    steer_tau: float = 0.0  # first-order lag [s]
    steer_delay: float = 0.0  # dead time [s]
    max_drive_torque: float  # [N m]
    max_power: float  # [W]
    max_brake_torque: float  # [N m]
    wheel_radius: float  # R_e [m], for the power cap
    torque_tau: float = 0.0  # [s]
    torque_delay: float = 0.0  # [s]

    def __post_init__(self) -> None:
        # a road-wheel angle (as VehicleParams'): 40 would be degrees given as radians
        in_range("max_steer", self.max_steer, 0.0, 0.5 * math.pi, "rad", lo_open=True)
        positive("max_steer_rate", self.max_steer_rate, "rad/s")
        nonnegative("steer_tau", self.steer_tau, "s")
        nonnegative("steer_delay", self.steer_delay, "s")
        positive("max_drive_torque", self.max_drive_torque, "N m")
        positive("max_power", self.max_power, "W")
        positive("max_brake_torque", self.max_brake_torque, "N m")
        positive("wheel_radius", self.wheel_radius, "m")
        nonnegative("torque_tau", self.torque_tau, "s")
        nonnegative("torque_delay", self.torque_delay, "s")

    @classmethod
    def from_vehicle(cls, vehicle: VehicleParams, **overrides) -> ActuatorParams:
        """Limits of a vehicle preset; lags and delays default to 0 unless given."""
        base = dict(
            max_steer=vehicle.max_steer,
            max_steer_rate=vehicle.max_steer_rate,
            max_drive_torque=vehicle.max_drive_torque,
            max_power=vehicle.max_power,
            max_brake_torque=vehicle.max_brake_torque,
            wheel_radius=vehicle.wheel_radius,
        )
        base.update(overrides)
        return cls(**base)

    def to_array(self, dt: float) -> np.ndarray:
        """Parameters for :func:`actuate_step` at plant step ``dt`` [s]."""
        dt = positive("dt", dt, "s")
        a_s = 1.0 if self.steer_tau == 0.0 else 1.0 - math.exp(-dt / self.steer_tau)
        a_t = 1.0 if self.torque_tau == 0.0 else 1.0 - math.exp(-dt / self.torque_tau)
        # the plant's clock is all the dead time has: say where it moves a setting (as the
        # sensors do for theirs)
        steps, rounded = {}, []
        for name in ("steer_delay", "torque_delay"):
            delay = getattr(self, name)
            steps[name], moved = whole_steps(delay, dt)
            if moved:
                rounded.append(f"{name} = {delay:g} s -> {steps[name] * dt:g} s")
        if rounded:
            warn(f"actuators at a step of {dt:g} s: {'; '.join(rounded)} "
                 "(rounded to whole steps)")
        return np.array([
            self.max_steer, self.max_steer_rate * dt, a_s, steps["steer_delay"],
            self.max_drive_torque, self.max_power * self.wheel_radius, self.max_brake_torque,
            a_t, steps["torque_delay"],
        ])


def actuator_state(params: ActuatorParams, dt: float, steer0: float = 0.0,
                   torque0: float = 0.0) -> np.ndarray:
    """Initial state for :func:`actuate_step`: outputs and the dead-time ring buffers."""
    n_s = whole_steps(params.steer_delay, dt)[0] + 1
    n_t = whole_steps(params.torque_delay, dt)[0] + 1
    depth = max(n_s, n_t)
    # layout: [steer_out, torque_out, write_index, steer_buf(depth), torque_buf(depth)]
    st = np.empty(3 + 2 * depth)
    st[0] = steer0
    st[1] = torque0
    st[2] = 0.0
    st[3:3 + depth] = steer0
    st[3 + depth:] = torque0
    return st


@njit(**no_refcount({"cache": True}))
def actuate_step(torque_cmd, steer_cmd, v_drive, p, st):
    """Advance the actuators by one plant step; returns (torque_applied, steer_applied).

    ``v_drive`` [m/s] is the speed of the power cap (module docstring, item 4).
    ``p`` from :meth:`ActuatorParams.to_array`, ``st`` from :func:`actuator_state` (mutated).
    A non-finite command is ignored (the previous command is repeated). Allocation-free,
    compiled without reference counting (``flatfree._vecmath.no_refcount``).
    """
    depth = (st.shape[0] - 3) // 2
    w = int(st[2])
    # ring indices (w in [0, depth)): Python's modulo, without an integer division per step
    # where the index is already in range (no delay)
    prev = w - 1 if w > 0 else depth - 1
    if not math.isfinite(steer_cmd):
        steer_cmd = st[3 + prev]
    if not math.isfinite(torque_cmd):
        torque_cmd = st[3 + depth + prev]
    st[3 + w] = steer_cmd
    st[3 + depth + w] = torque_cmd
    d_s = int(p[3])
    d_t = int(p[8])
    i_s = w - d_s
    if i_s < 0:
        i_s %= depth
    i_t = w - d_t
    if i_t < 0:
        i_t %= depth
    steer_in = st[3 + i_s]
    torque_in = st[3 + depth + i_t]
    st[2] = w + 1 if w + 1 < depth else 0
    # steering: lag, rate limit, range
    target = st[0] + p[2] * (steer_in - st[0])
    dmax = p[1]
    step = min(max(target - st[0], -dmax), dmax)
    s = min(max(st[0] + step, -p[0]), p[0])
    st[0] = s
    # torque: lag, range with the power cap
    tq = st[1] + p[7] * (torque_in - st[1])
    drive_cap = min(p[4], p[5] / max(abs(v_drive), V_POWER_MIN))
    tq = min(max(tq, -p[6]), drive_cap)
    st[1] = tq
    return tq, s
