"""Pulling away: the natural-output controller stepped from a standstill (issue 7 follow-up).

A user's loop steps the controller while the car stands (at a light, before a start): the
steer does not move e_y there, the iPD's F absorbs the missing response and its law, an
integrator in disguise at zero speed, turns the wheels towards their lock. Here the peugeot406
(10DoF, noise-free) stands ``STAND_S`` seconds ``e0`` to the left of a straight path (the x
axis) with the path's heading, then follows a speed reference ramping at 2 m/s^2 to 15 m/s,
through ``NaturalOutputController`` in a Python loop (as examples/own_loop.py), 20 s in all.
For each offset: the largest |e_y| [m], |e_y| at the end [m] and the largest applied steer
[rad] (or when the car left the path: |e_y| > 5 m), for

- ``steer_min_speed`` 0 (the steer law runs at every speed) and 1 m/s (the default: below it
  the steer applied last is held);
- ``correction_max`` inf (no bound) and 4 m/s^2 (the default).

Run as a script (about half a minute)::

    python benchmarks/pull_away.py

Nothing here is a test; the figures are in benchmarks/README.md, "Pulling away".
"""

from __future__ import annotations

import math
import platform
import time

import numpy as np

import flatfree as ff
from flatfree.actuators import actuate_step, actuator_state
from flatfree.models.tendof import TenDoF

OFFSETS = (0.0, 0.05, 0.3, 1.0)  # [m]
STAND_S = 1.0  # [s] standing before the speed reference ramps
RAMP = 2.0  # [m/s^2]
V_END = 15.0  # [m/s]
SECONDS = 20.0
LEFT_M = 5.0  # [m] |e_y| beyond this: the car left the path


def speed_reference(t: float, stand_s: float = STAND_S) -> tuple[float, float]:
    """(vx_ref [m/s], ax_ref [m/s^2]) at time ``t`` [s]: 0 while standing, then the ramp."""
    if t < stand_s:
        return 0.0, 0.0
    v = RAMP * (t - stand_s)
    return (V_END, 0.0) if v >= V_END else (v, RAMP)


def run(settings: ff.MfcNaturalSettings, e0: float, *, stand_s: float = STAND_S,
        seconds: float = SECONDS) -> tuple[float, float, float, float]:
    """(max |e_y| [m], |e_y| at the end [m], max |applied steer| [rad], the time the car left
    the path [s] or inf) of one start ``e0`` [m] left of the x axis at a standstill."""
    car = ff.load_vehicle("peugeot406")
    plant = TenDoF(car)
    dt = 0.001
    x = plant.initial_state(0.0, x=0.0, y=e0, psi=0.0)
    act = ff.ActuatorParams.from_vehicle(car)
    ctrl = ff.NaturalOutputController(dt=dt, actuators=act, settings=settings)
    ctrl.reset()
    act_p, act_s = act.to_array(dt), actuator_state(act, dt)
    u = np.array([0.0, 0.0, 1.0, 1.0, 1.0, 1.0])
    worst, steer_max = 0.0, 0.0
    for k in range(round(seconds / dt)):
        vx_ref, ax_ref = speed_reference(k * dt, stand_s)
        torque, steer = ctrl.step(vx=float(x[3]), r=float(x[5]), e_y=float(x[1]), kappa=0.0,
                                  vx_ref=vx_ref, ax_ref=ax_ref)
        u[0], u[1] = actuate_step(torque, steer, x[3], act_p, act_s)
        x = plant.step(x, u, dt)
        steer_max = max(steer_max, abs(float(u[1])))
        if not (abs(x[1]) <= LEFT_M):  # NaN too
            return math.inf, math.inf, steer_max, (k + 1) * dt
        worst = max(worst, abs(float(x[1])))
    return worst, abs(float(x[1])), steer_max, math.inf


def main() -> None:
    print(f"machine: {platform.machine()}, python {platform.python_version()}, "
          f"{time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}")
    print(f"peugeot406, 10DoF, noise-free, standing {STAND_S:g} s then {RAMP:g} m/s^2 to "
          f"{V_END:g} m/s on a straight path, {SECONDS:g} s; max |e_y| [m] / |e_y| at the end "
          f"[m] / max |steer| [rad] for the offsets {', '.join(f'{e:g}' for e in OFFSETS)} m")
    for vmin in (0.0, 1.0):
        for cmax in (math.inf, 4.0):
            s = ff.MfcNaturalSettings(steer_min_speed=vmin, correction_max=cmax)
            cells = []
            for e0 in OFFSETS:
                worst, end, steer, left = run(s, e0)
                cells.append(f"left at {left:.1f} s (steer {steer:.3f})" if left < math.inf
                             else f"{worst:.3f} / {end:.4f} / {steer:.3f}")
            print(f"  steer_min_speed {vmin:g}, correction_max {cmax:g}:  " + "   ".join(cells),
                  flush=True)


if __name__ == "__main__":
    main()
