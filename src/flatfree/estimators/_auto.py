"""Automatic design: choose a Jacobi differentiator from a bandwidth and a noise level.

The design rule (documented in :func:`design_for`)
-------------------------------------------------
Model the signal as band-limited white noise: a flat power spectrum of total variance ``S^2``
(``signal_std ** 2``) on ``[0, B]`` (``B = bandwidth_hz``), plus white measurement noise of
standard deviation ``sigma`` (``noise_std``). For a FIR design ``w`` with frequency response
``H(f)`` the expected mean-square error of the ``order``-th derivative estimate is then

    MSE(w) = (S^2 / B) * integral_0^B |H(f) - (j 2 pi f)^order|^2 df  +  sigma^2 * sum_i w_i^2

(bias from truncation and delay + noise variance). The rule returns the member of the discrete
Jacobi family that minimises this predicted MSE over

* truncation order ``N`` in 0..4 (fit degree ``order + N``),
* Jacobi exponent ``kappa`` in {0, 1, 2} at the old end of the window, ``mu = 0`` (newest
  samples never down-weighted),
* window length ``n`` (geometric grid refined to the sample, at most ``max_taps``),
* evaluation lag (whole samples) in ``[0, min(max_delay, T/2)]`` for ``N >= 1``.

Nothing in the rule depends on a particular test signal: its only inputs are ``B``, ``sigma``,
``S`` and ``dt`` (and the optional ``max_delay``). The delay is not fixed in advance: the phase
error it causes is part of the bias term, so the rule trades delay against noise itself.

References
----------
.. [MJF09] Mboup, Join, Fliess, Numer. Algorithms 50 (2009) 439-467 (bias/variance of the
   Jacobi estimators, choice of the truncation order).
.. [OKR22] Othmane, Kiltz, Rudolph, Int. J. Syst. Sci. (2022), doi:10.1080/00207721.2022.2025948
   (choosing the design in the frequency domain from a signal bandwidth and the noise).
"""

from __future__ import annotations

import functools
import math

import numpy as np
from numpy.polynomial import legendre as _leg

from flatfree._validate import finite, nonnegative, positive, real_array, whole
from flatfree.estimators._fir import check_finite
from flatfree.estimators._fweights import _check_dt
from flatfree.estimators._jacobi import JacobiDesign, _fit_operator

__all__ = ["design_for", "predicted_rms", "signal_std_estimate"]

_N_CHOICES = (0, 1, 2, 3, 4)
_KAPPA_CHOICES = (0.0, 1.0, 2.0)
_SIGNAL_UNITS = "(signal units)"
_NQUAD = 64  # Gauss-Legendre nodes on [0, B]: |H|^2 varies on the scale 1/T >= B/4, ample


def _quad(B: float, order: int):
    x, wq = _leg.leggauss(_NQUAD)
    f = 0.5 * (x + 1.0) * B
    return f, 0.5 * wq, (2j * np.pi * f) ** order  # mean over [0, B] = sum wq/2 g(f)


def _deriv_matrix(degree: int, order: int) -> np.ndarray:
    """C with legvander(x, degree) @ C = d^order/dx^order of P_0..P_degree at x."""
    c = np.zeros((degree + 1, degree + 1))
    for k in range(degree + 1):
        e = np.zeros(degree + 1)
        e[k] = 1.0
        d = _leg.legder(e, order) if order else e
        c[: d.size, k] = d
    return c


def _check_rule_inputs(dt, bandwidth_hz, noise_std, signal_std, order):
    dt = _check_dt(dt)
    order = whole("order", order, 0, strict=True)
    nyq = 0.5 / dt
    B = finite("bandwidth_hz", bandwidth_hz, "Hz")
    if not 0.0 < B < nyq:
        raise ValueError(f"bandwidth_hz = {bandwidth_hz!r} Hz: must lie in (0, {nyq}) Hz (Nyquist)")
    s = nonnegative("noise_std", noise_std, _SIGNAL_UNITS)
    S = positive("signal_std", signal_std, _SIGNAL_UNITS)
    return dt, B, s, S, order


def predicted_rms(design: JacobiDesign, *, bandwidth_hz: float, noise_std: float,
                  signal_std: float) -> float:
    """RMS error of ``design`` predicted by the rule's signal model (see :func:`design_for`).

    Units: signal units / s^order.
    """
    dt, B, s, S, order = _check_rule_inputs(design.dt, bandwidth_hz, noise_std, signal_std,
                                            design.order)
    f, wf, ideal = _quad(B, order)
    i = np.arange(design.n, dtype=np.float64)
    h = np.exp(-2j * np.pi * np.outer(f, i) * dt) @ design.weights
    bias2 = S * S * float(wf @ np.abs(h - ideal) ** 2)
    return math.sqrt(bias2 + s * s * float(design.weights @ design.weights))


def _candidate(n, N, kappa, order, dt, E, wf, ideal, S2, s2, max_lag_samples):
    """Best lag (whole samples) for one (n, N, kappa): returns (mse, lag_samples)."""
    degree = order + N
    _, sw, q, r = _fit_operator(n, degree, kappa, 0.0)
    qs = sw[:, None] * q  # W = qs @ Z, Z = R^-T D
    P = (E[0][:, :n] @ qs) + 1j * (E[1][:, :n] @ qs)  # H = P @ Z, (nf, degree+1); real BLAS
    K = qs.T @ qs
    half = 0.5 * (n - 1)
    if N == 0:
        lags = np.zeros(1)
    else:
        lmax = int(min(max_lag_samples, half))
        # whole samples; beyond 128 candidates a uniform subset (long lags are never optimal
        # for a low-delay design, and the criterion is smooth in the lag)
        lags = np.unique(np.linspace(0, lmax, min(lmax + 1, 129)).round())
    x0 = lags / half - 1.0
    D = (_leg.legvander(x0, degree) @ _deriv_matrix(degree, order)).T
    D *= (-1.0 / (half * dt)) ** order
    Z = np.linalg.solve(r.T, D)
    H = P @ Z
    bias2 = S2 * (wf @ (np.abs(H - ideal[:, None]) ** 2))
    noise2 = s2 * np.einsum("ij,ik,kj->j", Z, K, Z)
    mse = bias2 + noise2
    k = int(np.argmin(mse))
    return float(mse[k]), float(lags[k])


def design_for(dt: float, *, bandwidth_hz: float, noise_std: float, signal_std: float,
               order: int = 1, max_delay: float | None = None,
               max_taps: int = 20_000) -> JacobiDesign:
    """The Jacobi design chosen by the documented rule (module docstring of ``_auto``).

    Parameters
    ----------
    dt : float
        Sampling period, s.
    bandwidth_hz : float
        Highest frequency of interest in the signal, Hz, below Nyquist.
    noise_std : float
        Standard deviation of the white measurement noise (signal units), >= 0.
    signal_std : float
        Standard deviation of the noise-free signal (signal units), > 0; see
        :func:`signal_std_estimate` to estimate it from a record.
    order : int
        Derivative order (0 = denoising).
    max_delay : float, optional
        Upper bound on the delay, s; default: no bound beyond the window's half length (the
        rule's error criterion penalises delay by itself).
    max_taps : int
        Longest window considered, samples.

    Returns
    -------
    JacobiDesign
        Minimiser of the predicted MSE (see :func:`predicted_rms`) over the searched family.

    Notes
    -----
    Rule: minimise ``S^2 mean_{f in [0,B]} |H(f) - (j 2 pi f)^order|^2 + sigma^2 sum w^2`` over
    ``N in 0..4``, ``kappa in {0, 1, 2}``, ``mu = 0``, the window and the lag. A geometric
    grid of windows (ratio 1.15) is searched first, then the best window of each (N, kappa) is
    refined to the sample by a local integer search.

    References
    ----------
    .. [MJF09] Mboup, Join, Fliess, Numer. Algorithms 50 (2009) 439-467.
    .. [OKR22] Othmane, Kiltz, Rudolph, Int. J. Syst. Sci. (2022),
       doi:10.1080/00207721.2022.2025948.
    """
    dt, B, s, S, order = _check_rule_inputs(dt, bandwidth_hz, noise_std, signal_std, order)
    max_taps = whole("max_taps", max_taps, order + 2, strict=True)
    if max_delay is None:
        max_lag = md = math.inf
    else:
        md = nonnegative("max_delay", max_delay, "s")
        max_lag = md / dt + 1e-9
        md = md * (1.0 + 1e-12)
    # longest window worth trying: 4 periods of the bandwidth (bias dominates beyond)
    n_max = int(min(max_taps, math.ceil(4.0 / (B * dt)) + 1))
    f, wf, ideal = _quad(B, order)
    ph = 2.0 * np.pi * np.outer(f, np.arange(n_max, dtype=np.float64)) * dt
    E = (np.ascontiguousarray(np.cos(ph)), np.ascontiguousarray(-np.sin(ph)))
    S2, s2 = S * S, s * s

    cache: dict[tuple[int, float, int], tuple[float, int, float]] = {}

    def evaluate(N: int, kappa: float, n: int) -> tuple[float, int, float]:
        """(predicted MSE, n, best lag in samples) of one window, memoised."""
        key = (N, kappa, n)
        if key not in cache:
            mse, lag = _candidate(n, N, kappa, order, dt, E, wf, ideal, S2, s2, max_lag)
            # an N = 0 design's delay is intrinsic: it must respect max_delay too
            if (N == 0 and max_delay is not None
                    and JacobiDesign(n=n, dt=dt, order=order, kappa=kappa).delay > md):
                mse = math.inf
            cache[key] = (mse, n, lag)
        return cache[key]

    best = (math.inf, None)
    for N in _N_CHOICES:
        n_lo = order + N + 2  # at least one sample more than an interpolant
        if n_lo > n_max:
            continue
        for kappa in _KAPPA_CHOICES:
            ev = functools.partial(evaluate, N, kappa)  # the windows of this (N, kappa)
            steps = 1 + int(math.log(n_max / n_lo) / math.log(1.15))
            grid = np.unique(np.geomspace(n_lo, n_max, steps + 1).astype(int))
            k = int(np.argmin([ev(int(n))[0] for n in grid]))
            a = int(grid[max(k - 1, 0)])
            b = int(grid[min(k + 1, grid.size - 1)])
            cand = ev(int(grid[k]))
            # local integer refinement: ternary search on [a, b], then a short scan
            while b - a > 4:
                m1 = a + (b - a) // 3
                m2 = b - (b - a) // 3
                if ev(m1)[0] <= ev(m2)[0]:
                    b = m2
                else:
                    a = m1
            for n in range(a, b + 1):
                if ev(n)[0] < cand[0]:
                    cand = ev(n)
            if cand[0] < best[0]:
                best = (cand[0], (N, kappa, cand[1], cand[2]))
    if best[1] is None:
        raise ValueError(
            f"max_delay = {max_delay!r} s: no design of the family meets it "
            f"(dt = {dt} s, bandwidth_hz = {B} Hz)"
        )
    N, kappa, n, lag = best[1]
    lag_arg: float | str = "exact" if N == 0 else lag * dt
    return JacobiDesign(n=n, dt=dt, order=order, N=N, kappa=kappa, mu=0.0, lag=lag_arg)


def signal_std_estimate(y, noise_std: float) -> float:
    """Estimate of the noise-free signal's standard deviation from a record.

    ``sqrt(max(var(y - linear trend) - noise_std^2, noise_std^2))``: the linear trend is removed
    because every design of the family with ``N >= 0`` differentiates ramps exactly (a trend
    is no bias); the floor keeps the estimate positive for records dominated by noise. ``var``
    is the mean square of the least-squares residual (``1/m``, ``m`` samples).

    The variance floor is in fact ``max(noise_std^2, tiny)``, ``tiny =
    np.finfo(float).tiny = 2.2e-308`` (units of y^2; the smallest positive normal double), so
    the estimate is never below ``sqrt(tiny) = 1.5e-154`` (units of y). That second floor
    exists for ``noise_std = 0`` (or so small that its square underflows) with a residual of
    exactly 0, e.g. a constant record: the estimate would be 0, which :func:`design_for`
    refuses (``signal_std`` must be > 0), so :func:`differentiate` would raise on a noise-free
    constant. It changes nothing else: whenever ``noise_std >= 1.5e-154`` or the residual's
    mean square exceeds ``tiny``, the result is the formula above.

    Parameters
    ----------
    y : array_like, shape (m,)
        Uniformly spaced, finite samples, ``m >= 3``.
    noise_std : float
        Standard deviation of the white measurement noise (units of y), finite and >= 0.

    Raises
    ------
    ValueError
        Naming the field and the value: a record that is not 1-D with at least 3 samples, a
        non-finite sample, a ``noise_std`` that is not a finite real number >= 0 (text and
        booleans are not numbers).
    """
    s = nonnegative("noise_std", noise_std, _SIGNAL_UNITS)
    y = real_array("y", y)
    if y.ndim != 1 or y.size < 3:
        raise ValueError(f"y: expected a 1-D record of at least 3 samples, got shape {y.shape}")
    check_finite(y, None, "y")  # the first non-finite sample, as differentiate names it
    i = np.arange(y.size, dtype=np.float64)
    coef = np.polyfit(i - i.mean(), y, 1)
    r = y - np.polyval(coef, i - i.mean())
    v = float(np.mean(r * r))
    floor = max(s * s, np.finfo(float).tiny)
    return math.sqrt(max(v - s * s, floor))
