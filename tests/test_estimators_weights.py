"""Exact discrete weights of the paper's kernels (flatfree.estimators, issue 3).

Reference values come from sympy (exact rational arithmetic), from exact simulation of the
ultra-local model under zero-order-hold inputs, and from the continuous kernels of NOTES.md.
"""

from __future__ import annotations

import functools
import math
import re

import numpy as np
import pytest
import sympy as sp
from hypothesis import given, settings
from hypothesis import strategies as st

from flatfree.estimators import (
    FEstimator,
    JacobiDesign,
    denoising_weights,
    derivative_weights,
    design_for,
    estimate_f,
    f_estimator_weights,
    fir_new,
)


# ---------------------------------------------------------------------------------------------
# sympy: the weights are the projection of the sampled kernel onto the exactness constraints,
# and the estimator is exact symbolically (any initial conditions, any ZOH input, any F).
# ---------------------------------------------------------------------------------------------
def _sympy_weights(nu: int, n: int):
    """Exact (rational, dt = 1) weights derived independently: a_j a polynomial of degree nu in j
    (the sampled continuous kernel's form) meeting the moment constraints; b from the ZOH model."""
    j = sp.symbols("j")
    c = sp.symbols(f"c0:{nu + 1}")
    poly = sum(c[p] * j**p for p in range(nu + 1))
    a = [poly.subs(j, jj) for jj in range(n)]
    if nu == 1:
        eqs = [sum(a), sum(jj * a[jj] for jj in range(n)) - 1]
    else:
        eqs = [sum(a), sum(jj * a[jj] for jj in range(n)),
               sp.Rational(1, 2) * sum(jj**2 * a[jj] for jj in range(n)) - 1]
    sol = sp.solve(eqs, c, dict=True)[0]
    a = [sp.nsimplify(ai.subs(sol)) for ai in a]
    if nu == 1:
        b = [-sum(a[jj] for jj in range(m + 1, n)) for m in range(n - 1)]
    else:
        b = [-sum((jj - m - sp.Rational(1, 2)) * a[jj] for jj in range(m + 1, n))
             for m in range(n - 1)]
    return a, b  # oldest first


@pytest.mark.parametrize("nu,n", [(1, 2), (1, 3), (1, 6), (2, 3), (2, 4), (2, 7)])
def test_f_weights_symbolically_exact_and_match_float(nu, n):
    a, b = _sympy_weights(nu, n)
    # symbolic signal: s_j = s0 (+ v0 j) + F j^nu/nu! + alpha * ZOH response to v_m (dt = 1)
    s0, v0, F, alpha = sp.symbols("s0 v0 F alpha")
    v = sp.symbols(f"v0:{n - 1}")
    s = []
    for jj in range(n):
        if nu == 1:
            s.append(s0 + F * jj + alpha * sum(v[m] for m in range(jj)))
        else:
            s.append(s0 + v0 * jj + F * sp.Rational(jj * jj, 2)
                     + alpha * sum((jj - m - sp.Rational(1, 2)) * v[m] for m in range(jj)))
    F_hat = sum(a[jj] * s[jj] for jj in range(n)) + alpha * sum(b[m] * v[m] for m in range(n - 1))
    assert sp.expand(F_hat - F) == 0
    # the float weights (any dt) are these rationals scaled: wy ~ 1/dt^nu, wu dimensionless
    dt = 0.02
    wy, wu = f_estimator_weights(nu, n, dt)
    ref_y = np.array([float(x) for x in a[::-1]]) / dt**nu
    ref_u = np.array([float(x) for x in b[::-1]]) * (dt if nu == 1 else dt * dt) / dt**nu
    # tolerance 1e-12 relative: a handful of float operations on O(1) numbers
    np.testing.assert_allclose(wy, ref_y, rtol=1e-12, atol=1e-12 * np.abs(ref_y).max())
    np.testing.assert_allclose(wu, ref_u, rtol=1e-12, atol=1e-12 * np.abs(ref_u).max())


# ---------------------------------------------------------------------------------------------
# exact simulation of y^(nu) = F + alpha u with ZOH inputs sampled from a random polynomial
# ---------------------------------------------------------------------------------------------
def _simulate(nu, F, alpha, u, y0, v0, dt):
    """Exact samples of y^(nu) = F + alpha u, u[m] held on [t_m, t_{m+1})."""
    y = np.empty(u.size + 1)
    y[0] = y0
    v = v0
    for m in range(u.size):
        acc = F + alpha * u[m]
        if nu == 1:
            y[m + 1] = y[m] + acc * dt
        else:
            y[m + 1] = y[m] + v * dt + 0.5 * acc * dt * dt
            v += acc * dt
    return y


@settings(max_examples=60, deadline=None)
@given(nu=st.sampled_from([1, 2]), extra=st.integers(0, 40), seed=st.integers(0, 2**32 - 1),
       dt_exp=st.floats(-3.0, -1.0))
def test_f_estimator_exact_on_random_polynomial_inputs(nu, extra, seed, dt_exp):
    rng = np.random.default_rng(seed)
    n = nu + 1 + extra  # includes the shortest window allowed
    dt = 10.0**dt_exp
    F, alpha, y0, v0 = rng.uniform(-2, 2, 4)
    F = math.copysign(max(abs(F), 0.1), F)
    m = n + 5
    tt = np.arange(m) * dt
    coef = rng.normal(size=4)
    u = np.polyval(coef, tt / tt[-1])  # a random cubic, sampled and held
    y = _simulate(nu, F, alpha, u, y0, v0, dt)
    wy, wu = f_estimator_weights(nu, n, dt)
    k = m  # last sample
    F_hat = wy @ y[k::-1][:n] + alpha * (wu @ u[k - 1::-1][: n - 1])
    # Tolerance: the contract's 1e-9 relative, or the float floor when that is larger. F is a
    # nu-th difference of y divided by dt^nu, so rounding of y (the exact simulation itself
    # accumulates ~m eps |y|) and of the dot products is amplified by sum|w|; the bound
    # 4 (m + n) eps (sum|wy||y| + |alpha| sum|wu||u|) covers both. It binds only for the shortest
    # nu = 2 windows at small dt (e.g. n = 3, dt = 1e-3: ~1e-9 of |y|).
    floor = 4 * (m + n) * np.finfo(float).eps * (
        np.abs(wy) @ np.abs(y[k::-1][:n])
        + abs(alpha) * (np.abs(wu) @ np.abs(u[k - 1::-1][: n - 1])))
    assert abs(F_hat - F) <= max(1e-9 * abs(F), floor)


@pytest.mark.parametrize("nu,n", [(1, 2), (1, 3), (1, 50), (2, 3), (2, 4), (2, 50)])
def test_f_estimator_contract_1e9_relative_at_10ms(nu, n):
    """The contract's figure itself, at a sampling period where rounding is far below it."""
    rng = np.random.default_rng(nu * 100 + n)
    dt, F, alpha = 0.01, 0.8, -1.3
    u = rng.normal(size=n + 3)
    y = _simulate(nu, F, alpha, u, 0.4, -0.2, dt)
    wy, wu = f_estimator_weights(nu, n, dt)
    k = u.size
    F_hat = wy @ y[k::-1][:n] + alpha * (wu @ u[k - 1::-1][: n - 1])
    assert abs(F_hat - F) <= 1e-9 * abs(F)


def test_trapezoid_leaks_as_the_issue_says_and_exact_weights_do_not():
    """The issue's measured leak of the trapezoid nu = 2 kernel: 60 dt^2 / T^4 per unit of y."""
    dt = 1e-3
    for T, leak in ((0.05, 9.6), (0.01, 6000.0)):
        n = int(round(T / dt)) + 1
        sig = np.arange(n) * dt  # local time from the window start, oldest first
        ker = (60 / T**5) * (T**2 - 6 * T * sig + 6 * sig**2)  # NOTES.md nu = 2, y term
        trap = ker * dt
        trap[[0, -1]] *= 0.5
        # response to y = 1 (should be 0): the trapezoid leak, vs the exact weights
        assert trap.sum() == pytest.approx(leak, rel=1e-3)  # 60 dt^2/T^4, to the 3 digits quoted
        wy, _ = f_estimator_weights(2, n, dt)
        assert abs(wy.sum()) < 1e-9 * np.abs(wy).sum()


@pytest.mark.parametrize("nu", [1, 2])
def test_discrete_weights_converge_to_the_corrected_continuous_kernels(nu):
    """n -> infinity at fixed T: wy/dt and wu/dt tend to NOTES.md's kernels (first order in dt)."""
    T = 0.2
    errs = []
    for n in (201, 401, 801):
        dt = T / (n - 1)
        wy, wu = f_estimator_weights(nu, n, dt)
        sig = T - np.arange(n) * dt  # local window time of y[k-i]
        sig_u = T - (np.arange(n - 1) + 0.5) * dt  # midpoint of the hold interval of u[k-1-i]
        if nu == 1:
            ky = -(6 / T**3) * (T - 2 * sig)  # NOTES.md nu = 1
            ku = -(6 / T**3) * sig_u * (T - sig_u)
        else:
            ky = (60 / T**5) * (T**2 - 6 * T * sig + 6 * sig**2)  # NOTES.md nu = 2 (sign fixed)
            ku = -(30 / T**5) * (T - sig_u) ** 2 * sig_u**2
        e = max(np.abs(wy / dt - ky).max() / np.abs(ky).max(),
                np.abs(wu / dt - ku).max() / np.abs(ku).max())
        errs.append(e)
    # first-order convergence: halving dt roughly halves the error (ratio in [1.7, 2.3]), and the
    # error is already small at n = 801
    assert 1.7 < errs[0] / errs[1] < 2.3 and 1.7 < errs[1] / errs[2] < 2.3
    assert errs[-1] < 2e-2


# ---------------------------------------------------------------------------------------------
# derivative and denoising kernels
# ---------------------------------------------------------------------------------------------
@pytest.mark.parametrize("n", [2, 3, 10, 101])
def test_derivative_weights_exact_on_ramps_with_half_window_delay_on_parabolas(n):
    dt = 0.01
    w = derivative_weights(n, dt)
    t = 1.7 - np.arange(n) * dt  # y[k-i] sampled at t_k - i dt, t_k = 1.7
    tol = 1e-12 * 100  # O(n eps) on O(1..100) numbers
    assert w @ (3.0 - 2.5 * t) == pytest.approx(-2.5, abs=tol)
    assert w @ np.ones(n) == pytest.approx(0.0, abs=tol)
    # a parabola t^2: the estimate is the derivative at the window centre, t_k - T/2
    T = (n - 1) * dt
    assert w @ t**2 == pytest.approx(2 * (1.7 - T / 2), abs=tol)
    np.testing.assert_allclose(w, JacobiDesign(n=n, dt=dt).weights, rtol=1e-10, atol=1e-12)


@pytest.mark.parametrize("n", [3, 4, 25])
def test_second_derivative_weights_exact_on_parabolas(n):
    dt = 0.01
    w = derivative_weights(n, dt, order=2)
    t = 0.4 - np.arange(n) * dt
    assert w @ (1 + 2 * t - 3.5 * t**2) == pytest.approx(-7.0, rel=1e-9)


@pytest.mark.parametrize("n", [2, 3, 50])
def test_denoiser_returns_a_ramp_unchanged_at_the_current_time(n):
    w = denoising_weights(n)
    t = 2.0 - np.arange(n) * 0.003
    assert w @ (0.5 + 4.0 * t) == pytest.approx(0.5 + 4.0 * 2.0, rel=1e-12)
    # and it is the corrected continuous kernel (2/T^2)(2T - 3d) in the limit, not the paper's
    # printed (3d - T) which returns the value at the window start
    np.testing.assert_allclose(
        w, JacobiDesign(n=n, dt=0.003, order=0, N=1, lag=0.0).weights, rtol=1e-10, atol=1e-13)


@functools.cache
def _sympy_denoiser():
    """Derived in sympy, for a symbolic window of n = 2c + 1 samples (c = (n - 1)/2, half the
    window in samples) and i = sample age (0 = newest):

    * ``w``: the least-squares line through (j, y_j), j = 0..n-1 oldest first, evaluated at the
      newest sample j = n - 1, from the normal equations with symbolic sums (independent of the
      library's centred closed form);
    * ``k``: NOTES.md's continuous kernel (2/T^2)(2T - 3d) dt sampled at d = i dt, T = 2c dt;
    * ``ratio``: max_i |w_i - k_i| / max_i |k_i| over i = 0..2c.
    """
    n, j, i, c = sp.symbols("n j i c", positive=True)
    s0 = n
    s1 = sp.summation(j, (j, 0, n - 1))
    s2 = sp.summation(j**2, (j, 0, n - 1))
    # y_hat(j0) = [1, j0] M^-1 sum_j [1, j] y_j: the weight of y_j
    M = sp.Matrix([[s0, s1], [s1, s2]])
    a = (sp.Matrix([[1, n - 1]]) * M.inv() * sp.Matrix([1, j]))[0]
    w = sp.simplify(a.subs(j, n - 1 - i).subs(n, 2 * c + 1))
    dt = sp.symbols("dt", positive=True)
    T = 2 * c * dt
    k = sp.simplify((2 / T**2) * (2 * T - 3 * i * dt) * dt)
    # w and k are linear in i: the extremes of |w - k| and |k| on [0, 2c] are at the ends
    assert sp.diff(w, i, 2) == 0 and sp.diff(k, i, 2) == 0
    e0, e1 = sp.simplify((w - k).subs(i, 0)), sp.simplify((w - k).subs(i, 2 * c))
    k0, k1 = k.subs(i, 0), sp.simplify(k.subs(i, 2 * c))
    assert sp.simplify(k0 - 2 / c) == 0 and sp.simplify(k1 + 1 / c) == 0  # max |k| = k0 = 2/c
    assert sp.simplify(e0 + (5 * c + 2) / (c * (2 * c + 1) * (c + 1))) == 0  # < 0
    assert sp.simplify(e1 - (4 * c + 1) / (c * (2 * c + 1) * (c + 1))) == 0  # > 0, |e1| < |e0|
    ratio = sp.simplify(-e0 / k0)
    return c, i, w, ratio


@pytest.mark.parametrize("n", [2, 3, 10, 50, 51, 200])
def test_denoiser_equals_its_closed_form_and_the_sampled_kernel_difference(n):
    """Weights (4c + 1 - 3i) / ((2c + 1)(c + 1)) and discretisation difference
    max|w - k| / max|k| = (5c + 2) / (2 (2c + 1)(c + 1)), c = (n - 1)/2, both derived in sympy
    (:func:`_sympy_denoiser`); the difference is O(1/n): 5/(8c) for large c."""
    c, i, w_sym, ratio_sym = _sympy_denoiser()
    assert sp.simplify(w_sym - (4 * c + 1 - 3 * i) / ((2 * c + 1) * (c + 1))) == 0
    assert sp.simplify(ratio_sym - (5 * c + 2) / (2 * (2 * c + 1) * (c + 1))) == 0
    cv = sp.Rational(n - 1, 2)
    w_ref = np.array([float(w_sym.subs({c: cv, i: ii})) for ii in range(n)])
    ratio_ref = float(ratio_sym.subs(c, cv))
    w = denoising_weights(n)
    eps = np.finfo(float).eps
    # a few roundings of O(max|w|) numbers per weight: 4 eps of max|w|
    assert np.abs(w - w_ref).max() <= 4 * eps * np.abs(w_ref).max()
    dt = 0.003
    T = (n - 1) * dt
    d = np.arange(n) * dt
    k = (2 / T**2) * (2 * T - 3 * d) * dt
    # w and k each carry a few roundings relative to max|k| (>= max|w|): 8 eps on the ratio
    assert abs(np.abs(w - k).max() / np.abs(k).max() - ratio_ref) <= 8 * eps


@pytest.mark.parametrize(
    "call, text",
    [
        (lambda: f_estimator_weights(3, 10, 0.01), "nu = 3: must be 1 or 2"),
        (lambda: f_estimator_weights(1, 1, 0.01), "n = 1: must be an integer >= 2"),
        (lambda: f_estimator_weights(2, 2, 0.01), "n = 2: must be an integer >= 3"),
        (lambda: f_estimator_weights(1, 5, 0.0), "dt = 0.0 s: must be > 0"),
        (lambda: f_estimator_weights(1, 5, -1e-3), "dt = -0.001 s: must be > 0"),
        (lambda: f_estimator_weights(1, 5, float("nan")), "dt = nan s: must be finite"),
        (lambda: f_estimator_weights(1, 5, "0.01"), "dt = '0.01' s: expected a real number"),
        (lambda: f_estimator_weights(1, 5, True), "dt = True s: expected a real number"),
        (lambda: f_estimator_weights(1, 5.0, 0.01),
         "n = 5.0: must be an integer >= 2, given as an int (not float)"),
        (lambda: derivative_weights(1, 0.01), "n = 1: must be an integer >= 2"),
        (lambda: derivative_weights(5, [0.01]), "dt = [0.01] s: expected a real number"),
        (lambda: derivative_weights(5, 0.01, order=3),
         "order = 3: must be 1 or 2 (use JacobiDesign for higher orders)"),
        (lambda: denoising_weights(1), "n = 1: must be an integer >= 2"),
    ],
)
def test_bad_arguments_raise_valueerror_naming_the_value(call, text):
    with pytest.raises(ValueError, match=f"^{re.escape(text)}$"):
        call()


@pytest.mark.parametrize(
    "call, text",
    [
        (lambda: f_estimator_weights(1, 10.0, 0.01),
         "n = 10.0: must be an integer >= 2, given as an int (not float)"),
        (lambda: f_estimator_weights(1, np.float64(10), 0.01),
         "n = np.float64(10.0): must be an integer >= 2, given as an int (not float64)"),
        (lambda: f_estimator_weights(1, True, 0.01),
         "n = True: must be an integer >= 2, given as an int (not bool)"),
        (lambda: f_estimator_weights(1, "10", 0.01),
         "n = '10': must be an integer >= 2, given as an int (not str)"),
        (lambda: derivative_weights(10.0, 0.01),
         "n = 10.0: must be an integer >= 2, given as an int (not float)"),
        (lambda: denoising_weights(10.0),
         "n = 10.0: must be an integer >= 2, given as an int (not float)"),
        (lambda: JacobiDesign(n=10.0, dt=0.01),
         "n = 10.0: must be an integer >= 2, given as an int (not float)"),
        (lambda: JacobiDesign(n=10, dt=0.01, N=1.0),
         "N = 1.0: must be an integer >= 0, given as an int (not float)"),
        (lambda: JacobiDesign(n=10, dt=0.01, order=1.0),
         "order = 1.0: must be an integer >= 0, given as an int (not float)"),
        (lambda: design_for(1e-3, bandwidth_hz=2.0, noise_std=0.01, signal_std=0.7,
                            order=1.0),
         "order = 1.0: must be an integer >= 0, given as an int (not float)"),
        (lambda: design_for(1e-3, bandwidth_hz=2.0, noise_std=0.01, signal_std=0.7,
                            max_taps=100.0),
         "max_taps = 100.0: must be an integer >= 3, given as an int (not float)"),
        (lambda: estimate_f(np.zeros(5), np.zeros(5), nu=1, n=3.0, dt=0.01, alpha=1.0),
         "n = 3.0: must be an integer >= 2, given as an int (not float)"),
        (lambda: FEstimator(1, 3.0, 0.01, 1.0),
         "n = 3.0: must be an integer >= 2, given as an int (not float)"),
        (lambda: fir_new(np.ones(3), full=3.0),
         "full = 3.0: must be an integer >= 1, given as an int (not float)"),
        (lambda: fir_new(np.ones(3), full="3"),
         "full = '3': must be an integer >= 1, given as an int (not str)"),
    ],
)
def test_integer_arguments_are_integers_everywhere(call, text):
    """One rule for every sample count and derivative order of the estimators (the shared
    whole(strict=True)): an integral float such as 10.0 is refused as n is, by name, the
    message naming the type it must be given as."""
    with pytest.raises(ValueError, match=f"^{re.escape(text)}$"):
        call()
    # the integers themselves, NumPy's too, give the same weights bit for bit
    np.testing.assert_array_equal(f_estimator_weights(2, np.int64(10), 0.01)[0],
                                  f_estimator_weights(2, 10, 0.01)[0])
