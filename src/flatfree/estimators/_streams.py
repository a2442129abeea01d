"""Batch and streaming estimators: thin shells over the compiled FIR core (``_fir``)."""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from flatfree._validate import finite, nonnegative, real, real_array, whole
from flatfree.estimators._auto import design_for, signal_std_estimate
from flatfree.estimators._fir import (
    _HELD,
    NONFINITE,
    STARTUP,
    _policy,
    _stream_many,
    check_finite,
    fir_batch,
    fir_new,
    fir_reset,
    fir_update,
    nonfinite_message,
)
from flatfree.estimators._fweights import _check_dt, f_estimator_weights
from flatfree.estimators._jacobi import JacobiDesign

__all__ = [
    "SHRINK_MAX_TAPS", "Stream", "FEstimator", "causal_filter", "estimate_f", "differentiate",
    "f_update", "check_timestamps",
]

#: Longest window for ``startup="shrink"``: its table holds n (n - 1) / 2 floats (16 MB at 2048).
SHRINK_MAX_TAPS = 2048


def check_timestamps(t, dt: float | None = None, *, rtol: float = 1e-6) -> float:
    """Check that timestamps ``t`` (s) are uniform; return their period.

    Raises ``ValueError`` naming the first offending step (index and value) when a step differs
    from the period (``dt`` if given, else the mean step) by more than ``rtol`` relative; also
    for fewer than 2 timestamps, a non-finite timestamp (index and value), a non-positive mean
    step, and a ``dt`` or ``rtol`` that is not a finite real number (> 0, >= 0).
    """
    rtol = nonnegative("rtol", rtol)
    t = real_array("t", t)
    if t.ndim != 1 or t.size < 2:
        raise ValueError(f"t: expected at least 2 timestamps in a 1-D array, got shape {t.shape}")
    if not np.all(np.isfinite(t)):
        k = int(np.flatnonzero(~np.isfinite(t))[0])
        raise ValueError(f"t[{k}] = {float(t[k])!r} s: timestamps must be finite")
    steps = np.diff(t)
    ref = float(np.mean(steps)) if dt is None else _check_dt(dt)
    if ref <= 0.0:
        raise ValueError(f"t: timestamps must increase (mean step {ref!r} s)")
    bad = np.abs(steps - ref) > rtol * ref
    if bad.any():
        k = int(np.flatnonzero(bad)[0])
        raise ValueError(
            f"t[{k + 1}] - t[{k}] = {float(steps[k])!r} s: non-uniform timestamps "
            f"(expected step {ref!r} s within rtol {rtol})"
        )
    return ref


def _shrunk_design(design: JacobiDesign, c: int) -> np.ndarray:
    """Newest-first weights of the exact design of the same family on ``c`` samples: same
    exponents, the truncation order lowered until the fit fits (degree <= c - 1), the lag
    clipped to the shorter window; zeros when ``c <= order`` (no derivative is determined)."""
    if c <= design.order:
        return np.zeros(c)
    N = min(design.N, c - 1 - design.order)
    lag = design.lag
    if N == 0:
        lag = "exact"
    elif not isinstance(lag, str):
        lag = min(lag, (c - 1) * design.dt)
    return JacobiDesign(n=c, dt=design.dt, order=design.order, N=N, kappa=design.kappa,
                        mu=design.mu, lag=lag).weights


def _kernel_for(design, startup: str, nonfinite: str) -> np.ndarray:
    """A fresh kernel state (``_fir`` layout) for a JacobiDesign or raw weights."""
    if isinstance(design, JacobiDesign):
        w = design.weights
        if _policy("startup", startup, STARTUP) == 1:
            if design.n > SHRINK_MAX_TAPS:
                raise ValueError(
                    f'n = {design.n}: startup = "shrink" is limited to {SHRINK_MAX_TAPS} taps; '
                    'use "prefill"'
                )
            return fir_new(w, lambda c: _shrunk_design(design, c), startup=startup,
                           nonfinite=nonfinite)
        return fir_new(w, startup=startup, nonfinite=nonfinite)
    w = real_array("design", design)
    if _policy("startup", startup, STARTUP) == 1:
        raise ValueError('startup = "shrink" needs a JacobiDesign (raw weights have no shorter '
                         'designs)')
    return fir_new(w, startup=startup, nonfinite=nonfinite)


class Stream:
    """Streaming causal estimator: ``update(sample)`` returns the estimate at that sample.

    Parameters
    ----------
    design : JacobiDesign or array
        The design, or raw FIR weights (``w[i]`` multiplies the sample ``i`` steps back).
    startup : {"prefill", "shrink"}
        Start of the stream (fewer samples than the window). "prefill" (default): the first
        sample is taken as the whole past (signal at rest before it). "shrink": the exact
        design of the available shorter window (JacobiDesign only, ``n <= 2048``).
    nonfinite : {"raise", "hold"}
        A NaN/inf sample raises ``ValueError`` ("raise", default) or is replaced by the last
        finite sample ("hold"; ``ValueError`` when no finite sample has been seen yet). The
        error names the sample by its index, counted from 0 over the samples handed to
        :meth:`update` and :meth:`update_many` (pushed or refused) since construction or the
        last :meth:`reset`, and its value; a refused sample is not pushed.

    Attributes
    ----------
    state : ndarray
        The kernel state (configuration, weights, start-up table and ring buffer in one float
        array, layout in ``flatfree.estimators._fir``): pass it to :func:`fir_update` inside a
        compiled loop; :meth:`update` and the compiled call advance the same state.

    Notes
    -----
    O(taps) per sample in compiled code. ``Stream(d).update`` on a sequence equals
    :func:`causal_filter` on the same array to rounding: the two sum the same products in a
    different order (tests: within n eps * sum|w| * max|y|, n the taps).
    """

    __slots__ = ("design", "state", "_raise", "_k")

    def __init__(self, design, *, startup: str = "prefill", nonfinite: str = "raise") -> None:
        self.design = design
        self.state = _kernel_for(design, startup, nonfinite)
        self._raise = nonfinite == "raise"
        self._k = 0  # samples handed to update / update_many since the start or the reset

    def reset(self) -> None:
        """Forget every sample: the next update behaves as the first one."""
        fir_reset(self.state)
        self._k = 0

    def update(self, sample: float) -> float:
        """Push one sample; return the estimate at this sample."""
        k = self._k
        self._k = k + 1
        x = sample if isinstance(sample, float) else real(f"sample[{k}]", sample)
        if not math.isfinite(x) and (self._raise or not math.isfinite(self.state[_HELD])):
            raise ValueError(nonfinite_message("sample", k, float(x), self._raise))
        return fir_update(self.state, x)

    def update_many(self, samples) -> np.ndarray:
        """Push a sequence of samples (compiled loop); return the estimates.

        A sample the policy refuses raises ``ValueError`` (as :meth:`update`) after the samples
        before it have been pushed; the samples after it are not handed to the stream.
        """
        x = np.ascontiguousarray(real_array("samples", samples))
        out = np.empty(x.size)
        bad = ~np.isfinite(x)
        if bad.any():
            k = int(np.flatnonzero(bad)[0])
            # "hold" refuses only a non-finite sample with no finite one before it
            if self._raise or (k == 0 and not math.isfinite(self.state[_HELD])):
                _stream_many(self.state, x[:k], out[:k])
                k0 = self._k + k
                self._k = k0 + 1
                raise ValueError(nonfinite_message("sample", k0, float(x[k]), self._raise))
        _stream_many(self.state, x, out)
        self._k += x.size
        return out


def causal_filter(design, y, *, t=None, startup: str = "prefill",
                  nonfinite: str = "raise") -> np.ndarray:
    """Batch causal estimate: the output at ``k`` depends on ``y[:k+1]`` only.

    Parameters
    ----------
    design : JacobiDesign or array
        As in :class:`Stream`.
    y : array_like, shape (m,)
        Samples, uniformly spaced.
    t : array_like, optional
        Timestamps (s) of ``y``; checked uniform with the design's ``dt``
        (``ValueError`` otherwise).
    startup, nonfinite : str
        As in :class:`Stream`; the result equals streaming the samples one by one.

    Returns
    -------
    ndarray, shape (m,)
    """
    y = real_array("y", y)
    if y.ndim != 1:
        raise ValueError(f"y: expected a 1-D array, got shape {y.shape}")
    if t is not None:
        t = real_array("t", t)
        if t.shape != y.shape:
            raise ValueError(f"t: shape {t.shape} differs from y's {y.shape}")
        check_timestamps(t, design.dt if isinstance(design, JacobiDesign) else None)
    ks = _kernel_for(design, startup, nonfinite)
    y = check_finite(y, nonfinite)
    return fir_batch(ks, y)


def differentiate(y, dt, *, bandwidth_hz: float, noise_std: float, order: int = 1,
                  signal_std: float | None = None, max_delay: float | None = None,
                  nonfinite: str = "raise", return_design: bool = False):
    """Causal estimate of the ``order``-th derivative of a uniformly sampled signal.

    The design is chosen by the documented rule of :func:`design_for` (minimum predicted MSE
    for a signal of flat spectrum on ``[0, bandwidth_hz]`` plus white noise of ``noise_std``).

    Parameters
    ----------
    y : array_like, shape (m,)
        Samples.
    dt : float or array_like
        Sampling period, s, or the timestamps (s) of ``y`` (must be uniform).
    bandwidth_hz : float
        Highest frequency of interest of the signal, Hz.
    noise_std : float
        Standard deviation of the white measurement noise (units of y).
    order : int
        Derivative order (0: denoising).
    signal_std : float, optional
        Standard deviation of the noise-free signal; default :func:`signal_std_estimate` of y.
    max_delay : float, optional
        Upper bound on the design's delay, s.
    nonfinite : {"raise", "hold"}
        Policy for NaN/inf samples.
    return_design : bool
        Also return the chosen :class:`JacobiDesign`.

    Returns
    -------
    ndarray, shape (m,)
        Causal estimate (units of y / s^order); start-up "prefill" (signal at rest before
        ``y[0]``). With ``return_design``: ``(estimate, design)``.

    References
    ----------
    .. [MJF09] Mboup, Join, Fliess, Numer. Algorithms 50 (2009) 439-467.
    """
    y = real_array("y", y)
    if y.ndim != 1:
        raise ValueError(f"y: expected a 1-D array, got shape {y.shape}")
    if np.ndim(dt) == 0:
        dtv = _check_dt(dt)
    else:
        tt = real_array("dt", dt)
        if tt.shape != y.shape:
            raise ValueError(f"dt: timestamps of shape {tt.shape} differ from y's {y.shape}")
        dtv = check_timestamps(tt)
    yf = check_finite(y, nonfinite)
    if signal_std is None:
        signal_std = signal_std_estimate(yf, noise_std)
    design = design_for(dtv, bandwidth_hz=bandwidth_hz, noise_std=noise_std,
                        signal_std=signal_std, order=order, max_delay=max_delay)
    est = causal_filter(design, yf, startup="prefill", nonfinite=nonfinite)
    return (est, design) if return_design else est


# ---------------------------------------------------------------------------------------------
# F estimators (nu = 1, 2): y channel + alpha * input channel
# ---------------------------------------------------------------------------------------------
def _f_kernels(nu: int, n: int, dt: float, startup: str, nonfinite: str):
    wy, wu = f_estimator_weights(nu, n, dt)
    shrink = _policy("startup", startup, STARTUP) == 1
    _policy("nonfinite", nonfinite, NONFINITE)
    if shrink and n > SHRINK_MAX_TAPS:
        raise ValueError(f'n = {n}: startup = "shrink" is limited to {SHRINK_MAX_TAPS} taps')

    def y_start(c):  # exact shorter window; with c <= nu samples nothing is determined
        return f_estimator_weights(nu, c, dt)[0] if c >= nu + 1 else np.zeros(c)

    def u_start(c):  # input samples u[k-1..k-c+1] of the c-sample design (length c - 1);
        # with c <= nu samples: the at-rest value F = -alpha u[k-1]
        return f_estimator_weights(nu, c, dt)[1] if c >= nu + 1 else np.array([-1.0])

    ky = fir_new(wy, y_start if shrink else None, startup=startup, nonfinite=nonfinite)
    # the input channel holds n-1 taps but needs n pushes (u[k-1] arrives with y[k]) to be full
    ku = fir_new(wu, u_start if shrink else None, full=n, startup=startup, nonfinite=nonfinite)
    return ky, ku


@njit(cache=True)
def f_update(ks_y: np.ndarray, ks_u: np.ndarray, alpha: float, y: float, u_prev: float) -> float:
    """Compiled F-estimator step: push ``y[k]`` and ``u[k-1]``; return ``F_hat[k]``.

    ``ks_y``, ``ks_u``: the kernel states of an :class:`FEstimator` (``.state_y``,
    ``.state_u``).
    """
    return fir_update(ks_y, y) + alpha * fir_update(ks_u, u_prev)


class FEstimator:
    """Streaming algebraic estimator of F in ``y^(nu) = F + alpha u``.

    ``F_hat[k] = sum_i wy[i] y[k-i] + alpha sum_j wu[j] u[k-1-j]`` with the exact weights of
    :func:`f_estimator_weights` (window ``T = (n - 1) dt``).

    Parameters
    ----------
    nu : int
        1 or 2.
    n : int
        Window in samples (>= 2 for nu = 1, >= 3 for nu = 2).
    dt : float
        Sampling period, s.
    alpha : float
        The ultra-local model's input gain (units of y / s^nu per unit of u).
    startup : {"prefill", "shrink"}
        "prefill" (default): before the first sample the system was at rest, ``y`` constant at
        its first value under the first ``u_prev``, so the first estimate is ``-alpha u_prev``.
        "shrink": the exact estimator of the shorter window available (>= nu + 1 samples;
        before that the at-rest value ``-alpha u[k-1]``).
    nonfinite : {"raise", "hold"}
        Policy for NaN/inf in ``y`` or ``u`` ("hold": ``ValueError`` while that channel has no
        finite sample yet). The error names the channel (``y`` or ``u_prev``), the step index
        (counted from 0 over the calls to :meth:`update`, refused ones included, since
        construction or the last :meth:`reset`) and the value; a refused step pushes nothing.

    References
    ----------
    .. [P] paper eqs. (integral), (integral_2) corrected in NOTES.md "Algebraic estimators".
    """

    __slots__ = ("nu", "n", "dt", "alpha", "state_y", "state_u", "_raise", "_k")

    def __init__(self, nu: int, n: int, dt: float, alpha: float, *, startup: str = "prefill",
                 nonfinite: str = "raise") -> None:
        a = finite("alpha", alpha)
        self.state_y, self.state_u = _f_kernels(nu, n, dt, startup, nonfinite)
        self.nu, self.n, self.dt, self.alpha = int(nu), int(n), float(dt), a
        self._raise = nonfinite == "raise"
        self._k = 0  # calls to update since the start or the last reset

    def reset(self) -> None:
        """Forget every sample."""
        fir_reset(self.state_y)
        fir_reset(self.state_u)
        self._k = 0

    def update(self, y: float, u_prev: float) -> float:
        """Push the output ``y[k]`` and the input ``u[k-1]`` held over ``[t_{k-1}, t_k)``;
        return ``F_hat[k]``."""
        k = self._k
        self._k = k + 1
        yv = y if isinstance(y, float) else real(f"y[{k}]", y)
        uv = u_prev if isinstance(u_prev, float) else real(f"u_prev[{k}]", u_prev)
        if not (math.isfinite(yv) and math.isfinite(uv)):
            for name, v, ks in (("y", yv, self.state_y), ("u_prev", uv, self.state_u)):
                if not math.isfinite(v) and (self._raise or not math.isfinite(ks[_HELD])):
                    raise ValueError(nonfinite_message(name, k, float(v), self._raise))
        return f_update(self.state_y, self.state_u, self.alpha, yv, uv)


def estimate_f(y, u, *, nu: int, n: int, dt: float, alpha: float, u_before: float = 0.0,
               t=None, startup: str = "prefill", nonfinite: str = "raise") -> np.ndarray:
    """Batch twin of :class:`FEstimator`.

    Parameters
    ----------
    y : array_like, shape (m,)
        Outputs ``y[k]`` at ``t_k``.
    u : array_like, shape (m,)
        Inputs, ``u[k]`` held on ``[t_k, t_{k+1})`` (``u[m-1]`` is not used).
    u_before : float
        The input held before ``t_0`` (``u[-1]``).
    nu, n, dt, alpha, startup, nonfinite
        As in :class:`FEstimator`.
    t : array_like, optional
        Timestamps, checked uniform with ``dt``.

    Returns
    -------
    ndarray, shape (m,)
        ``F_hat[k]``, equal to streaming ``update(y[k], u[k-1])`` to rounding.
    """
    y = real_array("y", y)
    u = real_array("u", u)
    if y.ndim != 1 or u.shape != y.shape:
        raise ValueError(f"y, u: expected 1-D arrays of one shape, got {y.shape} and {u.shape}")
    whole("n", n, 2, strict=True)
    if t is not None:
        t = real_array("t", t)
        if t.shape != y.shape:
            raise ValueError(f"t: shape {t.shape} differs from y's {y.shape}")
        check_timestamps(t, dt)
    a = finite("alpha", alpha)
    ky, ku = _f_kernels(nu, n, dt, startup, nonfinite)
    ub = finite("u_before", u_before)
    if nonfinite == "raise":
        check_finite(u[:-1], "raise", "u")  # the error names u's own index
    up = check_finite(np.concatenate(([ub], u[:-1])), nonfinite, "u_prev")  # u[k-1] with y[k]
    y = check_finite(y, nonfinite, "y")
    return fir_batch(ky, y) + a * fir_batch(ku, up)
