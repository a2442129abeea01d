"""Benchmark: the flatness-based tracking controller (issue 5), one compiled step.

(a) ns per flatness_step call inside a compiled loop (a closed loop on the 3DoF model with one
RK4 step per sample; the loop's cost with a trivial P law instead of the controller is measured
separately and subtracted), for derivative="model" and "algebraic" (window 10);
(b) us per FlatnessController.step call from Python (reference interpolation included).
Timings are the best of several repeats (noise on a shared machine only ever adds time).

    .venv/bin/python benchmarks/bench_flatness_control.py
"""

from __future__ import annotations

import datetime
import math
import platform

import numba
import numpy as np

from flatfree._timing import best_time
from flatfree.controllers.flatness_control import (
    FlatnessController,
    FlatnessControlParams,
    flat_reference,
    flatness_reset,
    flatness_step,
    gains_from_poles,
    make_state,
)
from flatfree.models.bicycle3dof import Bicycle3DoFParams, rk4_step_into

N_COMPILED = 1_000_000
N_SHELL = 50_000
REPEATS = 5
DT = 0.01

P = Bicycle3DoFParams(m=1500.0, iz=2620.0, lf=1.08, lr=1.62, cf=97_700.0, cr=73_800.0,
                      wheel_radius=0.31, wheel_inertia_front=0.0, wheel_inertia_rear=0.0)


@numba.njit  # not cached: it inlines flatfree kernels (flatfree._jitcache)
def _loop(p, s, plant, n, dt, with_controller):
    flatness_reset(p, s)
    x = np.array([20.5, 0.05, 0.0])
    u = np.zeros(2)
    acc = 0.0
    lf, m, iz = plant[2], plant[0], plant[1]
    for k in range(n):
        tk = k * dt
        # a smooth curved reference at 20 m/s (not exactly feasible; fine for timing)
        r = 0.1 * math.sin(0.3 * tk)
        rd = 0.03 * math.cos(0.3 * tk)
        y2 = lf * m * 0.02 * r - iz * r
        if with_controller:
            tw, de = flatness_step(p, s, x[0], x[1], x[2], 20.0, 0.0, y2, 0.0, 0.0, dt,
                                   math.nan, math.nan)
        else:
            tw = 400.0 * (20.0 - x[0])
            de = 0.5 * (r - x[2]) + rd
        u[0] = tw
        u[1] = de
        rk4_step_into(x, u, dt, plant, 0.0, 0.0, False, x)
        acc += abs(x[2] - r)
    return acc / n


def _best(fn, *args):
    return best_time(fn, *args, repeats=REPEATS)


def main() -> None:
    print(f"flatness controller benchmark, {datetime.date.today()}, "
          f"{platform.processor() or platform.machine()}, numba {numba.__version__}")
    gains = gains_from_poles([-2.0, -3.0], [-4.0, -5.0, -6.0])
    plant = P.to_array()
    for opts in ({}, dict(derivative="algebraic", derivative_window=10)):
        fp = FlatnessControlParams(model=P, gains=gains, dt=DT, **opts)
        p = fp.to_array()
        s = make_state(p)
        _loop(p, s, plant, 1000, DT, True)
        _loop(p, s, plant, 1000, DT, False)
        t_with = _best(_loop, p, s, plant, N_COMPILED, DT, True)
        t_without = _best(_loop, p, s, plant, N_COMPILED, DT, False)
        name = fp.derivative + (f" (window {fp.derivative_window})" if opts else "")
        print(f"  compiled step, y2' {name:22s}: {(t_with - t_without) / N_COMPILED * 1e9:6.1f} "
              f"ns/step  (loop with {t_with / N_COMPILED * 1e9:.1f}, without "
              f"{t_without / N_COMPILED * 1e9:.1f} ns)")
    n = 200
    t = np.arange(n) * DT
    z = np.zeros(n)
    ref = flat_reference(P, t, np.full(n, 20.0), z, z, vx_dot=z, vy_dot=z, r_dot=z)
    ctrl = FlatnessController(FlatnessControlParams(model=P, gains=gains, dt=DT), ref)
    x = np.array([20.5, 0.05, 0.0])

    def shell():
        for k in range(N_SHELL):
            ctrl.step(x, t[k % n])

    shell()
    ts = _best(shell)
    print(f"  Python shell FlatnessController.step: {ts / N_SHELL * 1e6:.2f} us/call")


if __name__ == "__main__":
    main()
