"""Starting off the path: how far from its path the natural-output controller comes back from.

The closed-loop engine starts every run on its reference; a car in a user's loop may not (a
start beside the line, a re-engagement after a fault). Here a preset (10DoF, noise-free; the
peugeot406 unless ``--vehicle``) drives a straight path, the x axis, at a constant speed
reference, starting ``e0`` to its left with the path's heading, through
``NaturalOutputController`` in a Python loop (as examples/own_loop.py), for 25 s, with the
settings tuned for the car (``flatfree.scenarios.natural_settings``). For each speed and
offset: the largest tracking error |e_y - e_y_ref| after the first second and |e_y| at 6 s
[m], and the settling time [s], the last time |e_y - e_y_ref| is above 1 cm (">25" if it still
is at the end), for

- the paper's design (``PAPER_DESIGN``: constant gains at wn 4 rad/s, no yaw damper, no
  bound, no low-speed hold; the peugeot406 only);
- ``correction_max`` = inf: the default settings without the bound;
- ``correction_max`` = 2, 3, 4 (the default), 6 m/s^2 (the iPD's proportional correction kp e
  bounded);
- the defaults without the bound, with a reference that starts at the car and merges into
  the path in ``T`` = 3 s (a quintic in time: e_y_ref = e0 phi(t), phi from 1 to 0 with zero
  slope and curvature at both ends).

Run as a script (about three minutes a car)::

    python benchmarks/initial_offset.py [--vehicle dallara_av21] [--speeds 10,20,40,60]

Nothing here is a test; the figures are in benchmarks/README.md, "Starting off the path".
"""

from __future__ import annotations

import argparse
import math
import platform
import time

import numpy as np

import flatfree as ff
from flatfree.actuators import actuate_step, actuator_state
from flatfree.models.tendof import TenDoF
from flatfree.scenarios import natural_settings

SPEEDS = (5.0, 10.0, 20.0, 40.0)  # [m/s]
OFFSETS = (0.05, 0.1, 0.3, 1.0, 3.0)  # [m]
SECONDS = 25.0
T_CHECK = 6.0  # [s] the |e_y| reported
SETTLED_M = 0.01  # [m] the settling band
MERGE_S = 3.0
CORRECTION_MAX = (2.0, 3.0, 4.0, 6.0)  # [m/s^2]
#: the paper's natural-output design (flatfree.scenarios.NATURAL_SETTINGS' docstring)
PAPER_DESIGN = {"yaw_damping": 0.0, "wn_lat": 4.0, "wn_lat_speed": 0.0,
                "correction_max": math.inf, "steer_min_speed": 0.0}


def merge(t: float, length: float) -> tuple[float, float, float]:
    """phi(t), phi'(t), phi''(t): 1 at t = 0 to 0 at t = ``length`` [s], a quintic with zero
    slope and curvature at both ends; 0 after."""
    if t >= length:
        return 0.0, 0.0, 0.0
    x = t / length
    phi = 1.0 - x**3 * (10.0 - 15.0 * x + 6.0 * x * x)
    dphi = -30.0 * x * x * (1.0 - x) ** 2 / length
    ddphi = -60.0 * x * (1.0 - x) * (1.0 - 2.0 * x) / length**2
    return phi, dphi, ddphi


def run(settings: ff.MfcNaturalSettings, v0: float, e0: float,
        merge_s: float | None = None, *, vehicle: str = "peugeot406",
        seconds: float = SECONDS) -> tuple[float, float, float]:
    """(max |e_y - e_y_ref| after 1 s [m], |e_y| at :data:`T_CHECK` [m], settling time [s]:
    the last time |e_y - e_y_ref| > :data:`SETTLED_M`, inf if at the end) of one start ``e0``
    [m] left of the x axis at ``v0`` [m/s]."""
    car = ff.load_vehicle(vehicle)
    plant = TenDoF(car)
    dt = 0.001
    x = plant.initial_state(v0, x=0.0, y=e0, psi=0.0)
    act = ff.ActuatorParams.from_vehicle(car)
    ctrl = ff.NaturalOutputController(dt=dt, actuators=act, settings=settings)
    ctrl.reset()
    act_p, act_s = act.to_array(dt), actuator_state(act, dt)
    u = np.array([0.0, 0.0, 1.0, 1.0, 1.0, 1.0])
    worst, at_check, settle = 0.0, math.inf, 0.0
    k_check = round(T_CHECK / dt)
    for k in range(round(seconds / dt)):
        phi = (0.0, 0.0, 0.0) if merge_s is None else merge(k * dt, merge_s)
        torque, steer = ctrl.step(vx=float(x[3]), r=float(x[5]), e_y=float(x[1]), kappa=0.0,
                                  vx_ref=v0, e_y_ref=e0 * phi[0], e_y_ref_dot=e0 * phi[1],
                                  e_y_ref_ddot=e0 * phi[2])
        u[0], u[1] = actuate_step(torque, steer, x[3], act_p, act_s)
        x = plant.step(x, u, dt)
        if not math.isfinite(x[1]):
            return math.inf, math.inf, math.inf
        err = abs(float(x[1]) - e0 * phi[0])
        if k * dt >= 1.0:
            worst = max(worst, err)
        if err > SETTLED_M:
            settle = (k + 1) * dt
        if k + 1 == k_check:
            at_check = abs(float(x[1]))
    return worst, at_check, math.inf if settle >= seconds else settle


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--vehicle", default="peugeot406", help="a bundled preset")
    ap.add_argument("--speeds", default=",".join(f"{v:g}" for v in SPEEDS),
                    help="comma-separated speeds [m/s]")
    args = ap.parse_args()
    speeds = [float(v) for v in args.speeds.split(",")]
    base = natural_settings(args.vehicle)
    print(f"machine: {platform.machine()}, python {platform.python_version()}, "
          f"{time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}")
    print(f"{args.vehicle} (settings {base}), 10DoF, noise-free, a straight path; max |e_y - "
          f"e_y_ref| after 1 s / |e_y| at {T_CHECK:g} s [m] / settled within "
          f"{100 * SETTLED_M:g} cm [s] for the offsets {', '.join(f'{e:g}' for e in OFFSETS)} m")
    default = ff.MfcNaturalSettings(**base).correction_max

    def settings(c: float) -> ff.MfcNaturalSettings:
        return ff.MfcNaturalSettings(**{**base, "correction_max": c})

    variants = []
    if args.vehicle == "peugeot406":
        variants += [("the paper's design", ff.MfcNaturalSettings(**PAPER_DESIGN), None)]
    variants += [("correction_max = inf (the defaults unbounded)", settings(math.inf), None)]
    variants += [(f"correction_max = {c:g}" + (" (the default)" if c == default else ""),
                  settings(c), None) for c in CORRECTION_MAX]
    variants += [(f"unbounded, merging in {MERGE_S:g} s", settings(math.inf), MERGE_S)]
    for label, s, merge_s in variants:
        print(label)
        for v0 in speeds:
            cells = [run(s, v0, e0, merge_s, vehicle=args.vehicle) for e0 in OFFSETS]
            print(f"  {v0:4.0f} m/s  " + "  ".join(
                f"{a:7.3f} / {b:6.3f} / " + (f"{c:4.1f}" if c < SECONDS else f">{SECONDS:g}")
                for a, b, c in cells), flush=True)


if __name__ == "__main__":
    main()
