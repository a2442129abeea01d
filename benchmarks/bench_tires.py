"""Tyre kernels: nanoseconds per call inside a compiled loop (best of 5 repetitions).

The 10DoF model evaluates the combined-slip Magic Formula for four tyres at each of the four
RK4 stages of a plant step: as four scalar ``mf_combined`` calls (the reference path) or as
one ``mf_combined4`` call (four SIMD lanes, the default). Their cost bounds the open-loop
real-time factor. Also timed: the vectorisable elementary functions of ``flatfree._vecmath``
against libm's, in a loop over an array, and whether the 4-lane loop compiles to packed
vector instructions (``inspect_asm``). Results: see README.md in this folder.
"""

from __future__ import annotations

import math
import re

import numpy as np
from numba import njit

from flatfree import _vecmath as vm
from flatfree import load_tire, tires
from flatfree._timing import best_time
from flatfree.tires import mf_combined, mf_combined4, mf_fx0, mf_fy0, slip_angle, slip_ratio

N = 2_000_000
N4 = 500_000
_NTP = tires._NTP


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


# ---- four tyres per call: the same inputs for the scalar and the lane kernel ----
@njit
def _fill(lanes, i):
    for w in range(4):
        lanes[w, 4] = -0.3 + 0.6 * ((i + 250 * w) % 1000) / 1000.0
        lanes[w, 3] = -0.2 + 0.4 * ((i + 97 * w) % 977) / 977.0
        lanes[w, 0] = 2000.0 + ((i + w) % 613)


@njit
def _loop4_empty(n, lanes, tpf, tpr):
    s = 0.0
    for i in range(n):
        _fill(lanes, i)
        s += lanes[0, 4] + lanes[3, 3]
    return s


@njit
def _loop4_scalar(n, lanes, tpf, tpr):
    s = 0.0
    for i in range(n):
        _fill(lanes, i)
        for w in range(4):
            fx, fy = mf_combined(lanes[w, 4], lanes[w, 3], lanes[w, 0], lanes[w, 5],
                                 tpf if w < 2 else tpr)
            s += fx + fy
    return s


@njit
def _loop4_lanes(n, lanes, tpf, tpr):
    s = 0.0
    for i in range(n):
        _fill(lanes, i)
        mf_combined4(lanes, tpf, tpr)
        s += lanes[0, 1] + lanes[1, 2] + lanes[2, 1] + lanes[3, 2]
    return s


# ---- elementary functions over an array ----
def _array_loop(fn):
    @njit
    def run(x, out):
        for i in range(x.size):
            out[i] = fn(x[i])

    return run


def _best(f, n, *args) -> float:
    """ns per call of a compiled loop ``f(n, *args)`` running ``n`` calls."""
    return best_time(f, n, *args) / n * 1e9


def _best_array(f, x, out) -> float:
    """ns per element of ``f(x, out)``."""
    return best_time(f, x, out) / x.size * 1e9


def vectorisation_report() -> None:
    """Count packed and scalar double-precision arithmetic in the compiled 4-lane loop."""

    @njit(error_model="numpy")
    def lanes(d, tpf, tpr):
        tires._mf_lanes_loop(d, vm.as_tuple(tpf, _NTP), vm.as_tuple(tpr, _NTP))

    d = np.zeros((4, 6))
    d[:, 0] = 3000.0
    d[:, 5] = 1.0
    tp = load_tire("pacejka2006_205_60R15").to_array()
    lanes(d, tp, tp)
    asm = lanes.inspect_asm(lanes.signatures[0])
    ops = r"(?:mul|add|sub|div|sqrt|fmadd\d+|fnmadd\d+|fmsub\d+)"
    ymm = len(re.findall(rf"\bv{ops}pd\s+[^\n]*%ymm", asm))
    zmm = len(re.findall(rf"\bv{ops}pd\s+[^\n]*%zmm", asm))
    xmm = len(re.findall(rf"\bv{ops}pd\s+[^\n]*%xmm", asm))
    scalar = len(re.findall(rf"\bv{ops}sd\b", asm))
    libm = re.findall(r"call\w*\s+.*\b(atan|sin|cos|exp)\b", asm)
    print(f"4-lane loop (both variants): packed double arithmetic {ymm} ymm + {zmm} zmm + "
          f"{xmm} xmm instructions, scalar {scalar}, libm calls {len(libm)}")


def main() -> None:
    for name in ("commonroad", "pacejka2006_205_60R15"):
        tp = load_tire(name).to_array()
        for f, label in ((_loop_empty, "loop overhead"), (_loop_pure, "mf_fx0 + mf_fy0"),
                         (_loop_combined, "mf_combined")):
            f(10, tp)  # compile
            print(f"{name:24s} {label:18s} {_best(f, N, tp):7.1f} ns/call")
    _loop_slips(10, 2.0)
    print(f"{'':24s} {'slip_ratio + angle':18s} {_best(_loop_slips, N, 2.0):7.1f} ns/call")

    print("four tyres (fl, fr: first set; rl, rr: second set), ns per 4 tyres, loop subtracted:")
    cr = load_tire("commonroad").to_array()
    pj = load_tire("pacejka2006_205_60R15").to_array()
    for label, tpf, tpr in (("commonroad x2", cr, cr), ("pacejka2006 x2", pj, pj),
                            ("pacejka2006 / commonroad", pj, cr)):
        lanes = np.zeros((4, 6))
        lanes[:, 5] = 1.0
        res = {}
        for f in (_loop4_empty, _loop4_scalar, _loop4_lanes):
            f(10, lanes, tpf, tpr)
            res[f] = _best(f, N4, lanes, tpf, tpr)
        s = res[_loop4_scalar] - res[_loop4_empty]
        v = res[_loop4_lanes] - res[_loop4_empty]
        print(f"   {label:26s} 4 x mf_combined {s:6.1f} ns   mf_combined4 {v:6.1f} ns   "
              f"-> {s / v:4.1f}x")

    print("elementary functions over an array of 10^6 values, ns per value:")
    rng = np.random.default_rng(1)
    for name, dom in (("atan", (-5.0, 5.0)), ("sin", (-3.0, 3.0)), ("cos", (-3.0, 3.0)),
                      ("exp", (-2.0, 2.0))):
        x = rng.uniform(*dom, 1_000_000)
        out = np.empty_like(x)
        fv = _array_loop(getattr(vm, name))
        fm = _array_loop(getattr(math, name))
        fv(x[:10], out[:10])
        fm(x[:10], out[:10])
        print(f"   {name:5s} libm {_best_array(fm, x, out):5.2f}   _vecmath "
              f"{_best_array(fv, x, out):5.2f}")
    vectorisation_report()


def ellipse_exceedance() -> None:
    """Friction-ellipse exceedance of the combined forces on low-friction roads.

    sup over slips of (F_x/(mu_x F_z))^2 + (F_y/(mu_y F_z))^2, on a 401 x 321 grid (kappa in
    [-1, 1], alpha in [-0.8, 0.8] rad, F_z = 4 kN), for flatfree's combined slip (weighting
    functions at slip / mu_scale, tires.mf_combined) and for the plain MF 5.2 weighting (weights
    evaluated at the unscaled slips: G(kappa, alpha) F_0(s; mu), with G read off mf_combined at
    mu_scale = 1 as F / F_0).
    """
    from flatfree.tires import combined, friction_coefficients, fx0, fy0

    k, a = np.meshgrid(np.linspace(-1.0, 1.0, 401), np.linspace(-0.8, 0.8, 321))
    fz = 4000.0
    print("friction-ellipse exceedance sup((Fx/mux Fz)^2 + (Fy/muy Fz)^2), grid, Fz = 4 kN:")
    for name in ("commonroad", "pacejka2006_205_60R15"):
        tire = load_tire(name)
        fx1, fy1 = combined(k, a, fz, tire, 1.0)
        fx01, fy01 = fx0(k, fz, tire, 1.0), fy0(a, fz, tire, 1.0)
        with np.errstate(invalid="ignore", divide="ignore"):
            gx = np.where(fx01 != 0.0, fx1 / fx01, 1.0)
            gy = np.where(fy01 != 0.0, fy1 / fy01, 1.0)
        row = []
        for mu in (1.0, 0.5, 0.1):
            mx, my = friction_coefficients(tire, fz, mu_scale=mu)
            fx, fy = combined(k, a, fz, tire, mu)
            ours = np.max((fx / (mx * fz)) ** 2 + (fy / (my * fz)) ** 2)
            px, py = gx * fx0(k, fz, tire, mu), gy * fy0(a, fz, tire, mu)
            plain = np.max((px / (mx * fz)) ** 2 + (py / (my * fz)) ** 2)
            row.append(f"mu {mu:3.1f}: flatfree {ours:5.3f}, plain MF 5.2 {plain:5.3f}")
        print(f"  {name:24s} " + "; ".join(row))


if __name__ == "__main__":
    main()
    ellipse_exceedance()
