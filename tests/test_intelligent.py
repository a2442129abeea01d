"""Tests of the intelligent controllers (flatfree.controllers.intelligent), issue 6.

Every plant below is written here and unknown to the controller: the controller sees only the
sampled measurement and its own applied input. Reference values come from closed forms (exact
zero-order-hold recursions, the designed linear error dynamics via the matrix exponential),
sympy (gain formulas), or a peer controller measured on the same runs (the classic PI).
"""

from __future__ import annotations

import math
import re
from typing import NamedTuple

import numba
import numpy as np
import pytest
import sympy as sp
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.linalg import expm

from flatfree.controllers.intelligent import (
    IP,
    IPD,
    IPI,
    IPID,
    IntelligentController,
    IntelligentParams,
    error_dynamics_gains,
    intelligent_law_ran,
    intelligent_reset,
    intelligent_step,
    make_state,
    model_derivative_weights,
)


# ------------------------------------------------------------------------------------------
# helpers: plants (unknown to the controllers), integrators, a classic PI
# ------------------------------------------------------------------------------------------
def rk4(f, x, h, steps):
    """``steps`` RK4 steps of size h for x' = f(x) (x a float or a numpy array)."""
    for _ in range(steps):
        k1 = f(x)
        k2 = f(x + 0.5 * h * k1)
        k3 = f(x + 0.5 * h * k2)
        k4 = f(x + h * k3)
        x = x + (h / 6.0) * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
    return x


def designed_error(a_mat: np.ndarray, x0: np.ndarray, t: np.ndarray, row: int) -> np.ndarray:
    """Component ``row`` of x(t) = expm(A t) x0 (the designed linear error dynamics)."""
    return np.array([(expm(a_mat * tt) @ x0)[row] for tt in t])


#: The error-equation bounds below rest on identities of the sampled loop, exact up to rounding
#: (the recursion reproduces the runs' errors to ~1e-15); this relative margin covers rounding
#: only, nothing else. Many samples meet their bound with equality (all terms of the envelope of
#: one sign), so the observed value exceeds it by rounding: measured (every
#: :func:`assert_within` call and every :func:`_alpha_run` here) the largest relative excess
#: (observed - bound) / bound is 9.7e-15 (44 eps; cubic iPI at dt = 0.005, k = 1), elsewhere
#: <= 7.4e-15; the margin is 10x that (450 eps). The largest absolute excess was 1.1e-15, at a
#: bound of 0.58 (alpha/b = 50); at zero bounds the observed value was exactly 0.
ROUNDING = 1e-13


def sampled_error_model(nu: int, kp: float, ki: float, kd: float, dt: float):
    """The exact sampled error equation of the intelligent law under zero-order hold.

    State ``z_k = (I_{k-1}, e_k)`` (nu = 1) or ``(I_{k-1}, e_k, e'_k)`` (nu = 2), with
    ``I_k = I_{k-1} + e_k dt`` the controller's integral (rectangle rule, includes ``e_k``).
    On ``[t_k, t_{k+1})`` the plant gives ``y^(nu) = F(t) + alpha u_k`` (this defines F, the
    ultra-local model's lumped term, relative to the controller's output ``u_k``) and the law sets
    ``alpha u_k = -(F_hat_k - r^(nu)_k + Kp e_k + Ki I_k [+ Kd e'_hat_k])``. Integrating the
    interval exactly, with ``w_k = -(Kp e_k + Ki I_k [+ Kd e'_k])``:

    * nu = 1: ``e_{k+1} = e_k + dt (w_k + d_k)``, ``d_k`` from :func:`nu1_disturbance`;
    * nu = 2: ``e'_{k+1} = e'_k + dt (w_k + d1_k)``, ``e_{k+1} = e_k + dt e'_k
      + dt^2 / 2 (w_k + d2_k)``: ``d1`` and ``d2`` are the interval's mean of
      ``F - F_hat_k - (r'' - r''_k) + Kd (e'_k - e'_hat_k)``, plain and weighted by
      ``2 (dt - s) / dt^2`` (``test_mass_with_friction...`` forms them).

    Returns ``(A, [B_i], C)``: ``z_{k+1} = A z_k + sum_i B_i d_i,k`` and ``e_k = C z_k``, so
    ``e_k = e_free_k + sum_i sum_j C A^(k-1-j) B_i d_i,j`` (:func:`excursion_envelope`).
    """
    h = dt
    if nu == 1:
        shift, inputs = np.array([[1.0, h], [0.0, 1.0]]), [np.array([0.0, h])]
        w = np.array([-ki, -(kp + h * ki)])  # Ki I_k = Ki I_{k-1} + Ki h e_k
        return shift + np.outer([0.0, h], w), inputs, np.array([0.0, 1.0])
    shift = np.array([[1.0, h, 0.0], [0.0, 1.0, h], [0.0, 0.0, 1.0]])
    w = np.array([-ki, -(kp + h * ki), -kd])
    inputs = [np.array([0.0, h * h / 2, 0.0]), np.array([0.0, 0.0, h])]  # d2, d1
    return shift + np.outer([0.0, h * h / 2, h], w), inputs, np.array([0.0, 1.0, 0.0])


def nu1_disturbance(y, r, r_dot, u, f_hat, alpha: float, dt: float) -> np.ndarray:
    """``d_k`` of :func:`sampled_error_model` (nu = 1) from a run's samples (index k, the last
    sample gives only ``y`` and ``r``): the interval's mean F, ``(y_{k+1} - y_k)/dt - alpha u_k``,
    minus the estimate ``F_hat_k``, less the reference's drift within the hold,
    ``(r_{k+1} - r_k)/dt - r'_k``. Formed from the plant's output and the controller's output and
    estimate, not from the law."""
    y, r, r_dot, u, f_hat = (np.asarray(v, dtype=float) for v in (y, r, r_dot, u, f_hat))
    return (np.diff(y) / dt - alpha * u[:-1] - f_hat[:-1]) - (np.diff(r) / dt - r_dot[:-1])


def free_error(a: np.ndarray, c: np.ndarray, z0: np.ndarray, n: int) -> np.ndarray:
    """``C A^k z0``, k = 0..n-1: the sampled design without disturbance from ``z0`` (with an
    input column ``B_i`` for ``z0``: the impulse response ``h_i``)."""
    out, z = np.empty(n), np.asarray(z0, dtype=float)
    for k in range(n):
        out[k] = c @ z
        z = a @ z
    return out


def excursion_envelope(a: np.ndarray, inputs, c: np.ndarray, dists) -> np.ndarray:
    """``env_k = sum_i sum_{j<k} |h_i[k-1-j]| |d_i,j|``, k = 0..n (n samples of each ``d_i``;
    ``h_i[m] = C A^m B_i``): the most the disturbances can have moved ``e_k`` away from the free
    response (triangle inequality on the identity of :func:`sampled_error_model`). Its maximum
    is at most ``sum_i ||h_i||_1 max|d_i|`` (:func:`l1_norm`)."""
    n = len(dists[0])
    env = np.zeros(n + 1)
    for b, d in zip(inputs, dists, strict=True):
        env[1:] += np.convolve(np.abs(free_error(a, c, b, n)), np.abs(d))[:n]
    return env


def l1_norm(a: np.ndarray, b: np.ndarray, c: np.ndarray, n: int) -> float:
    """``||h||_1 = sum_{m<n} |C A^m B|`` (an exact finite sum)."""
    return float(np.abs(free_error(a, c, b, n)).sum())


def assert_within(observed: np.ndarray, bound: np.ndarray) -> None:
    """``observed_k <= bound_k`` at every sample, up to rounding (:data:`ROUNDING`; the
    1e-15 absolute term for samples where both are zero, such as the start)."""
    excess = observed - bound * (1.0 + ROUNDING) - 1e-15
    k = int(np.argmax(excess))
    assert excess[k] <= 0.0, (k, observed[k], bound[k])


class ClassicPI:
    """u = Kc (e_r + (1/Ti) int e_r dt), e_r = r - y (the textbook form, [AM08] 10.1)."""

    def __init__(self, kc: float, ti: float, dt: float) -> None:
        self.kc, self.ti, self.dt, self.i = kc, ti, dt, 0.0

    def step(self, y: float, r: float, r_dot: float = 0.0) -> float:
        e = r - y
        self.i += e * self.dt
        return self.kc * (e + self.i / self.ti)


# ------------------------------------------------------------------------------------------
# validation
# ------------------------------------------------------------------------------------------
@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        (dict(nu=1, alpha=0.0, window=10, dt=0.01), r"alpha = 0\.0"),
        (dict(nu=1, alpha=1.0, window=10, dt=0.0), r"dt = 0\.0 s"),
        (dict(nu=1, alpha=1.0, window=10, dt=-0.01), r"dt = -0\.01 s"),
        (dict(nu=1, alpha=1.0, window=10, dt=float("nan")), r"dt = nan s"),
        (dict(nu=1, alpha=1.0, dt=0.01, window=1), r"window = 1 samples.*at least 2"),
        (dict(nu=2, alpha=1.0, dt=0.01, window=2), r"window = 2 samples.*at least 3"),
        (dict(nu=2, alpha=1.0, dt=0.01, window=5, derivative="model", derivative_window=2),
         r"derivative_window = 2"),
        (dict(nu=2, alpha=1.0, dt=0.01, window=5, derivative_window=1), r"derivative_window = 1"),
        (dict(nu=3, alpha=1.0, window=10, dt=0.01), r"nu = 3"),
        (dict(nu=1, alpha=1.0, window=10, dt=0.01, kp=-1.0), r"kp = -1\.0"),
        (dict(nu=1, alpha=1.0, window=10, dt=0.01, kd=1.0), r"kd = 1\.0"),
        (
            dict(nu=1, alpha=1.0, window=10, dt=0.01, u_min=1.0, u_max=1.0),
            r"u_min = 1\.0, u_max = 1\.0",
        ),
        (dict(nu=1, alpha=1.0, window=10, dt=0.01, rate_max=0.0), r"rate_max = 0\.0"),
        (dict(nu=1, alpha=1.0, window=10, dt=0.01, estimator="fancy"), r"estimator = 'fancy'"),
        (dict(nu=1, alpha=1.0, window=10, dt=0.01, anti_windup="x"), r"anti_windup = 'x'"),
        # a list where a name is expected: a named ValueError, not "unhashable type"
        (dict(nu=1, alpha=1.0, window=10, dt=0.01, estimator=["algebraic"]),
         r"estimator = \['algebraic'\]"),
        (dict(nu=2, alpha=1.0, window=10, dt=0.01, derivative=["model"]),
         r"derivative = \['model'\]"),
    ],
)
def test_bad_parameters_raise_valueerror_with_value(kwargs, match):
    with pytest.raises(ValueError, match=match):
        IntelligentParams(**kwargs)


@pytest.mark.parametrize(
    ("nu", "kwargs", "message"),
    [
        (1, {}, "time_constant = None: required for nu = 1 (the error's time constant, s)"),
        (1, dict(time_constant=-1.0), "time_constant = -1.0 s: must be > 0"),
        (1, dict(time_constant=0.2, natural_frequency=3.0),
         "natural_frequency = 3.0 rad/s: not used for nu = 1 (give time_constant)"),
        (1, dict(time_constant=0.2, damping=0.7),
         "damping = 0.7: not used for nu = 1 (give time_constant)"),
        (1, dict(time_constant=0.2, natural_frequency=3.0, damping=0.7),
         "natural_frequency = 3.0 rad/s, damping = 0.7: not used for nu = 1 (give time_constant)"),
        (1, dict(time_constant=0.2, integral_pole=-2.0), "integral_pole = -2.0 1/s: must be > 0"),
        (2, dict(natural_frequency=3.0),
         "natural_frequency = 3.0 rad/s, damping = None: both required for nu = 2"),
        (2, dict(natural_frequency=3.0, damping=0.7, time_constant=0.2),
         "time_constant = 0.2 s: not used for nu = 2 (give natural_frequency, damping)"),
        (2, dict(natural_frequency=0.0, damping=0.7), "natural_frequency = 0.0 rad/s: must be > 0"),
        (2, dict(natural_frequency=3.0, damping=float("nan")), "damping = nan: must be finite"),
        (3, dict(time_constant=1.0), "nu = 3: must be 1 or 2"),
        (True, dict(time_constant=1.0), "nu = True: must be 1 or 2"),
    ],
)
def test_gain_helper_errors_name_the_field_and_the_value(nu, kwargs, message):
    # the whole message, not a fragment of it
    with pytest.raises(ValueError) as info:
        error_dynamics_gains(nu, **kwargs)
    assert str(info.value) == message


# ------------------------------------------------------------------------------------------
# gains: the characteristic polynomial of the designed error dynamics (sympy)
# ------------------------------------------------------------------------------------------
@pytest.mark.parametrize(
    ("nu", "kwargs", "poles"),
    [
        (1, dict(time_constant=0.25), [-4]),
        (1, dict(time_constant=0.25, integral_pole=1.5), [-4, sp.Rational(-3, 2)]),
        (2, dict(natural_frequency=3, damping=sp.Rational(1, 2)), None),
        (2, dict(natural_frequency=3, damping=sp.Rational(7, 10), integral_pole=2), None),
    ],
)
def test_error_dynamics_gains_place_the_designed_poles(nu, kwargs, poles):
    g = error_dynamics_gains(nu, **{k: float(v) for k, v in kwargs.items()})
    s = sp.symbols("s")
    kp, ki, kd = (sp.nsimplify(x, rational=True, tolerance=1e-12) for x in (g.kp, g.ki, g.kd))
    # closed-loop error equations of the module docstring (paper Section 3.2.2)
    if nu == 1:
        char = s * (s + kp) + ki if ki != 0 else s + kp
    else:
        char = s**3 + kd * s**2 + kp * s + ki if ki != 0 else s**2 + kd * s + kp
    if poles is None:
        wn, z = kwargs["natural_frequency"], kwargs["damping"]
        want = s**2 + 2 * z * wn * s + wn**2
        if "integral_pole" in kwargs:
            want = sp.expand(want * (s + kwargs["integral_pole"]))
    else:
        want = sp.expand(sp.prod([s - p for p in poles]))
    # exact rational arithmetic: the gains are rational functions of rational inputs
    assert sp.expand(char - want) == 0


# ------------------------------------------------------------------------------------------
# exactness on the ultra-local model itself (ZOH closed forms; rounding-level tolerances)
# ------------------------------------------------------------------------------------------
def test_model_derivative_weights_exact_on_the_nu2_model():
    # y'' = F + alpha u, F constant, u held on each interval: exact ZOH propagation.
    rng = np.random.default_rng(20240601)
    dt, alpha, f0 = 0.02, 1.7, -0.8
    for n in (3, 4, 7, 15):
        wy, wu = model_derivative_weights(n, dt)
        y, v = 0.3, -1.1
        ys, us, vs = [], [], []
        for _ in range(n + 5):
            u = float(rng.normal())
            ys.append(y)
            vs.append(v)
            us.append(u)
            acc = f0 + alpha * u
            y, v = y + v * dt + 0.5 * acc * dt * dt, v + acc * dt
        k = len(ys) - 1
        est = sum(wy[i] * ys[k - i] for i in range(n)) + alpha * sum(
            wu[j] * us[k - 1 - j] for j in range(n - 1)
        )
        # exact to rounding: |v| ~ 1, weights ~ 1/(n dt); measured <= 4.0e-15 over the four
        # windows: 1e-13 is 25x
        assert est == pytest.approx(vs[k], abs=1e-13)


def test_ip_error_obeys_the_exact_discrete_design_on_the_ultra_local_model():
    # Plant y' = F0 + alpha u exactly (b = alpha, F constant), ramp reference: F_hat = F0 exactly
    # and, within a held interval, e' = -Kp e_k, so e_{k+1} = (1 - Kp dt) e_k (closed form).
    dt, alpha, kp, f0, slope = 0.01, 2.5, 6.0, 0.7, 0.4
    c = IP(alpha=alpha, kp=kp, dt=dt, window=6)
    y = 1.0
    errs = []
    for k in range(80):
        t = k * dt
        u = c.step(y, slope * t, slope)
        if c.status.window_full:
            # exact estimator: rounding only, measured <= 9.5e-15; 2e-13 is 20x
            assert c.status.f_hat == pytest.approx(f0, abs=2e-13)
            errs.append(y - slope * t)
        y += (f0 + alpha * u) * dt
    errs = np.array(errs)
    # measured 2.2e-16 (|e| <= 1): 1e-14 is 45x
    np.testing.assert_allclose(errs[1:], (1.0 - kp * dt) * errs[:-1], rtol=0, atol=1e-14)


@settings(max_examples=30, deadline=None, derandomize=True)
@given(
    alpha=st.floats(0.2, 5.0) | st.floats(-5.0, -0.2),
    kp_dt=st.floats(0.01, 0.5),
    dt=st.floats(1e-3, 0.05),
    window=st.integers(2, 20),
    f0=st.floats(-10.0, 10.0),
    slope=st.floats(-2.0, 2.0),
)
def test_ip_exact_discrete_design_property(alpha, kp_dt, dt, window, f0, slope):
    # same closed form as above over random (alpha of either sign, gain, sample time, window)
    kp = kp_dt / dt
    c = IP(alpha=alpha, kp=kp, dt=dt, window=window)
    y, errs = 1.0, []
    for k in range(window + 15):
        u = c.step(y, slope * k * dt, slope)
        if c.status.window_full:
            errs.append(y - slope * k * dt)
        y += (f0 + alpha * u) * dt
    errs = np.array(errs)
    # rounding: |F0| <= 10 and weights ~ 1/(window dt) up to 1e3, but the error in e is that of
    # one step, dt (F_hat - F0): measured <= 4.0e-15 over 1500 random draws of these ranges
    # (including the extremes dt = 1e-3, window 20, |F0| = 10, Kp dt = 0.5); 2e-13 is 50x
    np.testing.assert_allclose(errs[1:], (1.0 - kp * dt) * errs[:-1], rtol=0, atol=2e-13)


@pytest.mark.parametrize("derivative", ["model", "algebraic"])
def test_ipd_error_obeys_the_exact_discrete_design_on_the_ultra_local_model(derivative):
    # y'' = F0 + alpha u exactly, parabolic reference. With the "model" derivative e' is exact,
    # so over one held interval e'' = -Kp e_k - Kd e'_k: [e, e']_{k+1} = Ad [e, e']_k with
    # Ad = [[1 - Kp dt^2/2, dt - Kd dt^2/2], [-Kp dt, 1 - Kd dt]]. The "algebraic" derivative is
    # exact on ramps only: on this run y is not a ramp and the recursion must NOT hold exactly
    # (which shows the check discriminates).
    dt, alpha, f0 = 0.01, 0.9, -1.3
    g = error_dynamics_gains(2, natural_frequency=5.0, damping=0.8)
    c = IPD(alpha=alpha, kp=g.kp, kd=g.kd, dt=dt, window=8, derivative=derivative)
    y, v = 0.5, 0.0
    ref = lambda t: (0.2 * t * t, 0.4 * t, 0.4)  # noqa: E731
    states = []
    for k in range(120):
        t = k * dt
        r, rd, rdd = ref(t)
        u = c.step(y, r, rd, rdd)
        if c.status.window_full:
            # rounding only (the nu = 2 weights ~ 1/(n dt)^2): measured <= 1.9e-13 with either
            # derivative; 2e-12 is ~10x
            assert c.status.f_hat == pytest.approx(f0, abs=2e-12)
            states.append((y - r, v - rd))
        acc = f0 + alpha * u
        y, v = y + v * dt + 0.5 * acc * dt * dt, v + acc * dt
    x = np.array(states)
    ad = np.array([[1 - g.kp * dt**2 / 2, dt - g.kd * dt**2 / 2], [-g.kp * dt, 1 - g.kd * dt]])
    pred = x[:-1] @ ad.T
    if derivative == "model":
        # measured 3.1e-15 (|e|, |e'| <= 1): 1e-13 is 30x
        np.testing.assert_allclose(x[1:], pred, rtol=0, atol=1e-13)
    else:
        assert np.abs(x[1:] - pred).max() > 1e-5


# ------------------------------------------------------------------------------------------
# the estimator sees the APPLIED input (after rate limit and saturation)
# ------------------------------------------------------------------------------------------
def test_estimator_fed_with_applied_input_under_saturation_and_rate_limit():
    # y' = F0 + alpha u exactly: F_hat must equal F0 at every step although the command is
    # clipped and rate-limited most of the time (with the commanded u it would be off by
    # alpha * (u_cmd - u_applied), O(1) here).
    dt, alpha, f0 = 0.01, 1.0, 2.0
    c = IPI(alpha=alpha, kp=8.0, ki=10.0, dt=dt, window=5, u_min=-1.0, u_max=0.5, rate_max=20.0)
    y, n_sat, n_rate = 0.0, 0, 0
    for k in range(300):
        t = k * dt
        r = 3.0 * math.sin(3.0 * t)
        u = c.step(y, r, 9.0 * math.cos(3.0 * t))
        st = c.status
        assert -1.0 <= u <= 0.5
        if st.window_full:
            # rounding only: measured <= 2.1e-14; 5e-13 is ~25x
            assert st.f_hat == pytest.approx(f0, abs=5e-13)
        n_sat += st.saturated != 0
        n_rate += st.rate_limited != 0
        y += (f0 + alpha * u) * dt
    assert n_sat > 50 and n_rate > 0  # the limits did bind


def test_set_applied_feeds_the_estimator_with_an_input_changed_after_the_controller():
    """An actuator clips the output to [-0.3, 0.3] without the controller knowing: told with
    intelligent_set_applied, F_hat stays exactly F0 (y' = F0 + alpha u_applied); not told, it is
    off by alpha (u_cmd - u_applied), which is O(1) here: the test can fail.
    """
    from flatfree.controllers.intelligent import intelligent_set_applied

    dt, alpha, f0 = 0.01, 1.0, 2.0
    errs = {}
    for told in (True, False):
        c = IP(alpha=alpha, kp=8.0, dt=dt, window=5)
        y, worst, clipped = 0.0, 0.0, 0
        for k in range(200):
            u = c.step(y, 3.0 * math.sin(3.0 * k * dt), 9.0 * math.cos(3.0 * k * dt))
            if c.status.window_full and k > 10:
                worst = max(worst, abs(c.status.f_hat - f0))
            ua = min(max(u, -0.3), 0.3)
            clipped += ua != u
            if told:
                intelligent_set_applied(c.params_array, c.state_array, ua)
            y += (f0 + alpha * ua) * dt
        errs[told] = worst
        assert clipped > 50
    assert errs[True] < 5e-13  # rounding only: measured 1.8e-14
    assert errs[False] > 0.1


def test_step_applied_feeds_the_estimator_as_set_applied_does():
    """``step(..., applied=)`` is intelligent_set_applied before the step: bit for bit the same
    outputs as the kernel called by hand; F_hat exact with the clipped input told (the test
    above), off when not told; a NaN ``applied`` (a lost feedback frame) is the own output."""
    from flatfree.controllers.intelligent import intelligent_set_applied

    dt, alpha, f0 = 0.01, 1.0, 2.0

    def run(mode):
        c = IP(alpha=alpha, kp=8.0, dt=dt, window=5)
        y, ua, out, worst = 0.0, None, [], 0.0
        for k in range(200):
            ref = (3.0 * math.sin(3.0 * k * dt), 9.0 * math.cos(3.0 * k * dt))
            if mode == "kernel" and ua is not None:
                intelligent_set_applied(c.params_array, c.state_array, ua)
            applied = {"step": ua, "nan": math.nan if k else None}.get(mode)
            u = c.step(y, *ref, applied=applied)
            if c.status.window_full and k > 10:
                worst = max(worst, abs(c.status.f_hat - f0))
            out.append(u)
            ua = min(max(u, -0.3), 0.3)
            y += (f0 + alpha * ua) * dt
        return out, worst

    by_step, worst_step = run("step")
    by_kernel, _ = run("kernel")
    assert by_step == by_kernel
    assert worst_step < 5e-13  # rounding only, as above
    by_none, worst_none = run("none")
    by_nan, _ = run("nan")
    assert by_nan == by_none
    assert worst_none > 0.1
    with pytest.raises(ValueError, match="applied = 'x'"):
        IP(alpha=1.0, kp=1.0, dt=dt, window=5).step(0.0, 0.0, applied="x")


def test_a_nu1_loop_ignores_the_second_derivative_it_does_not_use():
    """y_ref_ddot enters the law for nu = 2 only: an iP given NaN there runs its law as with
    0 (bit for bit); an iPD given NaN holds its output and counts a missing sample."""
    def run(cls, ddot, **kw):
        c = cls(alpha=2.0, kp=5.0, dt=0.01, window=10, **kw)
        y, out = 0.0, []
        for _ in range(100):
            u = c.step(y, 1.0, 0.0, ddot)
            out.append(u)
            y += 0.01 * 2.0 * u
        return out, c.status

    out_nan, st = run(IP, math.nan)
    assert out_nan == run(IP, 0.0)[0] and st.n_nonfinite == 0 and out_nan[-1] != 0.0
    out_nan, st = run(IPD, math.nan, kd=4.0)
    assert st.n_nonfinite == 100 and set(out_nan) == {0.0}  # warm-up steps counted too


def test_rate_limit_and_saturation_are_respected():
    dt, rate = 0.01, 5.0
    c = IP(alpha=1.0, kp=50.0, dt=dt, window=3, rate_max=rate, u_min=-2.0, u_max=2.0, u0=0.3)
    prev = 0.3
    y = 0.0
    for k in range(200):
        u = c.step(y, 10.0 * (k // 50 % 2) - 5.0)
        assert abs(u - prev) <= rate * dt + 1e-12
        assert -2.0 <= u <= 2.0
        prev = u
        y += (-y + u) * dt


# ------------------------------------------------------------------------------------------
# start-up, non-finite samples, reset, multi-loop, compiled use
# ------------------------------------------------------------------------------------------
def test_bumpless_start_holds_u0_until_the_window_is_full():
    c = IP(alpha=1.0, kp=1.0, dt=0.1, window=7, u0=0.25, u_max=0.2)
    outs = [c.step(float(k), 0.0) for k in range(6)]
    assert outs == [0.2] * 6  # u0 clipped to u_max, held while window not full
    assert not c.status.window_full and c.status.samples == 6
    c.step(6.0, 0.0)
    assert c.status.window_full


def test_nonfinite_measurement_holds_output_counts_and_flags():
    dt = 0.01
    c = IP(alpha=1.0, kp=4.0, dt=dt, window=5)
    assert c.step(float("nan"), 1.0) == 0.0  # before any finite sample: u0 held
    assert c.status.n_nonfinite == 1 and c.status.nonfinite and c.status.samples == 0
    y = 0.0
    for _ in range(30):
        u = c.step(y, 1.0)
        y += (0.5 + u) * dt
    u_last = u
    for bad in (float("nan"), float("inf"), -float("inf")):
        assert c.step(bad, 1.0) == u_last
        assert c.status.nonfinite
    assert c.step(y, float("nan")) == u_last  # a non-finite reference is held as well
    assert c.status.n_nonfinite == 5
    # then it recovers: finite output, flag cleared, tracking resumes
    for _ in range(200):
        u = c.step(y, 1.0)
        assert math.isfinite(u)
        y += (0.5 + u) * dt
    assert not c.status.nonfinite and c.status.n_nonfinite == 5
    assert abs(y - 1.0) < 1e-3  # constant F on y' = F + u: converges (exact estimator)


@pytest.mark.parametrize("arg", ["y", "y_ref", "y_ref_dot", "y_ref_ddot"])
@pytest.mark.parametrize("bad", ["a", None, True, np.array([1.0, 2.0]), [1.0], 1j])
def test_step_refuses_what_is_not_one_real_number_naming_the_argument(arg, bad):
    """Text, None, a boolean, an array or a complex number: a ValueError naming the argument and
    the value (not numba's TypeError), and the state is untouched (the next step is the one a
    fresh controller takes)."""
    c = IP(alpha=1.0, kp=4.0, dt=0.01, window=5)
    kw = dict(y=0.5, y_ref=1.0, y_ref_dot=0.0, y_ref_ddot=0.0)
    kw[arg] = bad
    with pytest.raises(ValueError, match=rf"^{arg} = {re.escape(repr(bad))}: expected a real"):
        c.step(**kw)
    assert c.status.samples == 0


def test_step_takes_ints_and_numpy_scalars_as_the_floats_they_are():
    ref = IPD(alpha=1.0, kp=4.0, kd=4.0, dt=0.01, window=5)
    c = IPD(alpha=1.0, kp=4.0, kd=4.0, dt=0.01, window=5)
    for k in range(12):
        y = float(k % 3)
        want = ref.step(y, 1.0, 0.0, 0.0)
        got = c.step([np.float64(y), np.float32(y), int(y), np.array(y)][k % 4], 1,
                     np.float32(0.0), np.int64(0))
        assert got == want and type(got) is float


@pytest.mark.parametrize("cls", [IP, IPD])
def test_an_overflowing_law_raises_naming_the_inputs_and_resets(cls):
    """Finite inputs of the order of 1e300 overflow the law (the compiled kernel returns NaN or
    inf): the shell raises instead, naming the inputs and the command, and resets the
    controller, whose window held the overflowed values (every later output would be NaN)."""
    gains = dict(kd=2.0) if cls is IPD else {}
    c = cls(alpha=2.0, kp=5.0, dt=0.01, window=10, u0=0.3, **gains)
    for _ in range(12):
        c.step(0.0, 0.0)
    with pytest.raises(ValueError, match=r"step\(y = 1e\+308, y_ref = 0\.0, .*the command u = "
                                         r"(nan|-?inf) is not finite.*controller was reset"):
        c.step(1e308, 0.0)
    assert c.status.samples == 0 and c.status.u == 0.3  # as after reset(): u0 held
    fresh = cls(alpha=2.0, kp=5.0, dt=0.01, window=10, u0=0.3, **gains)
    for k in range(15):  # and it works again, as a fresh controller
        assert c.step(0.1 * k, 1.0) == fresh.step(0.1 * k, 1.0)
    # a large reference overflows as well (the error e = y - y_ref)
    with pytest.raises(ValueError, match=r"y_ref = -1e\+308"):
        for _ in range(12):
            c.step(1e308, -1e308)


@pytest.mark.parametrize(("cls", "gains", "message"), [
    (IP, dict(ki=3.0), "ki = 3.0 1/s^2: must be 0 for an IP (use IPI for an integral term)"),
    (IP, dict(kd=1.0), "kd = 1.0 1/s: must be 0 for nu = 1 (iP, iPI)"),  # IntelligentParams'
    (IP, dict(ki="3"), "ki = '3' 1/s^2: expected a real number"),
    (IPD, dict(kd=1.0, ki=2.0),
     "ki = 2.0 1/s^3: must be 0 for an IPD (use IPID for an integral term)"),
    (IPI, dict(ki=1.0, kd=1.0), "kd = 1.0 1/s: must be 0 for nu = 1 (iP, iPI)"),
])
def test_a_shorthand_refuses_the_gains_it_fixes_at_zero(cls, gains, message):
    """IP(ki=3) used to give an iPI silently (its docstring says ki = kd = 0 fixed)."""
    with pytest.raises(ValueError, match=f"^{re.escape(message)}$"):
        cls(alpha=1.0, kp=1.0, dt=0.01, window=5, **gains)


def test_a_shorthand_takes_an_explicit_zero_for_a_gain_it_fixes():
    assert IP(alpha=1.0, kp=1.0, dt=0.01, window=5, ki=0.0, kd=0).params.ki == 0.0
    assert IPD(alpha=1.0, kp=1.0, kd=1.0, dt=0.01, window=5, ki=0.0).params.ki == 0.0


@pytest.mark.parametrize("nu", [1, 2])
def test_dropout_prediction_keeps_the_estimate_exact_on_the_ultra_local_model(nu):
    # y^(nu) = F0 + alpha u exactly: the one-step prediction used for a missing sample is then
    # exact (nu = 2: with the exact "model" derivative), so F_hat stays F0, to rounding, through
    # and after a dropout of 3 samples.
    dt, alpha, f0 = 0.01, 2.0, -0.4
    if nu == 1:
        c = IP(alpha=alpha, kp=3.0, dt=dt, window=6)
    else:
        c = IPD(alpha=alpha, kp=9.0, kd=6.0, dt=dt, window=6, derivative="model")
    y, v = 0.0, 0.3
    n_checked = 0
    for k in range(60):
        meas = float("nan") if 20 <= k < 23 else y
        u = c.step(meas, 0.5)
        if c.status.window_full and k >= 20:
            # rounding only: measured <= 2.7e-15 (nu = 1) and 3.6e-13 (nu = 2, weights
            # ~ 1/(n dt)^2): 5e-14 and 5e-12, ~15-20x
            assert c.status.f_hat == pytest.approx(f0, abs=5e-14 if nu == 1 else 5e-12)
            n_checked += 1
        acc = f0 + alpha * u
        if nu == 1:
            y += acc * dt
        else:
            y, v = y + v * dt + 0.5 * acc * dt * dt, v + acc * dt
    assert n_checked == 40 and c.status.n_nonfinite == 3


@pytest.mark.parametrize("nu, window, gap", [(1, 6, 4), (1, 30, 45), (2, 6, 4), (2, 40, 25),
                                             (2, 40, 55)])
def test_a_gap_ends_with_the_window_it_would_have_had(nu, window, gap):
    # y^(nu) = F + alpha u with F stepping by dF just after the last measured sample: the
    # prediction of the i-th missing sample, made with the F before the step, errs by exactly
    # dF dt^2 i^2 / 2 (nu = 2; dF dt i for nu = 1), which _end_gap's (i / (m + 1))^nu share of
    # the first measured sample's error undoes. So after the gap the window holds the samples
    # as measured: the controller's F and y' estimates equal, to rounding, those of a twin fed
    # every sample and told the same applied inputs. Windows of 30-40 take the sliding-moment
    # form, 6 the plain sums; gaps of 45 and 55 outlast their windows.
    dt, alpha, f0, df = 0.01, 2.0, 0.3, -0.7
    mk = ((lambda: IP(alpha=alpha, kp=3.0, dt=dt, window=window)) if nu == 1 else
          (lambda: IPD(alpha=alpha, kp=9.0, kd=6.0, dt=dt, window=window, derivative="model")))
    a, b = mk(), mk()
    k_gap = 2 * window + 3  # the first missing sample
    y, v = 0.1, 0.2
    worst_f = worst_d = u_last = 0.0
    for k in range(k_gap + gap + 20):
        missing = k_gap <= k < k_gap + gap
        u = a.step(float("nan") if missing else y, 0.5)
        b.step(y, 0.5, applied=None if k == 0 else u_last)
        if k >= k_gap + gap:  # from the first measured sample after the gap on
            sa, sb = a.status, b.status
            worst_f = max(worst_f, abs(sa.f_hat - sb.f_hat))
            worst_d = max(worst_d, abs(sa.error_rate - sb.error_rate))
        u_last = u
        acc = (f0 if k < k_gap - 1 else f0 + df) + alpha * u
        if nu == 1:
            y += acc * dt
        else:
            y, v = y + v * dt + 0.5 * acc * dt * dt, v + acc * dt
    assert a.status.n_nonfinite == gap and b.status.n_nonfinite == 0
    # rounding only (the old window, which met the step, erred by 0.5-4.2 in F)
    assert worst_f < 5e-12 and worst_d < 5e-12  # measured <= 4.3e-13 and 1.7e-14


def test_a_gap_while_the_window_fills_repeats_the_last_sample():
    # a plant at rest (y = 0, F = -0.5 against u0 = 0.5): a gap from the 4th sample fills the
    # window; with no F estimate yet its samples repeat the last one (the model's prediction
    # took F_hat = 0 once the count reached the window: a ramp, and F_hat -0.387 at the first
    # law step, a user's audit), so the first estimate is exact
    c = IP(alpha=1.0, kp=2.0, dt=0.01, window=10, u0=0.5)
    for k in range(60):
        u = c.step(math.nan if 3 <= k < 33 else 0.0, 0.0)
        if k >= 33:
            assert c.status.f_hat == pytest.approx(-0.5, abs=1e-14) and u == pytest.approx(0.5)


def _drive(c: IntelligentController, ys, refs) -> np.ndarray:
    return np.array([c.step(y, r, rd, rdd) for y, (r, rd, rdd) in zip(ys, refs, strict=True)])


def test_reset_then_same_inputs_gives_identical_outputs():
    rng = np.random.default_rng(7)
    ys = rng.normal(size=300)
    ys[[40, 41, 100]] = np.nan
    refs = rng.normal(size=(300, 3))
    for c in (
        IPI(alpha=1.3, kp=2.0, ki=1.0, dt=0.01, window=10, u_max=0.5, rate_max=30.0),
        IPID(alpha=0.7, kp=9.0, ki=4.0, kd=6.0, dt=0.01, window=10, derivative="model", u_min=-1.0),
    ):
        first = _drive(c, ys, refs)
        st1 = c.status
        c.reset()
        second = _drive(c, ys, refs)
        np.testing.assert_array_equal(first, second)  # bitwise: same code, same inputs
        assert c.status == st1


def test_independent_instances_multi_loop():
    rng = np.random.default_rng(11)
    ys = rng.normal(size=(200, 2))
    refs = rng.normal(size=(200, 3))
    mk = (
        lambda: IP(alpha=1.0, kp=2.0, dt=0.02, window=10),
        lambda: IPD(alpha=2.0, kp=4.0, kd=4.0, dt=0.02, window=10),
    )
    alone = [_drive(m(), ys[:, i], refs) for i, m in enumerate(mk)]
    a, b = mk[0](), mk[1]()
    inter = np.array([(a.step(y0, *r), b.step(y1, *r))
                      for (y0, y1), r in zip(ys, refs, strict=True)])
    np.testing.assert_array_equal(inter[:, 0], alone[0])
    np.testing.assert_array_equal(inter[:, 1], alone[1])


@numba.njit(cache=False)
def _compiled_loop(p, s, ys, refs, out):
    intelligent_reset(p, s)
    for k in range(ys.shape[0]):
        out[k] = intelligent_step(p, s, ys[k], refs[k, 0], refs[k, 1], refs[k, 2])


def test_compiled_kernel_callable_from_njit_matches_the_shell():
    rng = np.random.default_rng(3)
    ys = rng.normal(size=150)
    refs = rng.normal(size=(150, 3))
    c = IPID(alpha=1.1, kp=4.0, ki=1.0, kd=3.0, dt=0.01, window=7, derivative_window=5)
    shell = _drive(c, ys, refs)
    p = c.params_array
    s = make_state(p)
    out = np.empty(150)
    _compiled_loop(p, s, ys, refs, out)
    np.testing.assert_array_equal(out, shell)


# ------------------------------------------------------------------------------------------
# nu = 1 on y' = -a y^3 + b u (a, b unknown): first-order error dynamics
# ------------------------------------------------------------------------------------------
A_CUBIC, B_CUBIC, ALPHA_CUBIC = 1.0, 2.0, 1.5  # alpha/b = 0.75: alpha deliberately off


def _run_cubic(c: IntelligentController, dt: float, t_end: float, y0: float):
    """Columns t, y, r, r', u, F_hat, int e (one row per sample k)."""
    ref = lambda t: (0.5 + 0.3 * math.sin(2.0 * t), 0.6 * math.cos(2.0 * t))  # noqa: E731
    y = y0
    out = []
    for k in range(int(round(t_end / dt)) + 1):
        t = k * dt
        r, rd = ref(t)
        u = c.step(y, r, rd)
        st = c.status
        out.append((t, y, r, rd, u, st.f_hat, st.integral))
        y = rk4(lambda x, u=u: -A_CUBIC * x**3 + B_CUBIC * u, y, dt / 4, 4)
    return np.array(out)


def _cubic_deviation(dt: float, window: int, ki_pole: float | None = None):
    """``|e - e_design|`` at every sample from the first law step (e_design: the designed
    continuous error dynamics from the state there) and its bound from the sampled error equation
    (:func:`sampled_error_model`): ``|e_free - e_design| + env``, ``e_free`` the sampled design
    from the same start (its distance to the continuous one is the sampling's share) and ``env``
    the run's own F estimation error ``d`` (:func:`nu1_disturbance`) through ``|h|``
    (:func:`excursion_envelope`)."""
    tau = 0.2
    g = error_dynamics_gains(1, time_constant=tau, integral_pole=ki_pole)
    c = IntelligentController(
        IntelligentParams(nu=1, alpha=ALPHA_CUBIC, kp=g.kp, ki=g.ki, dt=dt, window=window)
    )
    o = _run_cubic(c, dt, 3.0, y0=1.5)
    k0 = window - 1  # first step with a full window: the law starts here
    t, y, r, rd, u, f_hat, integral = o[k0:].T
    t, e = t - t[0], y - r
    if ki_pole is None:
        ed = e[0] * np.exp(-t / tau)  # e' + Kp e = 0
    else:
        # state [I, e], I' = e, e' = -Kp e - Ki I, from the controller's own I at k0
        amat = np.array([[0.0, 1.0], [-g.ki, -g.kp]])
        ed = designed_error(amat, np.array([integral[0], e[0]]), t, 1)
    a, inputs, c_row = sampled_error_model(1, g.kp, g.ki, 0.0, dt)
    e_free = free_error(a, c_row, np.array([0.0, e[0]]), e.size)  # I_{k0-1} = 0
    d = nu1_disturbance(y, r, rd, u, f_hat, ALPHA_CUBIC, dt)
    bound = np.abs(e_free - ed) + excursion_envelope(a, inputs, c_row, [d])
    return np.abs(e - ed), bound


@pytest.mark.parametrize("ki_pole", [None, 2.0], ids=["iP", "iPI"])
def test_cubic_plant_error_follows_the_designed_first_order_dynamics(ki_pole):
    """The error follows the designed dynamics (e' + Kp e = 0; iPI: e'' + Kp e' + Ki e = 0)
    within the bound the error equation implies, at every sample: the sampling's share plus the
    run's own F estimation error through the disturbance-to-error impulse response
    (:func:`sampled_error_model`, :func:`excursion_envelope`). Its l1 form, the sampling's share
    plus ||h||_1 max|d| (iP: ||h||_1 = tau = 0.2 s; iPI: ||s / (s^2 + 7 s + 10)||_1 = 0.217 s),
    gives the summary: max deviation iP 0.0350 <= 0.107, iPI 0.0338 <= 0.150 (initial error
    0.71); the per-sample bound is tighter (peak 0.048) and is the one asserted. A law that
    drops F_hat or cancels only 90 % of it, mis-scales Kp or Ki or flips the reference term
    exceeds it (checked by hand, 2026-11-22)."""
    dev, bound = _cubic_deviation(0.01, 10, ki_pole)
    assert_within(dev, bound)
    # the deviation comes from the estimator's lag: halving dt at the same window length
    # (T halved) must shrink it; first order in T gives 0.5 asymptotically (measured 0.64 at
    # this coarse step), 0.75 fails a deviation that does not vanish with T.
    dev_half, bound_half = _cubic_deviation(0.005, 10, ki_pole)
    assert_within(dev_half, bound_half)
    assert dev_half.max() <= 0.75 * dev.max()


# ------------------------------------------------------------------------------------------
# nu = 2 on a mass with viscous and Coulomb friction (mass unknown)
# ------------------------------------------------------------------------------------------
M_MASS, C_VISC, F_COUL = 2.0, 0.8, 1.5  # kg, N s/m, N


def _run_mass(c: IntelligentController, dt: float, t_end: float):
    """Columns t, y, v, r, r', r'', u, F_hat, e'_hat, int e (one row per sample k)."""
    x = np.array([0.3, 0.0])

    def f(z, u):
        return np.array([z[1], (u - C_VISC * z[1] - F_COUL * np.sign(z[1])) / M_MASS])

    out = []
    for k in range(int(round(t_end / dt)) + 1):
        t = k * dt
        r, rd, rdd = 0.5 * math.sin(t), 0.5 * math.cos(t), -0.5 * math.sin(t)
        u = c.step(float(x[0]), r, rd, rdd)
        st = c.status
        out.append((t, x[0], x[1], r, rd, rdd, u, st.f_hat, st.error_rate, st.integral))
        x = rk4(lambda z, u=u: f(z, u), x, dt / 10, 10)
    return np.array(out)


@pytest.mark.parametrize("ki_pole", [None, 2.0], ids=["iPD", "iPID"])
def test_mass_with_friction_error_follows_the_designed_second_order_dynamics(ki_pole):
    """The error follows the designed second-order dynamics (iPID: with the integral pole).

    Derived bound, at every sample: the sampled error equation (:func:`sampled_error_model`,
    nu = 2) driven by the run's own disturbances ``d1``, ``d2`` (F - F_hat over each held
    interval, the reference's drift, and ``Kd (e' - e'_hat)``: the e' estimate's lag) through
    ``|h|`` (:func:`excursion_envelope`). Its l1 form is loose here (max deviation iPD 0.0077
    <= 0.055, iPID 0.0095 <= 0.107); the per-sample form asserted peaks at 0.019 and is reached
    to 98 % (iPD) and 88 % (iPID) at some sample. A law that drops F_hat, mis-scales Kp, Ki or
    Kd or flips the reference term exceeds it (checked by hand, 2026-11-22).

    Empirical bounds (not derived; measured 2026-11-22): at each velocity reversal F jumps by
    2 Fc / m; the estimator needs about a window to follow, an error impulse of about
    (2 Fc / m)(T / 2), and the critically damped error responds to an impulse with a peak
    1 / (wn e): that estimate times 2 (measured deviation 1.24x the estimate for the iPD, 1.53x
    for the iPID), and 5 % of the initial error (measured 3.0 %, 3.7 %). They guard the
    observed accuracy against a regression; they are not a correctness bound.
    """
    dt, n, wn = 0.01, 10, 4.0
    g = error_dynamics_gains(2, natural_frequency=wn, damping=1.0, integral_pole=ki_pole)
    alpha = 1.0 / 1.2  # the controller guesses m = 1.2 kg (true 2 kg)
    c = IntelligentController(
        IntelligentParams(nu=2, alpha=alpha, kp=g.kp, ki=g.ki, kd=g.kd, dt=dt, window=n)
    )
    o = _run_mass(c, dt, 8.0)
    k0 = n - 1
    t, y, v, r, rd, rdd, u, f_hat, ed_hat, integral = o[k0:].T
    t, e, ed = t - t[0], y - r, v - rd
    if ki_pole is None:
        amat = np.array([[0.0, 1.0], [-g.kp, -g.kd]])
        e_design = designed_error(amat, np.array([e[0], ed[0]]), t, 0)
    else:
        amat = np.array([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [-g.ki, -g.kp, -g.kd]])
        e_design = designed_error(amat, np.array([integral[0], e[0], ed[0]]), t, 1)
    dev = np.abs(e - e_design)
    # derived: the interval means of F - F_hat (plain: velocity increment; weighted:
    # position increment), less the reference's, plus the e' estimate's error times Kd
    lag = g.kd * (ed[:-1] - ed_hat[:-1])
    base = alpha * u[:-1] + f_hat[:-1] - rdd[:-1]
    d1 = np.diff(v) / dt - np.diff(rd) / dt - base + lag
    d2 = 2.0 * (np.diff(y) - dt * v[:-1] - np.diff(r) + dt * rd[:-1]) / dt**2 - base + lag
    a, inputs, c_row = sampled_error_model(2, g.kp, g.ki, g.kd, dt)
    e_free = free_error(a, c_row, np.array([0.0, e[0], ed[0]]), e.size)  # I_{k0-1} = 0
    assert_within(dev, np.abs(e_free - e_design) + excursion_envelope(a, inputs, c_row, [d2, d1]))
    # empirical (docstring)
    t_win = (n - 1) * dt
    assert dev.max() <= 2.0 * (2.0 * F_COUL / M_MASS) * (t_win / 2.0) / (wn * math.e)
    assert dev.max() <= 0.05 * abs(e[0])


# ------------------------------------------------------------------------------------------
# gain x0.3 / x3 during the run, 0-2 samples of input delay: iP vs a classic PI
# ------------------------------------------------------------------------------------------
A_DRAG, B_NOM = 0.5, 2.0


def run_gain_change(ctrl, factor: float, delay: int, dt: float = 0.01, t_end: float = 10.0,
                    record: list | None = None):
    """y' = -a y|y| + b(t) u(t - delay dt), b = B_NOM, then factor * B_NOM from t = 4 s.

    Returns the max |e| over t in [1, t_end] (after the start-up). ``record``, if given, receives
    one row (y, r, r', u, F_hat) per sample k (the last row: y and r only)."""
    y = 1.0
    queue = [0.0] * delay
    errs = []
    nk = int(round(t_end / dt))
    for k in range(nk):
        t = k * dt
        r, rd = 1.0 + 0.5 * math.sin(0.8 * t), 0.4 * math.cos(0.8 * t)
        queue.append(ctrl.step(y, r, rd))
        if record is not None:
            record.append((y, r, rd, queue[-1], ctrl.status.f_hat))
        ua = queue.pop(0)
        b = B_NOM * (1.0 if t < 4.0 else factor)
        y = rk4(lambda x, b=b, ua=ua: -A_DRAG * x * abs(x) + b * ua, y, dt / 4, 4)
        if not abs(y) < 1e6:
            return math.inf
        if t + dt >= 1.0:
            errs.append(abs(y - 1.0 - 0.5 * math.sin(0.8 * (t + dt))))
    if record is not None:
        record.append((y, 1.0 + 0.5 * math.sin(0.8 * nk * dt), math.nan, math.nan, math.nan))
    return max(errs)


def nominal_pi(dt: float) -> ClassicPI:
    # tuned on the nominal plant linearised at y = 1: y' = -2a dy + b u; closed-loop
    # characteristic polynomial s^2 + (2a + b Kc) s + b Kc / Ti = (s + 5)^2 (same 5 rad/s as
    # the iP's Kp = 5 /s)
    kc = (2 * 5.0 - 2 * A_DRAG) / B_NOM
    return ClassicPI(kc=kc, ti=B_NOM * kc / 25.0, dt=dt)


@pytest.mark.parametrize("factor", [0.3, 3.0])
@pytest.mark.parametrize("delay", [0, 1, 2])
def test_gain_change_and_input_delay_ip_keeps_tracking_and_beats_nominal_pi(factor, delay):
    dt = 0.01
    # alpha chosen at the top of the gain's range (2 b_nom): alpha/b stays in [0.67, 6.7],
    # away from the low edge that the delay moves up (alpha = b_nom diverges here with a
    # 1-sample delay once b = 3 b_nom: see the report / example)
    alpha, kp = 2.0 * B_NOM, 5.0
    ip = IP(alpha=alpha, kp=kp, dt=dt, window=10)
    rec = []
    e_ip = run_gain_change(ip, factor, delay, dt, record=rec)
    e_pi = run_gain_change(nominal_pi(dt), factor, delay, dt)
    # derived bound (sampled_error_model, nu = 1, Ki = 0), at every sample from t1 = 1 s on:
    # |e_k| <= (1 - Kp dt)^(k - k1) |e(t1)| + the run's own F - F_hat through |h|
    # (excursion_envelope; F relative to the controller's output: the delay and the gain
    # change are part of it). Its l1 form |e(t1)| + max|d| / Kp: measured max|e| 0.0125-0.0266
    # <= 0.0336-0.0441.
    y, r, rd, u, f_hat = np.array(rec)[round(1.0 / dt):].T
    e = y - r
    a, inputs, c_row = sampled_error_model(1, kp, 0.0, 0.0, dt)
    d = nu1_disturbance(y, r, rd, u, f_hat, alpha, dt)
    assert e_ip == pytest.approx(np.abs(e).max(), abs=1e-12)  # the same samples
    e_free = free_error(a, c_row, np.array([0.0, e[0]]), e.size)
    assert_within(np.abs(e), np.abs(e_free) + excursion_envelope(a, inputs, c_row, [d]))
    # the paper's claim, checked: the iP's worst error is below the nominal PI's on the same
    # run (measured PI 0.025-0.054)
    assert e_ip < e_pi


def test_low_alpha_with_delay_diverges_when_the_gain_triples():
    # the other side of the previous test (a measured limitation, documented): alpha = b_nom,
    # then b = 3 b_nom (alpha/b = 1/3) with a one-sample input delay
    ip = IP(alpha=B_NOM, kp=5.0, dt=0.01, window=10)
    assert run_gain_change(ip, 3.0, 1) > 1.0


# ------------------------------------------------------------------------------------------
# saturation: the integral does not wind up
# ------------------------------------------------------------------------------------------
def _smoothstep(t, t0, t1, a0, a1):
    if t <= t0:
        return a0, 0.0
    if t >= t1:
        return a1, 0.0
    s = (t - t0) / (t1 - t0)
    return a0 + (a1 - a0) * (3 * s * s - 2 * s**3), (a1 - a0) * (6 * s - 6 * s * s) / (t1 - t0)


def _run_saturation(anti_windup: str, dt: float = 0.01, t_end: float = 7.0):
    # y' = -y + 1.5 u with |u| <= 1 (reachable |y| <= 1.5); the reference goes to 3 (out of
    # reach) and back to 1. Exact ZOH propagation of the linear plant.
    g = error_dynamics_gains(1, time_constant=0.2, integral_pole=2.0)
    c = IPI(alpha=2.0, kp=g.kp, ki=g.ki, dt=dt, window=10, u_min=-1.0, u_max=1.0,
            anti_windup=anti_windup)
    ref = lambda t: _smoothstep(t, 0.5, 1.0, 0.5, 3.0) if t < 3 else _smoothstep(  # noqa: E731
        t, 3.0, 3.5, 3.0, 1.0
    )
    y, out = 0.5, []
    ed = math.exp(-dt)
    for k in range(int(round(t_end / dt))):
        t = k * dt
        r, rd = ref(t)
        u = c.step(y, r, rd)
        st = c.status
        out.append((t, y - r, st.saturated, st.integral, y, r, rd, u, st.f_hat))
        y = y * ed + 1.5 * u * (1.0 - ed)
    return np.array(out), g


def test_saturation_integral_does_not_wind_up():
    """After release the error follows the designed iPI dynamics from its state at release
    (the frozen integral only adds the designed slow mode, pole -2 /s), within the bound the
    error equation implies, at every sample, as in the cubic-plant test: the sampling's share
    ``|e_free - e_design|`` (the sampled design from ``(I_{k-1}, e_k)`` at release) plus the
    run's own F estimation error through ``|h|`` (:func:`excursion_envelope`). No limit binds
    after release, so the identity of :func:`sampled_error_model` holds there (it reproduces
    the run's errors to 6e-17). Measured: max deviation 0.00280 (at 0.21 s after release)
    against a bound peaking at 0.00288 (sampling 0.00093, estimation 0.00218), reached to 97 %
    at that sample; the former fixed 0.05 was 18x the deviation. A wound-up integral (anti-
    windup "none") starts from a wrong I and fails the recovery check below."""
    o, g = _run_saturation("clamp")
    sat = np.nonzero(o[:, 2])[0]
    assert o[sat[0], 0] < 1.0 and o[sat[-1], 0] > 3.0  # the limit did bind for > 2 s
    k_rel = sat[-1] + 1  # first unsaturated sample after the long saturation
    t_rel = o[k_rel, 0]
    amat = np.array([[0.0, 1.0], [-g.ki, -g.kp]])
    tt = o[k_rel:, 0] - t_rel
    e_design = designed_error(amat, np.array([o[k_rel, 3], o[k_rel, 1]]), tt, 1)
    y, r, rd, u, f_hat = o[k_rel:, 4:9].T
    e = y - r
    a, inputs, c_row = sampled_error_model(1, g.kp, g.ki, 0.0, 0.01)
    # z_k = (I_{k-1}, e_k): the integral the controller carries into the release step
    e_free = free_error(a, c_row, np.array([o[k_rel - 1, 3], e[0]]), e.size)
    d = nu1_disturbance(y, r, rd, u, f_hat, 2.0, 0.01)
    bound = np.abs(e_free - e_design) + excursion_envelope(a, inputs, c_row, [d])
    assert_within(np.abs(e - e_design), bound)
    # stated recovery: |e| <= 0.02 (1 % of the swing) from 1.5 s after release on
    late = o[:, 0] >= t_rel + 1.5
    assert np.abs(o[late, 1]).max() <= 0.02
    # without anti-windup the same run does not recover within the run (shows the test bites)
    o_none, _ = _run_saturation("none")
    assert np.abs(o_none[late, 1]).max() > 0.2


# ------------------------------------------------------------------------------------------
# the choice of alpha: y' = F(t) + b u, b unknown
# ------------------------------------------------------------------------------------------
class AlphaRun(NamedTuple):
    """``worst``: max |e| over the second half (inf when |y| exceeded 1e6); ``excess``: the
    largest ``|e_k| - bound_k`` there (as in :func:`assert_within`: <= 0 when the bound holds),
    ``bound_k`` derived from the error equation (sampled_error_model, nu = 1, Ki = 0:
    ``(1 - Kp dt)^(k - k1) |e_k1|`` plus the run's own F estimation error through ``|h|``; nan
    when diverged); ``quarters``: max |e| over each quarter of the run."""

    worst: float
    excess: float
    quarters: tuple


def _alpha_run(ratio: float, estimator: str, window: int, b: float = 3.0, dt: float = 0.01,
               t_end: float = 20.0) -> AlphaRun:
    """The iP (Kp = 2 /s) on y' = F(t) + b u, F(t) = 0.2 + 0.3 sin t (exact ZOH integral),
    alpha = ratio * b; reference sin(0.5 t)."""
    alpha, kp = ratio * b, 2.0
    c = IP(alpha=alpha, kp=kp, dt=dt, window=window, estimator=estimator)
    y, rec = 0.0, []
    nk = int(round(t_end / dt))
    for k in range(nk + 1):
        t = k * dt
        r, rd = math.sin(0.5 * t), 0.5 * math.cos(0.5 * t)
        if k == nk:
            rec.append((y, r, rd, math.nan, math.nan))
            break
        u = c.step(y, r, rd)
        rec.append((y, r, rd, u, c.status.f_hat))
        y += 0.3 * (math.cos(t) - math.cos(t + dt)) + 0.2 * dt + b * u * dt
        if not abs(y) < 1e6:
            return AlphaRun(math.inf, math.nan, ())
    y, r, rd, u, f_hat = np.array(rec).T
    e = np.abs(y - r)
    k1 = nk // 2 + 1  # the second half: e at t_k, k > nk / 2
    a, inputs, c_row = sampled_error_model(1, kp, 0.0, 0.0, dt)
    d = nu1_disturbance(y[k1:], r[k1:], rd[k1:], u[k1:], f_hat[k1:], alpha, dt)
    bound = (np.abs(free_error(a, c_row, np.array([0.0, e[k1]]), nk + 1 - k1))
             + excursion_envelope(a, inputs, c_row, [d]))
    q = nk // 4
    return AlphaRun(float(e[k1:].max()), float((e[k1:] - bound * (1.0 + ROUNDING) - 1e-15).max()),
                    tuple(float(e[1 + i * q: 1 + (i + 1) * q].max()) for i in range(4)))


#: "Tracks": second-half max |e| below 5 % of the reference amplitude. Every run this test calls
#: tracking stays below 0.012; the growing one (0.22) reaches 0.45, the others diverge: the
#: threshold classifies with a factor 4 to 9 either side, it is not fitted to a value.
TRACKS = 0.05

def _docstring_alpha_table() -> list[tuple[float, float, str]]:
    """The table of the module docstring ("Stable range of alpha"): rows ``(lo, hi, max|e|)``,
    ``lo == hi`` unless a column names a range ("0.24-0.5"), the figure as printed (its
    decimals are the precision the docstring claims)."""
    import flatfree.controllers.intelligent as mod

    head = re.search(r"^\s*alpha/b\s+(.+)$", mod.__doc__, re.M)
    vals = re.search(r"^\s*max\|e\|\s+(.+)$", mod.__doc__, re.M)
    assert head and vals, "the module docstring lost its alpha table"
    cols, figs = head.group(1).split(), vals.group(1).split()
    assert len(cols) == len(figs) >= 5
    rows = []
    for col, fig in zip(cols, figs, strict=True):
        lo, _, hi = col.partition("-")
        rows.append((float(lo), float(hi or lo), fig))
    return rows


def test_alpha_sweep_records_the_stable_range():
    """The claims of the module docstring ("Stable range of alpha"), run here: bounded from
    alpha/b = 0.24 to 50, diverged at 0.2, a growing oscillation at 0.22; the edge at window 5
    (between 0.24 and 0.28: about 0.26) and below 0.2 at window 20; the simple variant's edges
    (window 2: the closed-form alpha/b > 1/2). Every finite run also meets the error equation's
    derived bound (``excess <= 0``: that, and the divergence / tracking classification, are the
    correctness checks).

    The docstring's table of worst errors is the controller's own output on these runs, not a
    derived figure: it is not a reference here. What is checked is that the docstring states
    what the runs give, at the precision it prints (parsed from the docstring, not copied into
    the test): a change of the controller that moves a figure fails until the docstring is
    updated."""
    table = _docstring_alpha_table()
    # the ratios the docstring names, plus two inside its "0.24-0.5" range
    in_range = {lo for lo, _, _ in table} | {hi for _, hi, _ in table} | {0.26, 0.3}
    ratios = sorted({0.2, 0.22, *in_range})
    runs = {r: _alpha_run(r, "algebraic", 10) for r in ratios}
    for r, run in runs.items():
        if math.isfinite(run.worst):
            assert run.excess <= 0.0, (r, run)
    for r in in_range:
        assert math.isfinite(runs[r].worst), (r, runs[r])  # "bounded from 0.24 to 50"
    for lo, hi, fig in table:  # docstring consistency, at its printed precision
        decimals = len(fig.partition(".")[2])
        for r, run in runs.items():
            if lo <= r <= hi:
                assert round(run.worst, decimals) == float(fig), (r, fig, run)
    # the lower edge: diverges at 0.2; at 0.22 an oscillation that grows every quarter and ends
    # well outside tracking (measured quarters 0.030, 0.071, 0.18, 0.45)
    assert runs[0.2].worst == math.inf
    q = runs[0.22].quarters
    assert math.isfinite(runs[0.22].worst) and q[0] < q[1] < q[2] < q[3] and q[3] > TRACKS
    # the edge moves with the window: window 5 diverges at 0.24, tracks at 0.28 (measured
    # 0.0025; 0.26 there is the edge itself: 110 after 20 s); window 20 tracks at 0.2 (0.012)
    edge = [_alpha_run(0.24, "algebraic", 5), _alpha_run(0.28, "algebraic", 5),
            _alpha_run(0.2, "algebraic", 20)]
    assert edge[0].worst == math.inf
    for run in edge[1:]:
        assert run.worst <= TRACKS and run.excess <= 0.0, run
    # the simple variant with window 2 (backward difference): the input recursion has the root
    # 1 - b/alpha, stable iff alpha/b > 1/2 (closed form); the docstring's 0.5 and 0.52 as well
    assert _alpha_run(0.45, "simple", 2).worst == math.inf
    assert _alpha_run(0.5, "simple", 2).worst == math.inf  # root -1: not asymptotically stable
    for r in (0.52, 0.55):
        run = _alpha_run(r, "simple", 2)
        assert run.worst <= TRACKS and run.excess <= 0.0, (r, run)
    # mixed with a windowed derivative the simple variant diverges even at alpha = b (and at 2);
    # it tracks from alpha/b = 3 on (measured 0.006) and at 20 does better than the algebraic
    # estimator there (the docstring's claim); the docstring prints its figure at 20 ("0.05 at
    # 20"): checked, as the table above, to state what the run gives
    assert _alpha_run(1.0, "simple", 10).worst == math.inf
    assert _alpha_run(2.0, "simple", 10).worst == math.inf
    run = _alpha_run(3.0, "simple", 10)
    assert run.worst <= TRACKS and run.excess <= 0.0, run
    run = _alpha_run(20.0, "simple", 10)
    assert run.excess <= 0.0, run
    assert run.worst < runs[20.0].worst
    import flatfree.controllers.intelligent as mod

    stated = re.search(r"\((\d+\.\d+) at 20:", mod.__doc__)
    assert stated, "the module docstring lost the simple variant's figure at alpha/b = 20"
    assert round(run.worst, len(stated.group(1).split(".")[1])) == float(stated.group(1)), run


# ------------------------------------------------------------------------------------------
# outside estimates: intelligent_step_external / intelligent_override
# ------------------------------------------------------------------------------------------
def _ipd_params(ki=0.0):
    """An iPD (window 60, moments on) with rate and saturation limits that bind now and then."""
    return IntelligentParams(nu=2, alpha=-50.0, dt=1e-3, window=60, kp=25.0, kd=10.0, ki=ki,
                             derivative="model", derivative_window=60, u_min=-0.05,
                             u_max=0.05, rate_max=5.0).to_array()


def _signal(k, rng):
    return 0.02 * math.sin(0.004 * k) + 1e-3 * rng.standard_normal()


@pytest.mark.parametrize("ki", [0.0, 3.0])
def test_outside_estimates_equal_to_the_windows_give_the_same_steps(ki):
    """Twin controllers on one noisy signal: A steps on its own estimates; B is given, through
    intelligent_step_external, the estimates A just formed (F, y, y'). B's outputs and state
    (rings, integral, flags) equal A's bit for bit, except the moments, which B leaves stale
    (M_VALID cleared): it skips exactly the window's own estimate. Then B steps on its own
    window again and follows A to round-off (its moments recomputed exactly: a warm fallback).
    Before the window is full, external is the plain step."""
    from flatfree.controllers.intelligent import IST, intelligent_step_external

    p = _ipd_params(ki)
    sa, sb = make_state(p), make_state(p)
    rng = np.random.default_rng(3)
    L = int(p[11])  # IPAR.L
    skip = {int(IST.M_VALID), int(IST.M_SINCE), *range(int(IST.MY), int(IST.MU) + 5)}
    keep = np.array([i for i in range(sa.size) if i not in skip])
    n_limited = 0
    for k in range(1500):
        y, yr, yrd, yrdd = _signal(k, rng), 0.01, 0.0, 0.0
        ua = intelligent_step(p, sa, y, yr, yrd, yrdd)
        if k < 1000:
            # A's estimates of this sample: F, y'; its e was formed from y itself
            ub = intelligent_step_external(p, sb, y, yr, yrd, yrdd, sa[IST.F_HAT], y,
                                           sa[IST.YDOT])
            assert ub == ua
            np.testing.assert_array_equal(sb[keep], sa[keep])
            if k >= L:  # full before this sample: the external form itself ran
                assert sb[IST.M_VALID] == 0.0
        else:
            ub = intelligent_step(p, sb, y, yr, yrd, yrdd)
            assert abs(ub - ua) <= 1e-12 * 0.05
        n_limited += sa[IST.SAT] != 0.0 or sa[IST.RATE] != 0.0
    assert 50 < n_limited < 1400  # the limits took part, not all the time


def test_outside_estimates_drive_the_law_and_fall_back_when_not_finite():
    """The law at outside estimates: u = -(F - y_ref'' + kp e + kd e') / alpha with
    e = y_hat - y_ref, e' = y_dot_hat - y_ref' (inside the limits). A NaN estimate or a window
    that is not full yet gives the plain step on the measurement instead."""
    from flatfree.controllers.intelligent import IST, intelligent_step_external

    p = IntelligentParams(nu=2, alpha=-50.0, dt=1e-3, window=30, kp=4.0, kd=3.0).to_array()
    s, t = make_state(p), make_state(p)
    for k in range(29):  # not full: the plain step, whatever the estimates
        assert intelligent_step_external(p, s, 1e-3 * k, 0.0, 0.0, 0.0, 7.0, 1.0, 1.0) == \
            intelligent_step(p, t, 1e-3 * k, 0.0, 0.0, 0.0)
    intelligent_step(p, s, 0.03, 0.0, 0.0, 0.0)
    intelligent_step(p, t, 0.03, 0.0, 0.0, 0.0)
    f, yh, ydh, yr, yrd, yrdd = 0.4, 0.011, -0.02, 0.01, 0.003, 0.2
    u = intelligent_step_external(p, s, 0.031, yr, yrd, yrdd, f, yh, ydh)
    expected = -(f - yrdd + 4.0 * (yh - yr) + 3.0 * (ydh - yrd)) / -50.0
    assert u == pytest.approx(expected, rel=1e-15)
    assert s[IST.F_HAT] == f and s[IST.YDOT] == ydh and s[IST.Y_LAST] == 0.031
    u_plain = intelligent_step(p, t, 0.031, yr, yrd, yrdd)
    assert u_plain != u
    # a NaN estimate: the plain step on the measurement, state and all
    s3, t3 = s.copy(), s.copy()
    assert intelligent_step_external(p, s3, 0.032, yr, yrd, yrdd, math.nan, yh, ydh) == \
        intelligent_step(p, t3, 0.032, yr, yrd, yrdd)
    np.testing.assert_array_equal(s3, t3)


@pytest.mark.parametrize("nu", [1, 2])
def test_correction_max_bounds_the_proportional_term_only(nu):
    """With correction_max c the law is u = -(F - y_ref^(nu) + clip(kp e, -c, c) + kd e') /
    alpha (kd e' for nu = 2 only): neither the damping term nor the feedforward -F + y_ref^(nu)
    is bounded. A proportional term within the bound gives the unbounded law bit for bit, a
    large kd e' included (the last case: kp e = 0.004, kd e' = 2.99); the default (inf) is the
    paper's."""
    from flatfree.controllers.intelligent import intelligent_step_external

    kd = 3.0 if nu == 2 else 0.0
    f, yr, yrd, yrdd = 0.4, 0.01, 0.003, 0.2
    ff_term = f - (yrdd if nu == 2 else yrd)
    # kp e above, below and within 1.5; the last with kd e' beyond it
    for yh, ydh in ((0.5, 0.2), (-0.5, -0.2), (0.011, -0.02), (0.011, 1.0)):
        p_term = 4.0 * (yh - yr)
        d_term = kd * (ydh - yrd) if nu == 2 else 0.0
        outs = []
        for cmax in (1.5, math.inf):
            p = IntelligentParams(nu=nu, alpha=-50.0, dt=1e-3, window=30, kp=4.0, kd=kd,
                                  correction_max=cmax).to_array()
            s = make_state(p)
            for k in range(30):  # fill the window
                intelligent_step(p, s, 1e-3 * k, 0.0, 0.0, 0.0)
            outs.append(intelligent_step_external(p, s, 0.031, yr, yrd, yrdd, f, yh, ydh))
        bounded, free = outs
        assert free == pytest.approx(-(ff_term + p_term + d_term) / -50.0, rel=1e-15)
        if abs(p_term) <= 1.5:
            assert bounded == free
        else:
            assert bounded == pytest.approx(
                -(ff_term + math.copysign(1.5, p_term) + d_term) / -50.0, rel=1e-15)
    with pytest.raises(ValueError, match=r"^correction_max = 0\.0 y-unit/s\^nu: must be > 0"):
        IntelligentParams(nu=2, alpha=1.0, dt=1e-3, window=30, correction_max=0.0)


def test_override_replaces_the_steps_output_against_the_previous_one():
    """intelligent_override after a step: the law at the outside estimates, limited against
    the output applied before that step (the rate limit shows it), the ring and U hold it; the
    integral is left as the step made it. Given the window's own estimates it changes nothing."""
    from flatfree.controllers.intelligent import (
        IPAR,
        IST,
        intelligent_override,
    )

    p = _ipd_params(ki=2.0)
    s = make_state(p)
    rng = np.random.default_rng(8)
    for k in range(200):
        intelligent_step(p, s, _signal(k, rng), 0.01, 0.0, 0.0)
    before = s.copy()
    u_prev = s[IST.U]
    u = intelligent_step(p, s, 0.02, 0.01, 0.0, 0.0)
    same = s.copy()
    assert intelligent_override(p, same, 0.02, 0.01, 0.0, 0.0, s[IST.F_HAT], 0.02,
                                s[IST.YDOT]) == u
    np.testing.assert_array_equal(same, s)
    # a large F: the law asks for a big step, the rate limit (5 rad/s, 1 ms) holds it to
    # u_prev + 0.005 (u_prev: before the step, not the step's own output)
    big = s.copy()
    v = intelligent_override(p, big, 0.02, 0.01, 0.0, 0.0, -1e3, 0.02, 0.0)
    assert v == max(u_prev - 5.0 * 1e-3, -0.05) and v != u
    assert big[IST.U] == v and (big[IST.RATE] == -1.0 or big[IST.SAT] == -1.0)
    assert big[IST.INTEGRAL] == s[IST.INTEGRAL]
    # the ring (IST docstring: header, y ring, u ring of 2 L each, every sample written twice):
    # the step moved the head by one, the override does not; the step's u slot (both copies)
    # holds v, the slot before it still u_prev, and nothing else in either ring changed
    L = int(p[IPAR.L])
    hs = int(IST.ESTIMATED) + 1  # the header: the moments' blocks, GAP, ESTIMATED
    ub, head = hs + 2 * L, int(s[IST.HEAD])
    assert head == (int(before[IST.HEAD]) - 1) % L and big[IST.HEAD] == head
    assert big[ub + head] == v and big[ub + head + L] == v
    assert big[ub + head + 1] == u_prev and s[ub + head] == u
    changed = np.nonzero(big[hs:] != s[hs:])[0] + hs
    assert set(changed.tolist()) <= {ub + head, ub + head + L}


def test_law_ran_tells_a_law_step_from_a_held_one():
    """intelligent_law_ran: False while the window fills (the start value held, no law), True
    once it is full, False at a held step (non-finite y or reference), True again after it;
    vehicle_step adds the yaw damper on law steps only."""
    p = IntelligentParams(nu=2, alpha=2.0, kp=4.0, kd=4.0, dt=0.01, window=10,
                          u0=0.5).to_array()
    s = make_state(p)
    ran = []
    out = [0.5]  # the start value, held first
    for k, y in enumerate([0.1] * 12 + [math.nan, 0.1, 0.1]):
        u = intelligent_step(p, s, y, 0.0, 0.0, 0.0 if k != 13 else math.nan)
        ran.append(intelligent_law_ran(p, s))
        if not ran[-1]:
            assert u == out[-1]  # held
        out.append(u)
    assert ran == [False] * 9 + [True] * 3 + [False, False, True]
