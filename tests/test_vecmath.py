"""Tests of flatfree._vecmath: the vectorisable atan, sin, cos, exp of the SIMD tyre lanes.

Reference values: the C library (``math.*``, correctly rounded to within ~0.5 ulp) on dense
grids and random points, mpmath at 40 digits, and exact identities (odd/even symmetry, special
values). The polynomial coefficients are recomputed from their documented construction
(Chebyshev interpolation with mpmath) and must reproduce every stored literal.
"""

from __future__ import annotations

import math
import platform
import re

import mpmath as mp
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numba import njit

from flatfree import _vecmath as vm


# --------------------------------------------------------------------------------------------
# helpers: compiled loops over arrays (not cached: a test must see the current code)
# --------------------------------------------------------------------------------------------
def _loop(fn):
    @njit
    def run(x, out):
        for i in range(x.size):
            out[i] = fn(x[i])

    return run


_V = {"atan": _loop(vm.atan), "sin": _loop(vm.sin), "cos": _loop(vm.cos), "exp": _loop(vm.exp)}
_M = {"atan": _loop(math.atan), "sin": _loop(math.sin), "cos": _loop(math.cos),
      "exp": _loop(math.exp)}


def _eval(table, name, x):
    out = np.empty_like(x)
    table[name](x, out)
    return out


def _ulp_error(name, x):
    """|vecmath - libm| in units of the last place of libm's result (both finite, nonzero)."""
    a = _eval(_V, name, x)
    b = _eval(_M, name, x)
    assert np.all(np.isfinite(a) == np.isfinite(b))
    ok = np.isfinite(b) & (b != 0.0)
    assert np.array_equal(a[b == 0.0], b[b == 0.0])  # exact zeros stay exact
    return np.abs(a[ok] - b[ok]) / np.spacing(np.abs(b[ok]))


RNG_SEED = 20261122


# --------------------------------------------------------------------------------------------
# 1. accuracy against libm on dense grids and random points
# --------------------------------------------------------------------------------------------
# Tolerance 2 ulp of libm's result: the analysis of each method (module docstring) bounds the
# error at ~1.5 ulp of the exact value (two final roundings plus the reduction's rounding; the
# polynomials' interpolation error is < 0.05 ulp), and libm is within 0.5 ulp of it.
@pytest.mark.parametrize(
    "name, xs",
    [
        ("atan", lambda rng: np.linspace(-20.0, 20.0, 400_001)),
        ("atan", lambda rng: rng.choice([-1.0, 1.0], 200_000)
         * 10.0 ** rng.uniform(-300, 300, 200_000)),
        ("atan", lambda rng: np.tan(rng.uniform(-1.5707, 1.5707, 200_000))),
        ("sin", lambda rng: np.linspace(-10.0, 10.0, 400_001)),
        ("sin", lambda rng: rng.uniform(-1e5, 1e5, 200_000)),
        ("cos", lambda rng: np.linspace(-10.0, 10.0, 400_001)),
        ("cos", lambda rng: rng.uniform(-1e5, 1e5, 200_000)),
        ("exp", lambda rng: np.linspace(-745.0, 709.7, 400_001)),
        ("exp", lambda rng: rng.uniform(-3.0, 3.0, 200_000)),
    ],
)
def test_within_two_ulp_of_libm(name, xs):
    x = xs(np.random.default_rng(RNG_SEED))
    err = _ulp_error(name, x)
    assert err.max() <= 2.0, (name, float(err.max()))


def test_near_multiples_of_half_pi():
    """The three-part reduction keeps sin/cos accurate where they nearly vanish."""
    k = np.arange(-2000, 2001, dtype=np.float64)
    base = k * (math.pi / 2.0)
    x = np.concatenate([base, np.nextafter(base, np.inf), np.nextafter(base, -np.inf)])
    for name in ("sin", "cos"):
        assert _ulp_error(name, x).max() <= 2.0


def test_against_mpmath():
    """Error against the exact value (mpmath, 40 digits) at random points of the MF's range.

    Tolerance 2 ulp of the exact value (module docstring: measured max 1.76 for atan).
    """
    mp.mp.dps = 40
    rng = np.random.default_rng(RNG_SEED + 1)
    cases = {
        "atan": (np.concatenate([rng.uniform(-3, 3, 1500),
                                 np.tan(rng.uniform(-1.57, 1.57, 1500))]), mp.atan),
        "sin": (rng.uniform(-4.0, 4.0, 2000), mp.sin),
        "cos": (rng.uniform(-4.0, 4.0, 2000), mp.cos),
        "exp": (rng.uniform(-5.0, 5.0, 2000), mp.exp),
    }
    for name, (x, ref) in cases.items():
        y = _eval(_V, name, x)
        worst = 0.0
        for xi, yi in zip(x, y, strict=True):
            exact = ref(mp.mpf(float(xi)))
            worst = max(worst, float(abs(mp.mpf(float(yi)) - exact)) / math.ulp(float(exact)))
        assert worst <= 2.0, (name, worst)


# --------------------------------------------------------------------------------------------
# 2. special values, symmetry, domain
# --------------------------------------------------------------------------------------------
def test_special_values():
    x = np.array([0.0, -0.0, np.inf, -np.inf, np.nan, 5e-324, 1e300])
    a = _eval(_V, "atan", x)
    assert a[0] == 0.0 and not math.copysign(1.0, a[0]) < 0
    assert a[1] == 0.0 and math.copysign(1.0, a[1]) < 0  # atan(-0) = -0
    assert a[2] == math.pi / 2 and a[3] == -math.pi / 2 and a[6] == math.pi / 2
    assert math.isnan(a[4]) and a[5] == 5e-324
    s = _eval(_V, "sin", x)
    c = _eval(_V, "cos", x)
    assert s[0] == 0.0 and c[0] == 1.0 and c[1] == 1.0 and s[5] == 5e-324
    assert np.all(np.isnan(s[[2, 3, 4, 6]])) and np.all(np.isnan(c[[2, 3, 4, 6]]))
    e = _eval(_V, "exp", np.array([0.0, -0.0, np.inf, -np.inf, np.nan, 709.78, 709.79,
                                   -745.1, -746.0, 1e-300]))
    assert e[0] == 1.0 and e[1] == 1.0 and e[2] == np.inf and e[3] == 0.0
    assert math.isnan(e[4]) and e[6] == np.inf and e[8] == 0.0 and e[9] == 1.0
    assert e[5] == math.exp(709.78)  # largest finite results (two-factor scaling)
    assert e[7] == 5e-324  # gradual underflow to the smallest subnormal


def test_sin_cos_domain_limit():
    """|x| <= 2^22 is accurate, beyond is NaN (documented domain)."""
    lim = 2.0**22
    x = np.array([lim, -lim, np.nextafter(lim, np.inf), -np.nextafter(lim, np.inf)])
    s = _eval(_V, "sin", x)
    ref = np.array([math.sin(lim), -math.sin(lim)])
    assert np.all(np.abs(s[:2] - ref) <= 2 * np.spacing(np.abs(ref)))  # the 2 ulp (measured 0)
    assert np.all(np.isnan(s[2:]))


@settings(max_examples=200, deadline=None, derandomize=True)
@given(st.floats(min_value=-1e5, max_value=1e5, allow_nan=False))
def test_symmetry(x):
    """atan and sin are odd, cos is even, exactly (the reductions are symmetric)."""
    v = np.array([x, -x])
    a = _eval(_V, "atan", v)
    s = _eval(_V, "sin", v)
    c = _eval(_V, "cos", v)
    assert a[1] == -a[0] and s[1] == -s[0] and c[1] == c[0]


@settings(max_examples=200, deadline=None, derandomize=True)
@given(st.floats(min_value=-700.0, max_value=700.0, allow_nan=False))
def test_exp_within_two_ulp_hypothesis(x):
    v = np.array([x])
    assert abs(_eval(_V, "exp", v)[0] - math.exp(x)) <= 2.0 * math.ulp(math.exp(x))


# --------------------------------------------------------------------------------------------
# 3. the constants and coefficients are what the module docstring says
# --------------------------------------------------------------------------------------------
def _significant_bits(v: float) -> int:
    m, _ = math.frexp(abs(v))
    mant = int(m * 2**53)
    return 53 - ((mant & -mant).bit_length() - 1)


def test_split_constants():
    mp.mp.dps = 60
    half_pi = mp.pi / 2
    assert abs(mp.mpf(vm._P1) + vm._P2 + vm._P3 - half_pi) < mp.mpf(1e-34)
    assert _significant_bits(vm._P1) <= 30 and _significant_bits(vm._P2) <= 30
    assert abs(mp.mpf(vm._L1) + vm._L2 - mp.log(2)) < mp.mpf(1e-26)
    assert _significant_bits(vm._L1) <= 32
    for hi, lo, exact in ((vm._PI4_HI, vm._PI4_LO, mp.pi / 4), (vm._PI2_HI, vm._PI2_LO, half_pi)):
        assert abs(mp.mpf(hi) + lo - exact) < mp.mpf(1e-32)
    assert vm._TAN_PI8 == float(mp.tan(mp.pi / 8))
    assert vm._TAN_3PI8 == float(mp.tan(3 * mp.pi / 8))
    assert vm._TWO_OVER_PI == float(2 / mp.pi) and vm._LOG2E == float(1 / mp.log(2))
    assert vm._SHIFTER == 1.5 * 2.0**52
    assert vm._SHIFTER_BITS == np.array(vm._SHIFTER).view(np.int64)


def _chebyshev_interpolant(g, a, b, n):
    """Monomial coefficients (lowest first) of the degree-n interpolant of g at the n+1
    Chebyshev nodes of the first kind on [a, b] (mpmath, current precision)."""
    nodes = [(a + b) / 2 + (b - a) / 2 * mp.cos(mp.pi * (2 * k + 1) / (2 * (n + 1)))
             for k in range(n + 1)]
    vander = mp.matrix([[x**j for j in range(n + 1)] for x in nodes])
    c = mp.lu_solve(vander, mp.matrix([g(x) for x in nodes]))
    return tuple(float(c[j]) for j in range(n + 1))


def test_coefficients_reproduce():
    """Every polynomial literal is the documented Chebyshev interpolant rounded to double."""
    mp.mp.dps = 60
    tiny = mp.mpf(10) ** -25  # below: the series, where the quotients lose all digits

    def p_atan(w):  # (atan z - z) / z^3, w = z^2
        z = mp.sqrt(w)
        return -mp.mpf(1) / 3 + w / 5 if abs(w) < tiny else (mp.atan(z) - z) / z**3

    def p_sin(w):  # (sin r - r) / r^3, w = r^2
        r = mp.sqrt(w)
        return -mp.mpf(1) / 6 + w / 120 if abs(w) < tiny else (mp.sin(r) - r) / r**3

    def p_cos(w):  # (cos r - 1 + r^2/2) / r^4, w = r^2
        r = mp.sqrt(w)
        return mp.mpf(1) / 24 - w / 720 if abs(w) < tiny else (mp.cos(r) - 1 + w / 2) / w**2

    def p_exp(r):  # (e^r - 1 - r) / r^2
        return mp.mpf(1) / 2 + r / 6 if abs(r) < tiny else (mp.exp(r) - 1 - r) / r**2

    q = mp.pi / 4
    assert _chebyshev_interpolant(p_atan, mp.mpf(0), mp.tan(mp.pi / 8) ** 2, 10) == vm._AT
    assert _chebyshev_interpolant(p_sin, mp.mpf(0), q**2, 6) == vm._SN
    assert _chebyshev_interpolant(p_cos, mp.mpf(0), q**2, 5) == vm._CS
    assert _chebyshev_interpolant(p_exp, -mp.log(2) / 2, mp.log(2) / 2, 9) == vm._EX


# --------------------------------------------------------------------------------------------
# 4. they vectorise (the reason they exist)
# --------------------------------------------------------------------------------------------
@pytest.mark.skipif(platform.machine() not in ("x86_64", "AMD64"), reason="x86 assembly")
def test_loop_vectorises_without_libm_calls():
    """A loop over the functions compiles to packed-double arithmetic and no libm call.

    (The 4-lane loops of the tyre model are checked in tests/test_tendof_fastpath.py.)
    """

    @njit(error_model="numpy")
    def loop(x):
        for i in range(x.size):
            x[i] = vm.sin(1.3 * vm.atan(x[i])) * vm.exp(0.1 * x[i]) + vm.cos(x[i])

    x = np.linspace(-1.0, 2.0, 64)
    loop(x)
    asm = loop.inspect_asm(loop.signatures[0])
    assert not re.search(r"call\w*\s+.*\b(atan|sin|cos|exp)\b", asm)
    packed = re.findall(r"\bv?(?:mul|add|sub|div|fmadd\d+|fnmadd\d+)pd\b", asm)
    assert len(packed) >= 40  # the polynomials and reductions run on packed doubles


def test_stack_array():
    """A (rows, cols) C-contiguous float64 scratch in the caller's frame, fresh per call."""

    @njit(error_model="numpy")
    def fill(a):
        s = vm.stack_array(3, 4)
        for i in range(3):
            for j in range(4):
                s[i, j] = a[i] * 10.0 + j
        return s.shape[0], s.shape[1], s.strides[0], s.strides[1], s[2, 3], s.sum()

    a = np.array([1.0, 2.0, 3.0])
    expect = (3, 4, 32, 8, 33.0, float(sum(a[i] * 10.0 + j for i in range(3) for j in range(4))))
    assert fill(a) == expect
    assert fill(a) == expect  # the frame's memory, written again at each call
