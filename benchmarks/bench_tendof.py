"""Speed of the 10DoF validation model, side by side with CommonRoad's multi-body model.

Run as a script (``python benchmarks/bench_tendof.py``); it prints every figure recorded in
``benchmarks/README.md``. Sections:

1. a 60 s open-loop 10DoF maneuver at dt = 1 ms for each preset, after JIT warm-up (best of
   5 runs): real-time factor and time per step (target >= 1000x real time on one core), for
   the default path (tyres in SIMD lanes) and the scalar reference path (tire_lanes=False);
2. where the time goes: the 4-tyre Magic Formula (flatfree.tires.mf_combined4) and four scalar
   mf_combined calls, timed in compiled loops over the loads and slips of that maneuver,
   against the whole right-hand side;
3. a second process start with a warm numba cache: time from the interpreter's first line to
   the first completed RK4 step (target < 2 s), measured with subprocesses;
4. CommonRoad's 29-state MB model (pure Python) on a 5 s maneuver with fixed-step RK4 at 1 ms
   and with scipy's solve_ivp RK45 (default tolerances), and flatfree's 10DoF on the same
   maneuver through both doors (compiled RK4, and solve_ivp over the Python-callable rhs);
5. the stable RK4 step of each preset (linearised, flatfree.models.tendof.stable_step).

The machine has 2 cores shared with other jobs: timings are noisy; the best of several runs
is reported. Nothing here is a test.
"""

from __future__ import annotations

import math
import os
import platform
import statistics
import subprocess
import sys
import time

import numpy as np
from numba import njit
from scipy.integrate import solve_ivp

from flatfree._timing import best_time
from flatfree.models.tendof import TenDoF, TenDoFOptions, TenDoFState, stable_step
from flatfree.tires import mf_combined, mf_combined4
from flatfree.units import G
from flatfree.vehicles import load_vehicle

PRESETS = ("peugeot406", "bmw320i", "dallara_av21")
S = TenDoFState


def _best(fn, repeat: int = 5) -> float:
    return best_time(fn, repeats=repeat)


def maneuver_60s(model: TenDoF, dt: float = 1e-3):
    """60 s from 10 m/s: accelerate, slalom, cruise in a turn, brake in a turn, coast.

    Torques stay inside the tyres' traction (no wheel spin); steer inside +-0.04 rad.
    Returns (x0, u) with u of shape (60000, 6).
    """
    vp = model.vehicle
    n = int(round(60.0 / dt))
    t = np.arange(n) * dt
    mr = vp.mass * vp.wheel_radius
    tw = np.select(
        [t < 10.0, t < 30.0, t < 40.0, t < 45.0],
        [1.5 * mr, 0.3 * mr, 0.4 * mr, -3.0 * mr],
        default=0.0,
    )
    delta = np.select(
        [t < 10.0, t < 30.0, t < 45.0],
        [0.0, 0.03 * np.sin(2.0 * np.pi * 0.5 * (t - 10.0)), 0.02],
        default=0.01 * np.sin(2.0 * np.pi * 0.2 * t),
    )
    return model.initial_state(10.0), model.inputs(tw, delta)


# --------------------------------------------------------------------------------------------
# 1 and 2: throughput and where the time goes
# --------------------------------------------------------------------------------------------
@njit  # not cached: it inlines flatfree kernels (flatfree._jitcache)
def _mf4_loop(diag_rows, mu, tp_f, tp_r):
    """mf_combined4 over recorded per-wheel (F_z, alpha, kappa) of a run, in the model's layout."""
    lanes = np.zeros((4, 6))
    acc = 0.0
    for k in range(diag_rows.shape[0]):
        for w in range(4):
            lanes[w, 0] = diag_rows[k, w, 0]
            lanes[w, 3] = diag_rows[k, w, 3]
            lanes[w, 4] = diag_rows[k, w, 4]
            lanes[w, 5] = mu
        mf_combined4(lanes, tp_f, tp_r)
        acc += lanes[0, 1] + lanes[1, 2] + lanes[2, 1] + lanes[3, 2]
    return acc


@njit  # not cached: it inlines flatfree kernels (flatfree._jitcache)
def _mf_loop(diag_rows, mu, tp_f, tp_r):
    """The same inputs through four scalar mf_combined calls."""
    acc = 0.0
    for k in range(diag_rows.shape[0]):
        for w in range(4):
            fx, fy = mf_combined(diag_rows[k, w, 4], diag_rows[k, w, 3], diag_rows[k, w, 0], mu,
                                 tp_f if w < 2 else tp_r)
            acc += fx + fy
    return acc


@njit  # not cached: it inlines flatfree kernels (flatfree._jitcache)
def _copy_loop(diag_rows, mu, tp_f, tp_r):
    """The loop of _mf4_loop without the tyre call (its overhead)."""
    lanes = np.zeros((4, 6))
    acc = 0.0
    for k in range(diag_rows.shape[0]):
        for w in range(4):
            lanes[w, 0] = diag_rows[k, w, 0]
            lanes[w, 3] = diag_rows[k, w, 3]
            lanes[w, 4] = diag_rows[k, w, 4]
            lanes[w, 5] = mu
        acc += lanes[0, 4] + lanes[1, 3] + lanes[2, 0] + lanes[3, 4]
    return acc


def throughput() -> dict[str, float]:
    print("1. 60 s open-loop 10DoF maneuver, RK4 at dt = 1 ms, one core, after warm-up (best of 5)")
    print("   default (tyres in SIMD lanes) and, in brackets, the scalar reference path "
          "(TenDoFOptions(tire_lanes=False))")
    out = {}
    for name in PRESETS:
        m = TenDoF(load_vehicle(name))
        ref = TenDoF(load_vehicle(name), TenDoFOptions(tire_lanes=False))
        x0, u = maneuver_60s(m)
        xs = np.empty((u.shape[0] + 1, len(S)))
        m.simulate(x0, u, 1e-3, out=xs)  # warm-up (compiles or loads the cache)
        wall_ref = _best(lambda r=ref, x0=x0, u=u, xs=xs: r.simulate(x0, u, 1e-3, out=xs))
        wall = _best(lambda m=m, x0=x0, u=u, xs=xs: m.simulate(x0, u, 1e-3, out=xs))
        rt = 60.0 / wall
        out[name] = rt
        print(f"   {name:13s} {wall * 1e3:7.1f} ms  = {rt:6.0f}x real time, "
              f"{wall / u.shape[0] * 1e6:5.2f} us/step  (reference path: {60.0 / wall_ref:4.0f}x,"
              f" {wall_ref / u.shape[0] * 1e6:4.2f} us/step; v: {xs[:, S.vx].min():.1f}-"
              f"{xs[:, S.vx].max():.1f} m/s)")
        if name == "peugeot406":
            d = m.diagnostics(xs[1:], u)
            rows = np.ascontiguousarray(np.stack([d[k] for k in ("fz", "fx", "fy", "alpha",
                                                                  "kappa", "kappa_plain")], -1))
            for f in (_mf4_loop, _mf_loop, _copy_loop):
                f(rows[:10], 1.0, m.tire_front, m.tire_rear)
            tf, tr = m.tire_front, m.tire_rear
            t_copy = _best(lambda rows=rows, tf=tf, tr=tr: _copy_loop(rows, 1.0, tf, tr))
            t4 = _best(lambda rows=rows, tf=tf, tr=tr: _mf4_loop(rows, 1.0, tf, tr)) - t_copy
            t1 = _best(lambda rows=rows, tf=tf, tr=tr: _mf_loop(rows, 1.0, tf, tr))
            n = rows.shape[0]
            per_rhs = wall / (4 * u.shape[0])
            print("2. where the time goes (peugeot406, inputs of the run above):")
            print(f"   one right-hand side: {per_rhs * 1e9:6.0f} ns (4 per RK4 step)")
            print(f"   one mf_combined4   : {t4 / n * 1e9:6.0f} ns for 4 tyres, timed alone (1 per "
                  f"right-hand side, = {t4 / n / per_rhs:.0%} of it; inside the right-hand side it "
                  f"overlaps with the scalar work); 4 scalar mf_combined: {t1 / n * 1e9:.0f} ns")
            print("   elementary functions per tyre (pacejka2006 set, shifts 0): 8 atan, 2 sin, "
                  "2 cos, 1 exp, 2 sqrt; in the lanes they are polynomials (flatfree._vecmath) "
                  "evaluated for 4 tyres per instruction")
            print("   rest of the right-hand side: 4 slip-angle atan (in the lanes), 4-8 sqrt "
                  "(smooth signs), sincos of psi and delta, sin of roll and pitch (libm)")
            print(f"   => the tyres cost {16 * t4 / n / 4 * 1e6:.2f} us per step with lanes, "
                  f"{16 * t1 / n / 4 * 1e6:.2f} us with scalar calls")
    return out


# --------------------------------------------------------------------------------------------
# 3: second process start with a warm cache
# --------------------------------------------------------------------------------------------
_CHILD = r"""
import time
t0 = time.perf_counter()
import numpy as np
from flatfree.vehicles import load_vehicle
from flatfree.models.tendof import TenDoF
m = TenDoF(load_vehicle("peugeot406"))
x = m.step(m.initial_state(20.0), m.inputs(0.0, 0.01), 1e-3)
t1 = time.perf_counter()
xs = m.simulate(x, m.inputs(0.0, 0.01, n=10), 1e-3)
t2 = time.perf_counter()
print(f"{t1 - t0:.4f} {t2 - t0:.4f}")
"""


def second_start(repeat: int = 5) -> dict[str, float]:
    print("3. second process start (warm numba cache): import + first RK4 step")
    firsts, sims, walls = [], [], []
    for _ in range(repeat):
        t0 = time.perf_counter()
        res = subprocess.run([sys.executable, "-c", _CHILD], capture_output=True, text=True,
                             check=True)
        walls.append(time.perf_counter() - t0)
        a, b = (float(v) for v in res.stdout.split())
        firsts.append(a)
        sims.append(b)
    print(f"   inside the process, first line -> first step done: median "
          f"{statistics.median(firsts):.2f} s (min {min(firsts):.2f}, max {max(firsts):.2f})")
    print(f"   ... -> first simulate() done as well:             median "
          f"{statistics.median(sims):.2f} s")
    print(f"   whole subprocess incl. interpreter start and exit: median "
          f"{statistics.median(walls):.2f} s (min {min(walls):.2f})")
    return {"first_step": statistics.median(firsts), "process": statistics.median(walls)}


# --------------------------------------------------------------------------------------------
# 4: CommonRoad MB side by side
# --------------------------------------------------------------------------------------------
def commonroad_side_by_side(t_end: float = 5.0) -> dict[str, float]:
    from vehiclemodels.init_mb import init_mb
    from vehiclemodels.parameters_vehicle2 import parameters_vehicle2
    from vehiclemodels.vehicle_dynamics_mb import vehicle_dynamics_mb

    print(f"4. {t_end:.0f} s maneuver at 20 m/s (steer 0.03 sin(pi t) rad, 0.5 m/s^2 of drive), "
          "bmw320i / CommonRoad set 2")
    p = parameters_vehicle2()
    dt = 1e-3
    n = int(round(t_end / dt))
    amp, om, acc = 0.03, math.pi, 0.5

    def u_mb(t: float) -> list[float]:
        return [amp * om * math.cos(om * t), acc]  # MB steers with a rate input

    x0 = init_mb([0.0, 0.0, 0.0, 20.0, 0.0, 0.0, 0.0], p)

    def mb_rk4() -> list[float]:
        x = list(x0)
        h2, h6 = 0.5 * dt, dt / 6.0
        for k in range(n):
            u = u_mb(k * dt)
            k1 = vehicle_dynamics_mb(list(x), u, p)
            k2 = vehicle_dynamics_mb([a + h2 * b for a, b in zip(x, k1, strict=True)], u, p)
            k3 = vehicle_dynamics_mb([a + h2 * b for a, b in zip(x, k2, strict=True)], u, p)
            k4 = vehicle_dynamics_mb([a + dt * b for a, b in zip(x, k3, strict=True)], u, p)
            x = [a + h6 * (b + 2.0 * (c + d) + e)
                 for a, b, c, d, e in zip(x, k1, k2, k3, k4, strict=True)]
        return x

    def mb_ivp():
        return solve_ivp(lambda t, x: vehicle_dynamics_mb(list(x), u_mb(t), p), (0.0, t_end),
                         x0, method="RK45")

    res = {}
    w_rk4 = _best(mb_rk4, repeat=2)
    res["mb_rk4"] = t_end / w_rk4
    sol = mb_ivp()
    w_ivp = _best(mb_ivp, repeat=3)
    res["mb_ivp"] = t_end / w_ivp
    print(f"   CommonRoad MB, RK4 1 ms (pure Python)       : {w_rk4:7.3f} s = "
          f"{res['mb_rk4']:7.1f}x real time")
    print(f"   CommonRoad MB, solve_ivp RK45 (defaults)    : {w_ivp:7.3f} s = "
          f"{res['mb_ivp']:7.1f}x real time ({sol.nfev} evaluations)")

    m = TenDoF(load_vehicle("bmw320i"))
    t = np.arange(n) * dt
    tw = acc * m.vehicle.mass * m.vehicle.wheel_radius
    u = m.inputs(tw, amp * np.sin(om * (t + 0.5 * dt)))
    xs0 = m.initial_state(20.0)
    m.simulate(xs0, u)
    w_ff = _best(lambda: m.simulate(xs0, u), repeat=5)
    res["ff_rk4"] = t_end / w_ff

    def ff_ivp():
        fun = m.ivp_rhs(lambda tt: m.inputs(tw, amp * math.sin(om * tt)))
        return solve_ivp(fun, (0.0, t_end), xs0, method="RK45")

    sol2 = ff_ivp()
    w_ffi = _best(ff_ivp, repeat=3)
    res["ff_ivp"] = t_end / w_ffi
    print(f"   flatfree 10DoF, compiled RK4 1 ms           : {w_ff:7.4f} s = "
          f"{res['ff_rk4']:7.0f}x real time")
    print(f"   flatfree 10DoF, solve_ivp RK45 (defaults)   : {w_ffi:7.3f} s = "
          f"{res['ff_ivp']:7.1f}x real time ({sol2.nfev} evaluations; Python-level inputs)")
    return res


# --------------------------------------------------------------------------------------------
# 5: stable steps
# --------------------------------------------------------------------------------------------
def stable_steps() -> dict[str, float]:
    print("5. largest stable RK4 step (linearised at free rolling; brake = 70 % of the preset's "
          "max brake torque; steer 0.05 rad)")
    speeds = (0.0, 0.5, 2.0, 5.0, 20.0, 40.0, 60.0)
    print("   preset         " + " ".join(f"{v:>6.1f}" for v in speeds) + "   [m/s] -> min dt [ms]")
    out = {}
    for name in PRESETS:
        m = TenDoF(load_vehicle(name))
        vp = m.vehicle
        row = []
        for v in speeds:
            x = m.initial_state(v)
            row.append(min(stable_step(m, x, m.inputs(tw, de))[0]
                           for tw, de in ((0.0, 0.0), (-0.7 * vp.max_brake_torque, 0.0),
                                          (0.0, 0.05))))
        out[name] = min(row)
        print(f"   {name:13s}  " + " ".join(f"{1e3 * d:6.2f}" for d in row))
    return out


def main() -> int:
    cpu = "unknown"
    try:
        lscpu = subprocess.run(["lscpu"], capture_output=True, text=True, check=False).stdout
        for line in lscpu.splitlines():
            if line.startswith("Model name"):
                cpu = line.split(":", 1)[1].strip()
    except OSError:
        pass
    print(f"machine: {cpu}, {os.cpu_count()} cores; Python {platform.python_version()}; "
          f"{time.strftime('%Y-%m-%d %H:%M')}; G = {G}")
    throughput()
    second_start()
    commonroad_side_by_side()
    stable_steps()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
