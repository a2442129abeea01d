"""Tyre kernels: nanoseconds per call inside a compiled loop (best of 5 repetitions).

The 10DoF model evaluates ``mf_combined`` four tyres x four RK4 stages per plant step, so its
cost bounds the open-loop real-time factor. Results: see README.md in this folder.
"""

from __future__ import annotations

import time

from numba import njit

from flatfree import load_tire
from flatfree.tires import mf_combined, mf_fx0, mf_fy0, slip_angle, slip_ratio

N = 2_000_000


@njit
def _loop_empty(n, tp):
    s = 0.0
    for i in range(n):
        k = -0.3 + 0.6 * (i % 1000) / 1000.0
        a = -0.2 + 0.4 * (i % 977) / 977.0
        fz = 2000.0 + (i % 613)
        s += k + a * fz
    return s


@njit
def _loop_pure(n, tp):
    s = 0.0
    for i in range(n):
        k = -0.3 + 0.6 * (i % 1000) / 1000.0
        a = -0.2 + 0.4 * (i % 977) / 977.0
        fz = 2000.0 + (i % 613)
        s += mf_fx0(k, fz, 1.0, tp) + mf_fy0(a, fz, 1.0, tp)
    return s


@njit
def _loop_combined(n, tp):
    s = 0.0
    for i in range(n):
        k = -0.3 + 0.6 * (i % 1000) / 1000.0
        a = -0.2 + 0.4 * (i % 977) / 977.0
        fz = 2000.0 + (i % 613)
        fx, fy = mf_combined(k, a, fz, 1.0, tp)
        s += fx + fy
    return s


@njit
def _loop_slips(n, v_min):
    s = 0.0
    for i in range(n):
        v = -0.5 + 10.0 * (i % 1000) / 1000.0
        s += slip_ratio(v + 0.1, v, v_min) + slip_angle(v, 0.3, v_min)
    return s


def _best(f, *args) -> float:
    best = float("inf")
    for _ in range(5):
        t0 = time.perf_counter()
        f(*args)
        best = min(best, time.perf_counter() - t0)
    return best / args[0] * 1e9


def main() -> None:
    for name in ("commonroad", "pacejka2006_205_60R15"):
        tp = load_tire(name).to_array()
        for f, label in ((_loop_empty, "loop overhead"), (_loop_pure, "mf_fx0 + mf_fy0"),
                         (_loop_combined, "mf_combined")):
            f(10, tp)  # compile
            print(f"{name:24s} {label:18s} {_best(f, N, tp):7.1f} ns/call")
    _loop_slips(10, 2.0)
    print(f"{'':24s} {'slip_ratio + angle':18s} {_best(_loop_slips, N, 2.0):7.1f} ns/call")


if __name__ == "__main__":
    main()
