"""The natural-output controller in your own loop: reset() / step() (ROS 2, CARLA, a real car).

Here "your car" is flatfree's 10DoF model stepped from Python one millisecond at a time; replace
the three marked lines with your simulator's or your car's state estimate and actuator
commands. Per control period you hand the controller the measured speed, yaw rate, lateral
deviation from your path and the path's curvature (and, for the inertial-unit variant, the
deviation's second derivative from your accelerometers), and apply the torque and steer it
returns until the next call. Compares the paper's algebraic estimator with the inertial-unit
one (``estimator_lat = "imu"``) over the first seconds of Norisring. Usage::

    python examples/own_loop.py [seconds]
"""

from __future__ import annotations

import math
import sys

import numpy as np

import flatfree as ff
from flatfree.actuators import actuate_step, actuator_state
from flatfree.models.tendof import TenDoF
from flatfree.scenarios import natural_settings
from flatfree.tracks import frenet_init, frenet_project, lateral_deviation_acceleration


def run(settings: ff.MfcNaturalSettings, seconds: float, seed: int = 0) -> dict[str, float]:
    """Drive ``seconds`` of Norisring with 1 mm of position noise (and 0.05 m/s^2 on the
    accelerations): the max |e_y| after the first second [m] and the final speed [m/s]."""
    car = ff.load_vehicle("peugeot406")
    ref = ff.make_reference(ff.load_track("Norisring"), ff.SpeedLimits(), dt=0.01)
    g, closed = ref.path.geometry, ref.path.closed
    plant = TenDoF(car)
    dt = 0.001
    vx0 = float(ref["vx"][0])
    kappa0 = float(ref["kappa"][0])
    x = plant.initial_state(vx0, r=vx0 * kappa0, x=float(ref["x"][0]), y=float(ref["y"][0]),
                            psi=float(ref["psi"][0]))
    steer0 = car.wheelbase * kappa0  # the actuator's position when the controller starts
    act = ff.ActuatorParams.from_vehicle(car)
    ctrl = ff.NaturalOutputController(dt=dt, actuators=act, settings=settings)
    ctrl.reset(steer0=steer0)
    # your car's actuators (here flatfree's model of them: steer rate and range, torque limits,
    # power cap); they, not the controller, limit what reaches the wheels
    act_p, act_s = act.to_array(dt), actuator_state(act, dt, steer0=steer0)
    rng = np.random.default_rng(seed)
    seg = frenet_init(g, closed, x[0], x[1], x[2])
    prev = x[3:6].copy()
    u = np.array([0.0, steer0, 1.0, 1.0, 1.0, 1.0])  # torque, steer, road friction per wheel
    worst = 0.0
    for k in range(round(seconds / dt)):
        # --- your state estimate (here: the model's state, 1 mm noise on the position) ---
        px, py = x[0] + 1e-3 * rng.standard_normal(), x[1] + 1e-3 * rng.standard_normal()
        vx, vy, r = x[3], x[4], x[5]
        # your accelerometers (here: from the model, with 0.05 m/s^2 of noise)
        ax = (vx - prev[0]) / dt - r * vy + 0.05 * rng.standard_normal()
        ay = (vy - prev[1]) / dt + r * vx + 0.05 * rng.standard_normal()
        prev = x[3:6].copy()
        s, e_y, e_psi, kappa, seg = frenet_project(g, closed, px, py, x[2], seg)
        e_y_ddot = lateral_deviation_acceleration(ax, ay, vx, vy, e_y, e_psi, kappa)
        # the references at the car's arc length: the speed and its time derivative (the iP's
        # feedforward: without it the speed lags the profile by ax_ref / kp_lon, 3 m/s at a
        # 6 m/s^2 braking, and the car enters the corners too fast)
        vx_ref = float(np.interp(s, ref["s_path"], ref["vx"]))
        ax_ref = float(np.interp(s, ref["s_path"], ref["ax"]))
        if k == 0:
            e_y_ddot = math.nan  # no previous velocity yet: the controller falls back
        torque, steer = ctrl.step(vx=vx, r=r, e_y=e_y, kappa=kappa, vx_ref=vx_ref,
                                  ax_ref=ax_ref, e_y_ddot=e_y_ddot)
        # --- your actuators (here: the model's inputs, held for one period) ---
        u[0], u[1] = actuate_step(torque, steer, vx, act_p, act_s)
        x = plant.step(x, u, dt)
        _, true_e_y, _, _, _ = frenet_project(g, closed, x[0], x[1], x[2], seg)
        worst = max(worst, abs(true_e_y)) if k * dt > 1.0 else worst
    return {"max_lateral_m": worst, "vx_end": float(x[3])}


def main(seconds: float = 10.0) -> None:
    for name, settings in (
            # the named scenarios' tunings for the peugeot406 (`paper`, `paper-imu`)
            ("algebraic (the paper's)", ff.MfcNaturalSettings(**natural_settings("peugeot406"))),
            ("imu", ff.MfcNaturalSettings(**natural_settings("peugeot406", imu=True)))):
        out = run(settings, seconds)
        print(f"{name:24s} max |e_y| after 1 s: {100 * out['max_lateral_m']:.2f} cm "
              f"(speed at the end {out['vx_end']:.1f} m/s)")


if __name__ == "__main__":
    main(float(sys.argv[1]) if len(sys.argv) > 1 else 10.0)
