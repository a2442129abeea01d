"""``python -m flatfree.demo``: a 10DoF step-steer maneuver and its steady-state figures.

The peugeot406 preset drives at 20 m/s (a feed-forward wheel torque balances drag and rolling
resistance), the road wheels are steered by a step at t = 0.5 s to the angle that the linear
bicycle formula says gives 3 m/s^2, and the compiled 10DoF model (RK4, 1 ms) runs for 5 s.
The steady state (mean of the last 0.5 s) is printed next to the linear single-track formulas:

* yaw rate ``r = v delta / (L + K_us v^2)`` and ``a_y = v r``;
* sideslip ``beta = l_r / R - m l_f v^2 / (L C_r R)``, ``R = v / r``;
* roll ``phi = m_s h' a_y / (K_phi - m_s g h')``;
* understeer gradient ``K_us = (m / L)(l_r / C_f - l_f / C_r)`` against the measured
  ``(delta - L / R) / a_y``,

with ``C_f, C_r`` the tyres' cornering stiffness at static load (VEHICLE_MODEL.md 5.4, 5.5).
The first run compiles the numba kernels (a few seconds); later runs use the on-disk cache.

References
----------
[VM] docs/VEHICLE_MODEL.md, sections 1 and 5.
[Raj] R. Rajamani, Vehicle Dynamics and Control, 2nd ed., 2012, Ch. 3.
"""

from __future__ import annotations

import argparse
import math
import time

import numpy as np

from flatfree.models.tendof import MP, TenDoF, TenDoFState
from flatfree.tires import cornering_stiffness
from flatfree.units import G, rad_to_deg
from flatfree.vehicles import load_vehicle

__all__ = ["main", "step_steer"]


def step_steer(
    vehicle: str = "peugeot406", speed: float = 20.0, ay_target: float = 3.0,
    duration: float = 5.0, dt: float = 1e-3,
) -> dict[str, tuple[float, float]]:
    """Run the step steer and return ``{quantity: (10DoF value, linear value)}`` in SI units.

    Keys: ``speed`` [m/s], ``delta`` [rad], ``yaw_rate`` [rad/s], ``ay`` [m/s^2], ``sideslip``
    [rad], ``roll`` [rad], ``understeer`` [rad/(m/s^2)], ``wall_time`` [s] (the simulation
    call), ``sim_time`` [s] (simulated) and ``warm_up`` [s] (compiling the kernels, or loading
    them from numba's cache);
    both entries of these two pairs are the same number.
    """
    vp = load_vehicle(vehicle)
    model = TenDoF(vp)
    wb, m = vp.wheelbase, vp.mass
    fzf, fzr = vp.static_axle_loads
    cf = 2.0 * cornering_stiffness(vp.tire_front, 0.5 * fzf)  # per axle [N/rad]
    cr = 2.0 * cornering_stiffness(vp.tire_rear, 0.5 * fzr)
    k_us = m / wb * (vp.lr / cf - vp.lf / cr)  # [Raj] Ch. 3
    delta = ay_target * (wb + k_us * speed**2) / speed**2
    n = int(round(duration / dt))
    n_step = int(round(0.5 / dt))
    cruise = vp.wheel_radius * (0.5 * vp.air_density * vp.drag_area * speed**2
                                + vp.rolling_resistance * m * G)
    steer = np.where(np.arange(n) < n_step, 0.0, delta)
    u = model.inputs(cruise, steer)
    t0 = time.perf_counter()
    model.simulate(model.initial_state(speed), u[:1], dt)  # compile, or load the numba cache
    t1 = time.perf_counter()
    xs = model.simulate(model.initial_state(speed), u, dt)
    wall = time.perf_counter() - t1
    last = slice(n - int(round(0.5 / dt)), n)
    d = model.diagnostics(xs[1:][last], u[last])
    s = TenDoFState
    v = float(np.mean(xs[1:][last, s.vx]))
    r = float(np.mean(xs[1:][last, s.r]))
    ay = float(np.mean(d["ay"]))
    beta = float(np.mean(np.arctan2(xs[1:][last, s.vy], xs[1:][last, s.vx])))
    phi = float(np.mean(xs[1:][last, s.roll]))
    # linear references at the simulated speed
    r_lin = v * delta / (wb + k_us * v**2)
    ay_lin = v * r_lin
    radius_lin = v / r_lin
    beta_lin = vp.lr / radius_lin - m * vp.lf * v**2 / (wb * cr * radius_lin)
    p = model.params
    k_phi = (vp.spring_front * vp.track_front**2 / 2 + vp.arb_front
             + vp.spring_rear * vp.track_rear**2 / 2 + vp.arb_rear)
    ms_h = vp.sprung_mass * p[MP.h_roll]
    phi_lin = ms_h * ay_lin / (k_phi - ms_h * G)  # [VM] 5.4
    us_meas = (delta - wb * r / v) / ay
    return {
        "speed": (v, v),
        "delta": (delta, delta),
        "yaw_rate": (r, r_lin),
        "ay": (ay, ay_lin),
        "sideslip": (beta, beta_lin),
        "roll": (phi, phi_lin),
        "understeer": (us_meas, k_us),
        "wall_time": (wall, wall),
        "warm_up": (t1 - t0, t1 - t0),
        "sim_time": (duration, duration),
    }


def main(argv: list[str] | None = None) -> int:
    """Command line entry point: print the step-steer table."""
    ap = argparse.ArgumentParser(prog="python -m flatfree.demo",
                                 description=__doc__.split("\n")[0])
    ap.add_argument("--vehicle", default="peugeot406", help="preset name (default peugeot406)")
    ap.add_argument("--speed", type=float, default=20.0, help="speed [m/s] (default 20)")
    ap.add_argument("--ay", type=float, default=3.0,
                    help="target lateral acceleration of the linear formula [m/s^2] (default 3)")
    args = ap.parse_args(argv)
    res = step_steer(args.vehicle, args.speed, args.ay)
    deg = rad_to_deg(1.0)
    rows = [
        ("yaw rate", "deg/s", deg, "yaw_rate"),
        ("lateral acceleration", "m/s^2", 1.0, "ay"),
        ("sideslip at the CoG", "deg", deg, "sideslip"),
        ("roll angle", "deg", deg, "roll"),
        ("understeer gradient", "deg/g", deg * G, "understeer"),
    ]
    v, _ = res["speed"]
    delta, _ = res["delta"]
    print(f"flatfree 10DoF step steer: {args.vehicle}, {v:.2f} m/s ({v * 3.6:.1f} km/h), "
          f"road-wheel steer {delta * deg:.3f} deg at t = 0.5 s, RK4 1 ms")
    head = ("steady state (last 0.5 s)", "unit", "10DoF", "linear", "diff")
    print(f"{head[0]:28s} {head[1]:>6s} {head[2]:>9s} {head[3]:>9s} {head[4]:>7s}")
    for label, unit, scale, key in rows:
        a, b = res[key]
        diff = f"{100.0 * (a / b - 1.0):+6.1f}%" if abs(b) > 1e-12 else "     -"
        print(f"{label:28s} {unit:>6s} {a * scale:9.4f} {b * scale:9.4f} {diff:>7s}")
    wall, _ = res["wall_time"]
    sim, _ = res["sim_time"]
    warm, _ = res["warm_up"]
    print(f"simulated {sim:.1f} s in {wall:.3f} s of wall time ({sim / wall:.0f}x real time); "
          f"kernels compiled or loaded from the cache in {warm:.2f} s")
    print("linear: single-track formulas with the tyres' cornering stiffness at static load "
          "(docs/VEHICLE_MODEL.md 5.4-5.5)")
    return 0 if all(math.isfinite(res[k][0]) for k in res) else 1


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
