"""The Jacobi differentiator family: exactness, delay and cutoff helpers against measured
responses, the closed-form continuous delay, and the design rule (flatfree.estimators)."""

from __future__ import annotations

import math
import re

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.special import roots_jacobi

from flatfree.estimators import (
    JacobiDesign,
    Stream,
    causal_filter,
    cutoff,
    delay,
    design_for,
    predicted_rms,
    signal_std_estimate,
)


def _impulse_response(design: JacobiDesign) -> np.ndarray:
    """Measured: stream a unit impulse (after a zero history) through the filter."""
    s = Stream(design)
    s.update(0.0)  # prefill with zeros
    return np.array([s.update(1.0 if k == 0 else 0.0) for k in range(design.n + 5)])


# ---------------------------------------------------------------------------------------------
# exactness on polynomials
# ---------------------------------------------------------------------------------------------
@settings(max_examples=60, deadline=None)
@given(order=st.integers(0, 3), N=st.integers(0, 3), extra=st.integers(0, 60),
       kappa=st.sampled_from([-0.5, 0.0, 1.0, 2.5]), mu=st.sampled_from([-0.5, 0.0, 1.0]),
       lag_frac=st.sampled_from([None, 0.0, 0.1, 0.5]), seed=st.integers(0, 2**32 - 1))
def test_exact_on_polynomials_of_the_design_degree(order, N, extra, kappa, mu, lag_frac, seed):
    dt = 0.01
    n = order + N + 1 + extra
    T = (n - 1) * dt
    lag = "exact" if lag_frac is None else lag_frac * T
    d = JacobiDesign(n=n, dt=dt, order=order, N=N, kappa=kappa, mu=mu, lag=lag)
    rng = np.random.default_rng(seed)
    deg = d.degree  # order + N, one more at an "exact" evaluation point
    p = np.polynomial.Polynomial(rng.normal(size=deg + 1))
    t_now = 0.3
    y = p(t_now - np.arange(n) * dt)
    est = d.weights @ y
    ref = p.deriv(order)(t_now - delay(d)) if order else p(t_now - delay(d))
    # rounding only, of scale eps * sum|w||y| (|w| ~ 1/(T^order dt) over n samples; the
    # weights come from a least-squares solve): measured <= 1.1e-15 * sum|w||y| over 400 random
    # draws of these parameters (1.9e-15 in an earlier audit); 1e-12 is ~500x that, ~4500 eps
    assert abs(est - ref) <= 1e-12 * (np.abs(d.weights) @ np.abs(y))


def test_not_exact_one_degree_beyond():
    """The exactness claims are sharp: one degree more is not annihilated (for a float lag)."""
    d = JacobiDesign(n=41, dt=0.01, order=1, N=1, lag=0.0)
    t = -np.arange(41) * 0.01
    assert abs(d.weights @ t**3 - 0.0) > 1e-4  # d/dt t^3 at 0 is 0; the estimate is not


@pytest.mark.parametrize("kw", [dict(n=51), dict(n=101, N=1), dict(n=61, order=2, N=1),
                                dict(n=81, kappa=1.0, mu=1.0), dict(n=61, order=0, N=1, lag=0.0)])
def test_documented_degree_is_sharp(kw):
    """``degree`` (one more at an "exact" evaluation point) is exactly the exactness degree: the
    test above shows exactness at ``degree``; here ``(t/T)^(degree + 1)`` is not reproduced.
    Its error is O(1/T^order), far above the rounding bound of the exactness test."""
    d = JacobiDesign(dt=1e-3, **kw)
    y = (-np.arange(d.n) * d.dt / d.T) ** (d.degree + 1)
    p = np.polynomial.Polynomial.basis(d.degree + 1) / d.T ** (d.degree + 1)
    ref = p.deriv(d.order)(-d.delay) if d.order else p(-d.delay)
    # (threshold 1e-6 sum|w||y|, 1e6 times the exactness test's rounding bound)
    assert abs(d.weights @ y - ref) > 1e-6 * (np.abs(d.weights) @ np.abs(y))


@pytest.mark.parametrize("order,kappa,mu", [(1, 0.0, 0.0), (1, 1.0, 0.0), (1, 0.0, 2.0),
                                            (2, 1.0, 1.0), (0, 2.0, 0.0)])
def test_minimal_design_delay_tends_to_the_continuous_jacobi_value(order, kappa, mu):
    """N = 0: the delay is the mean zero of P_{order+1}^{(mu, kappa)} mapped to [0, T] (the
    continuous Jacobi estimator [MJF09]); scipy's Jacobi roots give the reference."""
    x, _ = roots_jacobi(order + 1, mu, kappa)  # weight (1-x)^mu (1+x)^kappa, x = 1 - 2 a / T
    for n in (201, 801, 3201):
        d = JacobiDesign(n=n, dt=1e-3, order=order, kappa=kappa, mu=mu)
        ref = d.T * (1 - x.mean()) / 2
        # discrete (Hahn) vs continuous (Jacobi) weight: a constant offset of a fraction of a
        # sample that does not grow with n (measured 0, 0.1 and 1/6 dt for these cases); the
        # bound dt/4 at three lengths shows the delay scales as the continuous one
        assert abs(delay(d) - ref) <= 0.25 * d.dt
    # closed form T (order + 1 + mu) / (2 order + 2 + kappa + mu), same as AlgDiff's N = 0 delay
    assert d.T * (1 - x.mean()) / 2 == pytest.approx(
        d.T * (order + 1 + mu) / (2 * order + 2 + kappa + mu), rel=1e-12)


# ---------------------------------------------------------------------------------------------
# delay and cutoff helpers agree with the measured responses
# ---------------------------------------------------------------------------------------------
DESIGNS = [
    dict(n=51),  # the paper's derivative kernel: delay T/2
    dict(n=101, N=1),  # low-delay (exact root)
    dict(n=101, N=1, lag=0.0),  # delay-free
    dict(n=151, N=3, kappa=2.0, lag=0.004),
    dict(n=81, kappa=1.0, mu=1.0),
    dict(n=61, order=2, N=1),
    dict(n=61, order=0, N=1, lag=0.0),  # the paper's denoiser, corrected
    dict(n=61, order=0),  # moving average: delay T/2
]


@pytest.mark.parametrize("kw", DESIGNS)
def test_delay_helper_matches_measured_impulse_response(kw):
    d = JacobiDesign(dt=1e-3, **kw)
    h = _impulse_response(d)
    r = d.order
    i = np.arange(h.size)
    # (1) moment: the filter applied to t^{r+1}/(r+1)! at t = 0 gives -delay, exactly up to
    # rounding: measured <= 4.6e-16 T over these designs; 1e-14 T is ~20x
    moment = -np.sum(h * (-i * d.dt) ** (r + 1)) / math.factorial(r + 1)
    assert moment == pytest.approx(delay(d), abs=1e-14 * d.T)
    # (2) phase of the measured response at a low frequency, relative to (j w)^r:
    # -arg/w tends to the delay with an O(w^2 T^3) correction; f = 0.002/T keeps it < 1e-4 T
    f = 0.002 / d.T
    H = np.sum(h * np.exp(-2j * np.pi * f * i * d.dt)) / (2j * np.pi * f) ** r
    assert -np.angle(H) / (2 * np.pi * f) == pytest.approx(delay(d), abs=1e-4 * d.T)
    if kw == dict(n=51) or kw == dict(n=61, order=0):
        assert delay(d) == pytest.approx(d.T / 2, rel=1e-12)


@pytest.mark.parametrize("kw", DESIGNS[:6])
def test_cutoff_helper_matches_measured_sine_response(kw):
    d = JacobiDesign(dt=1e-3, **kw)
    fc = cutoff(d)
    assert 0 < fc < 500
    # measured: filter a sine at fc, fit the steady-state output amplitude by least squares
    t = np.arange(6000) * d.dt
    y = np.sin(2 * np.pi * fc * t)
    out = causal_filter(d, y)[d.n:]
    tt = t[d.n:]
    A = np.column_stack((np.sin(2 * np.pi * fc * tt), np.cos(2 * np.pi * fc * tt)))
    c, *_ = np.linalg.lstsq(A, out, rcond=None)
    ratio = np.hypot(*c) / (2 * np.pi * fc) ** d.order
    # the LS fit is exact for a pure sine up to rounding: 1e-9 relative
    assert ratio == pytest.approx(1 / math.sqrt(2), rel=1e-9)


@pytest.mark.parametrize("fc, kw", [(10.0, dict(N=1)), (25.0, dict(order=2, kappa=1.0))])
def test_from_cutoff_picks_the_window_closest_to_the_target(fc, kw):
    """The documented promise: of all windows, the one whose cutoff (:func:`cutoff`, checked
    against the measured sine response above) is the closest to the target; checked against
    both neighbours (n - 1, n + 1: a bisection off by one fails) and five windows each side."""
    d = JacobiDesign.from_cutoff(fc, 1e-3, **kw)
    err = abs(cutoff(d) - fc)
    for n in range(d.n - 5, d.n + 6):
        if n != d.n:
            assert err <= abs(cutoff(JacobiDesign(n=n, dt=1e-3, **kw)) - fc)
    assert (d.order, d.N, d.kappa) == (kw.get("order", 1), kw.get("N", 0), kw.get("kappa", 0.0))


def test_from_window():
    assert JacobiDesign.from_window(0.05, 1e-3).n == 51
    assert JacobiDesign.from_window(0.0504, 1e-3).n == 51  # n = round(T / dt) + 1


# ---------------------------------------------------------------------------------------------
# the design rule
# ---------------------------------------------------------------------------------------------
RULE = dict(bandwidth_hz=2.0, noise_std=0.01, signal_std=0.7)


@pytest.fixture(scope="module")
def ruled():
    return design_for(1e-3, **RULE)


def test_rule_returns_a_local_minimum_of_its_criterion(ruled):
    d = ruled
    best = predicted_rms(d, **RULE)
    kw = dict(dt=d.dt, order=d.order, N=d.N, kappa=d.kappa, mu=d.mu, lag=d.lag)
    for dn in (-5, -1, 1, 5):  # neighbouring windows, same lag
        assert predicted_rms(JacobiDesign(n=d.n + dn, **kw), **RULE) >= best * (1 - 1e-12)
    for other in ({"kappa": 0.0}, {"N": max(d.N - 1, 0)}, {"N": d.N + 1}):
        kw2 = {**kw, **other}
        if kw2["N"] == 0:
            kw2["lag"] = "exact"
        assert predicted_rms(JacobiDesign(n=d.n, **kw2), **RULE) >= best * (1 - 1e-12)


def test_rule_prediction_matches_a_signal_drawn_from_its_own_model(ruled):
    """Band-limited flat-spectrum signal (many random-phase sines on [0, B]) + white noise:
    the realised RMS error equals the rule's prediction within sampling scatter."""
    d = ruled
    rng = np.random.default_rng(7)
    dt, B, S = 1e-3, RULE["bandwidth_hz"], RULE["signal_std"]
    t = np.arange(200_000) * dt
    f = (np.arange(400) + rng.uniform(size=400)) * B / 400  # stratified over [0, B]
    ph = rng.uniform(0, 2 * np.pi, 400)
    amp = S * math.sqrt(2 / 400)
    y = np.zeros_like(t)
    dy = np.zeros_like(t)
    for fk, pk in zip(f, ph, strict=True):
        y += amp * np.sin(2 * np.pi * fk * t + pk)
        dy += amp * 2 * np.pi * fk * np.cos(2 * np.pi * fk * t + pk)
    y += RULE["noise_std"] * rng.standard_normal(t.size)
    est = causal_filter(d, y)
    rms = np.sqrt(np.mean((est[d.n:] - dy[d.n:]) ** 2))
    # scatter of one realisation (400 random phases, 200 s): the ratio measured/predicted was
    # 0.978-1.007 over seeds 7-11; 5 % is about twice that spread
    assert rms == pytest.approx(predicted_rms(d, **RULE), rel=0.05)


def test_rule_respects_max_delay_and_reacts_to_noise():
    d0 = design_for(1e-3, **RULE, max_delay=0.0)
    assert delay(d0) == 0.0
    d2 = design_for(1e-3, **RULE, max_delay=0.002)
    assert delay(d2) <= 0.002 + 1e-15
    quiet = design_for(1e-3, **{**RULE, "noise_std": 0.001}, max_delay=0.0)
    # less noise -> the rule tolerates a larger noise gain for less bias
    assert quiet.noise_gain > d0.noise_gain


@pytest.mark.parametrize(
    "kw, text",
    [
        (dict(n=2, dt=1e-3, order=1, N=1), "n = 2: must be an integer >= 3"),
        (dict(n=10, dt=0.0), "dt = 0.0 s: must be > 0"),
        (dict(n=10, dt=True), "dt = True s: expected a real number"),
        (dict(n=10, dt=1e-3, kappa=-1.0), "kappa = -1.0: Jacobi exponent must be > -1"),
        (dict(n=10, dt=1e-3, mu="0"), "mu = '0': expected a real number"),
        (dict(n=10, dt=1e-3, mu=math.inf), "mu = inf: must be finite"),
        (dict(n=10, dt=1e-3, lag=0.5), "lag = 0.5 s: must lie in [0, T = 0.009000000000000001] s"),
        (dict(n=10, dt=1e-3, lag="fast"), "lag = 'fast': expected a time in s or \"exact\""),
        (dict(n=10, dt=1e-3, N=1, lag=True), "lag = True s: expected a real number"),
        (dict(n=10, dt=1e-3, order=-1), "order = -1: must be an integer >= 0"),
        (dict(n=30, dt=1e-3, order=6, N=7), "order + N = 13: the fit degree must be <= 12"),
    ],
)
def test_bad_designs_raise(kw, text):
    with pytest.raises(ValueError, match=f"^{re.escape(text)}$"):
        JacobiDesign(**kw)


def test_bad_alternative_constructor_inputs_raise():
    with pytest.raises(ValueError, match=r"^T = -1 s: must be > 0$"):
        JacobiDesign.from_window(-1, 1e-3)
    with pytest.raises(ValueError, match=r"^T = '0\.05' s: expected a real number$"):
        JacobiDesign.from_window("0.05", 1e-3)
    with pytest.raises(ValueError, match=re.escape("cutoff_hz = 600.0 Hz: must lie in (0, "
                                                   "Nyquist = 500.0) Hz") + "$"):
        JacobiDesign.from_cutoff(600.0, 1e-3)
    with pytest.raises(ValueError, match=r"^cutoff_hz = nan Hz: must be finite$"):
        JacobiDesign.from_cutoff(math.nan, 1e-3)


@pytest.mark.parametrize(
    "kw, text",
    [
        (dict(bandwidth_hz=600.0), "bandwidth_hz = 600.0 Hz: must lie in (0, 500.0) Hz (Nyquist)"),
        (dict(bandwidth_hz=math.nan), "bandwidth_hz = nan Hz: must be finite"),
        (dict(bandwidth_hz="2"), "bandwidth_hz = '2' Hz: expected a real number"),
        (dict(noise_std=-1), "noise_std = -1 (signal units): must be >= 0"),
        (dict(noise_std="0.01"), "noise_std = '0.01' (signal units): expected a real number"),
        (dict(noise_std=[0.01]), "noise_std = [0.01] (signal units): expected a real number"),
        (dict(signal_std=0.0), "signal_std = 0.0 (signal units): must be > 0"),
        (dict(signal_std=True), "signal_std = True (signal units): expected a real number"),
        (dict(max_delay=-0.1), "max_delay = -0.1 s: must be >= 0"),
        (dict(max_delay=math.inf), "max_delay = inf s: must be finite"),
    ],
)
def test_bad_rule_inputs_raise(kw, text):
    args = {**dict(bandwidth_hz=2.0, noise_std=0.01, signal_std=1.0), **kw}
    with pytest.raises(ValueError, match=f"^{re.escape(text)}$"):
        design_for(1e-3, **args)


# ---------------------------------------------------------------------------------------------
# signal_std_estimate: sqrt(max(var(y - linear trend) - noise_std^2, noise_std^2))
# ---------------------------------------------------------------------------------------------
def _cosine_plus_trend(A, m=1000, cycles=7):
    """y_i = A cos(2 pi cycles (i - c) / m) + 0.3 - 0.02 i, c = (m - 1)/2.

    By hand: the cosine is even about the centre c, so sum (i - c) cos = 0; with
    theta = 2 pi cycles / m, sum_i cos(theta (i - c)) = Re(e^{-j theta c} sum_i e^{j theta i})
    = 0 (a full geometric sum, cycles not a multiple of m). The cosine is thus orthogonal to
    1 and i: the least-squares line removes exactly the trend and the residual is the cosine.
    Its mean square is A^2/2 (1 + mean cos(2 theta (i - c))) = A^2 / 2 (same argument, 2 cycles
    not a multiple of m)."""
    i = np.arange(m, dtype=np.float64)
    return A * np.cos(2 * np.pi * cycles * (i - (m - 1) / 2) / m) + 0.3 - 0.02 * i


@pytest.mark.parametrize(
    "A, s, expected",
    [
        (2.0, 0.0, math.sqrt(2.0)),  # var A^2/2 = 2, no noise
        (2.0, 0.3, math.sqrt(2.0 - 0.09)),  # var - s^2
        (0.2, 0.3, 0.3),  # var 0.02 < 2 s^2 = 0.18: the floor s
    ],
)
def test_signal_std_estimate_follows_its_documented_formula(A, s, expected):
    y = _cosine_plus_trend(A)
    # rounding only: the residual is computed from O(20) numbers (the trend reaches -20)
    assert signal_std_estimate(y, s) == pytest.approx(expected, rel=1e-12)


def test_signal_std_estimate_stays_positive_without_variation_or_noise():
    """The documented floor: the residual of a zero record is exactly 0 and noise_std = 0, yet
    the estimate (a signal_std for design_for, which must be > 0) stays positive. The floor is
    max(noise_std^2, smallest normal float): here exactly sqrt(2.2e-308) = 1.49e-154."""
    S = signal_std_estimate(np.zeros(100), 0.0)
    assert S == math.sqrt(np.finfo(np.float64).tiny)
    design_for(1e-3, bandwidth_hz=2.0, noise_std=0.0, signal_std=S)  # accepted


@pytest.mark.parametrize(
    "y, s, text",
    [
        (np.ones(10), -1, "noise_std = -1 (signal units): must be >= 0"),
        (np.ones(10), math.nan, "noise_std = nan (signal units): must be finite"),
        (np.ones(10), None, "noise_std = None (signal units): expected a real number"),
        (np.ones(10), "abc", "noise_std = 'abc' (signal units): expected a real number"),
        (np.ones(10), True, "noise_std = True (signal units): expected a real number"),
        (np.ones(2), 0.1, "y: expected a 1-D record of at least 3 samples, got shape (2,)"),
        (np.ones((3, 3)), 0.1, "y: expected a 1-D record of at least 3 samples, got shape (3, 3)"),
        # no policy named: the function has no nonfinite argument (the text named one)
        (np.r_[1.0, 2.0, np.inf, 4.0], 0.1, "y[2] = inf: non-finite sample"),
        (np.r_[1.0, np.nan, np.nan], 0.1, "y[1] = nan: non-finite sample"),
    ],
)
def test_signal_std_estimate_refuses_bad_input(y, s, text):
    with pytest.raises(ValueError, match=f"^{re.escape(text)}$"):
        signal_std_estimate(y, s)
