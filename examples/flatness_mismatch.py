"""Flatness-based tracking with wrong cornering stiffnesses: the paper's Figure 2 on the 3DoF model.

The paper (Section 3.1, Figure 2) shows that its flatness-based controller, good with the nominal
cornering stiffnesses, tracks badly when the controller's model has 0.3 Cf and 0.3 Cr. Here the
plant is the 3DoF model itself (flatfree.models.bicycle3dof, Peugeot 406 preset, pose-extended
so that the path can be drawn), and the reference is *feasible*: the same model driven open loop
by a smooth steer (two sines, up to ~4.5 m/s^2 lateral) and a torque profile around 22 m/s.
Three controllers start on the reference (so that any error is the mismatch's doing; the
tests cover starts off the reference):

* exact model parameters (converges to the reference to rounding),
* 0.3 Cf and 0.3 Cr in the controller's model, y2' from that model (the paper's situation),
* the same mismatch, y2' from the algebraic differentiator (paper eq. (Derivative); window 10)
  and the reference's y2', y2'' from the kinematic d/dt (lf m Vy - Iz r), free of Cf, Cr.

Gains: poles -2, -3 (speed) and -4, -5, -6 (y2). The script prints the worst errors and writes
``flatness_mismatch.png`` next to itself. Note: the controller tracks velocities (Vx and
y2 = lf m Vy - Iz r), not the position; the path error is what the small velocity errors
integrate to.

Output (2026-11-22), max over the 30 s run:

    case                              |e_vy| m/s  |e_r| deg/s  |e_psi| deg  |e_pos| m
    exact parameters                   7e-16       1e-14        3e-14        0.000
    0.3 Cf, 0.3 Cr (model y2')         3.3e-2      0.76         1.23         1.80
    0.3 Cf, 0.3 Cr (algebraic y2')     3.9e-2      0.75         1.29         1.71

Run:  .venv/bin/python examples/flatness_mismatch.py
"""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from flatfree.controllers.flatness_control import (
    FlatnessController,
    FlatnessControlParams,
    flat_reference,
    gains_from_poles,
)
from flatfree.models.bicycle3dof import Bicycle3DoFParams, simulate, vector_field
from flatfree.vehicles import load_vehicle

DT = 0.01  # s, sample time of the controller (and RK4 step of the plant)
T_END = 30.0  # s


def reference(plant: Bicycle3DoFParams):
    """Feasible reference: pose-extended open-loop run under smooth held inputs."""
    n = int(round(T_END / DT))
    t = np.arange(n) * DT
    steer = 0.035 * np.sin(0.45 * t) + 0.015 * np.sin(1.2 * t + 0.5)  # rad
    torque = 400.0 * np.sin(0.25 * t)  # N m
    u = np.column_stack([torque, steer])
    x = simulate(plant, [0.0, 0.0, 0.0, 22.0, 0.0, 0.0], u, DT)[:-1]  # X, Y, psi, vx, vy, r
    xd = np.array([vector_field(plant, x[k, 3:], u[k]) for k in range(n)])  # right derivatives
    return t, x, u, xd


def closed_loop(plant, ctrl: FlatnessController, x0: np.ndarray, n: int):
    """Sampled loop through the Python shell: controller at t_k, plant RK4 over DT."""
    x = np.array(x0, dtype=float)
    xs, us = np.empty((n, 6)), np.empty((n, 2))
    ctrl.reset()
    for k in range(n):
        u = ctrl.step(x[3:], k * DT)
        xs[k], us[k] = x, u
        x = simulate(plant, x, u[None, :], DT)[1]
    return xs, us


def main() -> None:
    plant = Bicycle3DoFParams.from_vehicle(load_vehicle("peugeot406"))
    t, xr, ur, xd = reference(plant)
    gains = gains_from_poles([-2.0, -3.0], [-4.0, -5.0, -6.0])
    cases = {
        "exact parameters": {},
        "0.3 Cf, 0.3 Cr (model y2')": dict(cf_scale=0.3, cr_scale=0.3),
        "0.3 Cf, 0.3 Cr (algebraic y2')": dict(cf_scale=0.3, cr_scale=0.3,
                                              derivative="algebraic", derivative_window=10),
    }
    runs = {}
    print(f"{'case':34s} {'|e_vx|':>9s} {'|e_vy|':>9s} {'|e_r|':>9s} {'|e_psi|':>9s}"
          f" {'|e_pos|':>8s}   (max over the run; m/s, m/s, deg/s, deg, m)")
    for name, opts in cases.items():
        fp = FlatnessControlParams(model=plant, gains=gains, dt=DT, **opts)
        # the controller computes its flat-output reference with its own (maybe wrong) model
        # (with a measured y2', the reference y2' is the kinematic d/dt y2_ref: no Cf, Cr in it)
        kin = "kinematic" if fp.derivative == "algebraic" else "model"
        ref = flat_reference(fp.design_model, t, xr[:, 3], xr[:, 4], xr[:, 5],
                             vx_dot=xd[:, 0], vy_dot=xd[:, 1], r_dot=xd[:, 2], y2_dot=kin)
        xs, us = closed_loop(plant, FlatnessController(fp, ref), xr[0], len(t))
        runs[name] = (xs, us)
        e = np.abs(xs - xr)
        pos = np.hypot(xs[:, 0] - xr[:, 0], xs[:, 1] - xr[:, 1])
        print(f"{name:34s} {e[:, 3].max():9.2e} {e[:, 4].max():9.2e} "
              f"{np.degrees(e[:, 5].max()):9.2e} {np.degrees(e[:, 2].max()):9.2e} "
              f"{pos.max():8.3f}")

    fig, ax = plt.subplots(2, 2, figsize=(11, 7.5), constrained_layout=True)
    ax[0, 0].plot(xr[:, 0], xr[:, 1], color="0.6", lw=4, label="reference")
    for name, (xs, _us) in runs.items():
        ax[0, 0].plot(xs[:, 0], xs[:, 1], lw=1.2, label=name)
    ax[0, 0].set(xlabel="X [m]", ylabel="Y [m]", title="path (pose from the 3DoF velocities)")
    ax[0, 0].legend(fontsize=8)
    for name, (xs, _us) in runs.items():
        ax[0, 1].semilogy(t, np.maximum(np.abs(xs[:, 4] - xr[:, 4]), 1e-16), lw=1, label=name)
        ax[1, 0].plot(t, np.hypot(xs[:, 0] - xr[:, 0], xs[:, 1] - xr[:, 1]), lw=1, label=name)
    ax[0, 1].set(xlabel="t [s]", ylabel="|Vy - Vy_ref| [m/s]", title="lateral speed error")
    ax[1, 0].set(xlabel="t [s]", ylabel="[m]", title="position error |(X, Y) - ref|")
    ax[1, 1].plot(t, np.degrees(ur[:, 1]), color="0.6", lw=4, label="reference input")
    for name, (_xs, us) in runs.items():
        ax[1, 1].plot(t, np.degrees(us[:, 1]), lw=1, label=name)
    ax[1, 1].set(xlabel="t [s]", ylabel="delta [deg]", title="steer command",
                 ylim=(-4.0, 4.0))
    for a in ax.flat[1:]:
        a.grid(alpha=0.3)
    ax[1, 1].legend(fontsize=8)
    fig.suptitle("Flatness-based control of the 3DoF model (Peugeot 406), "
                 "nominal vs 0.3 Cf, 0.3 Cr (paper Fig. 2)")
    out = Path(__file__).with_suffix(".png")
    fig.savefig(out, dpi=110)
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
