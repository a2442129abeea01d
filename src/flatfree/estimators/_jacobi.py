"""The algebraic (Jacobi) differentiator family, discretised exactly.

A design estimates the ``order``-th derivative of a sampled signal at the current sample from the
last ``n`` samples. It is the ``order``-th derivative, evaluated ``lag`` seconds in the past, of
the weighted least-squares polynomial of degree ``q = order + N`` fitted to the window, with the
discrete Jacobi (Hahn) weight

    w_j = binom(mu + j, j) * binom(kappa + n - 1 - j, n - 1 - j),   j = 0 .. n-1 (j = sample age),

which tends to ``(j dt)^mu (T - j dt)^kappa`` (the Jacobi weight of [MJF09]) as ``n`` grows.
``kappa`` shapes the OLDEST end of the window (``kappa > 0``: the weight vanishes there), ``mu``
the NEWEST end. The continuous algebraic estimators of [MJF09] are exactly these fits (Jacobi
truncated expansions) in the continuous limit; the paper's minimal kernels are ``kappa = mu = 0``,
``N = 0`` (derivative) and ``N = 1, lag = 0`` (denoising, NOTES.md kernel ``2T - 3d``).

Because the discrete weights come from a discrete fit, the FIR filter annihilates exactly the
polynomials it should: it returns ``y^(order)(t - lag)`` exactly for every polynomial of degree
``<= q``, whatever ``n`` (no quadrature leak).

Delay. For ``N >= 1`` the estimate of a polynomial of degree ``<= q`` is the derivative at
``t - lag``: the delay is ``lag`` (``lag = 0``: delay-free, extrapolating). For ``N = 0`` the
evaluation point is irrelevant (the ``order``-th derivative of a degree-``order`` fit is constant)
and the delay is intrinsic: the age at which the estimate is also exact for degree ``order + 1``,
the root of the ``order``-th derivative of the degree-``order + 1`` orthogonal residual. The same
root construction for ``N >= 1`` gives the low-delay design of [MJF09] (``lag="exact"``: one degree
of exactness more than the fit degree). In every case ``delay`` equals the low-frequency group delay
``-d arg(H(w) / (jw)^order) / dw`` at ``w -> 0`` of the discrete filter.

Cutoff. :func:`cutoff` is the lowest frequency at which the amplitude response relative to the
ideal differentiator, ``|H(f)| / (2 pi f)^order``, falls to ``1/sqrt(2)`` (-3 dB).

References
----------
.. [MJF09] M. Mboup, C. Join, M. Fliess, "Numerical differentiation with annihilators in noisy
   environment", Numerical Algorithms 50 (2009) 439-467.
.. [OKR22] A. Othmane, L. Kiltz, J. Rudolph, "Survey on algebraic numerical differentiation:
   historical developments, parametrization, examples, and applications", Int. J. Syst. Sci.
   (2022), doi:10.1080/00207721.2022.2025948 (frequency-domain parametrisation, as in AlgDiff).
.. [P] paper 000_81cd509a47ab99bc, Section 2.4, corrected in NOTES.md.
.. [KLS10] R. Koekoek, P. A. Lesky, R. F. Swarttouw, "Hypergeometric Orthogonal Polynomials and
   Their q-Analogues", Springer (2010), Section 9.5 (Hahn polynomials and their weight).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numpy.polynomial import legendre as _leg
from scipy.special import gammaln

from flatfree._validate import finite, positive, real_array, whole
from flatfree.estimators._fweights import _check_dt

__all__ = ["JacobiDesign", "jacobi_weights", "delay", "cutoff", "frequency_response"]

#: Largest polynomial degree q = order + N accepted (the Legendre-basis least squares stays
#: well conditioned far beyond; higher degrees are never useful for noisy data).
MAX_DEGREE = 12


def _hahn_weight(n: int, kappa: float, mu: float) -> np.ndarray:
    """Discrete Jacobi (Hahn) weight over ages 0..n-1, normalised to max 1:
    binom(mu + j, j) binom(kappa + n-1-j, n-1-j) ([KLS10] 9.5, alpha = mu, beta = kappa), the
    discrete counterpart of the Jacobi weight (j dt)^mu (T - j dt)^kappa of [MJF09]."""
    j = np.arange(n, dtype=np.float64)
    m = n - 1
    lw = (gammaln(mu + 1.0 + j) - gammaln(j + 1.0) - gammaln(mu + 1.0)) + (
        gammaln(kappa + 1.0 + m - j) - gammaln(m - j + 1.0) - gammaln(kappa + 1.0)
    )
    return np.exp(lw - lw.max())


def _fit_operator(n: int, degree: int, kappa: float, mu: float):
    """QR pieces of the weighted least-squares fit in the Legendre basis over x in [-1, 1]
    (x = -1 at age 0, the newest sample; x = +1 at age n-1)."""
    x = np.linspace(-1.0, 1.0, n) if n > 1 else np.zeros(1)
    sw = np.sqrt(_hahn_weight(n, kappa, mu))
    v = _leg.legvander(x, degree)
    q, r = np.linalg.qr(v * sw[:, None])
    return x, sw, q, r


def _deriv_row(degree: int, order: int, x0: float) -> np.ndarray:
    """d^order/dx^order of Legendre P_0..P_degree at x0."""
    row = np.zeros(degree + 1)
    for k in range(degree + 1):
        c = np.zeros(degree + 1)
        c[k] = 1.0
        row[k] = _leg.legval(x0, _leg.legder(c, order)) if order else _leg.legval(x0, c)
    return row


def jacobi_weights(
    n: int, dt: float, *, order: int = 1, N: int = 0, kappa: float = 0.0, mu: float = 0.0,
    lag_samples: float = 0.0,
) -> np.ndarray:
    """FIR weights ``w`` (``w[i]`` multiplies ``y[k-i]``) of a Jacobi design.

    Low-level form of :class:`JacobiDesign`: the ``order``-th derivative at age ``lag_samples``
    (in samples, may be fractional) of the Hahn-weighted least-squares polynomial of degree
    ``order + N`` over ``n`` samples. Units: 1/s^order.
    """
    degree = order + N
    _, sw, q, r = _fit_operator(n, degree, kappa, mu)
    half = 0.5 * (n - 1) if n > 1 else 1.0
    x0 = lag_samples / half - 1.0
    # time runs opposite to age: d/dt = -(1/(half dt)) d/dx
    d = _deriv_row(degree, order, x0) * (-1.0 / (half * dt)) ** order
    z = np.linalg.solve(r.T, d)
    return np.ascontiguousarray(sw * (q @ z))


def _exact_lag_roots(n: int, order: int, N: int, kappa: float, mu: float) -> np.ndarray:
    """Ages (in samples, ascending) in the window at which the design is also exact for degree
    q + 1: roots of the order-th derivative of the orthogonal residual of P_{q+1} ([MJF09] §4)."""
    degree = order + N
    x, sw, q, r = _fit_operator(n, degree, kappa, mu)
    p_next = _leg.legvander(x, degree + 1)[:, -1]
    coef = np.linalg.solve(r, q.T @ (sw * p_next))  # LS coefficients of P_{q+1}
    resid = np.zeros(degree + 2)
    resid[-1] = 1.0
    resid[:-1] -= coef
    droots = _leg.legroots(_leg.legder(resid, order)) if order else _leg.legroots(resid)
    droots = np.real(droots[np.abs(np.imag(droots)) < 1e-9])
    droots = droots[(droots >= -1.0 - 1e-12) & (droots <= 1.0 + 1e-12)]
    half = 0.5 * (n - 1)
    return np.sort((np.clip(droots, -1.0, 1.0) + 1.0) * half)


@dataclass(frozen=True, slots=True, kw_only=True)
class JacobiDesign:
    """A discrete algebraic (Jacobi) estimator of the ``order``-th derivative.

    Parameters
    ----------
    n : int
        Samples in the window (window ``T = (n - 1) dt``), ``n >= order + N + 1``.
    dt : float
        Sampling period, s.
    order : int
        Derivative order, >= 0 (0: denoising).
    N : int
        Truncation order: the fit degree is ``order + N``; ``0 <= N``, ``order + N <= 12``.
    kappa, mu : float
        Jacobi exponents, > -1: ``kappa`` at the oldest end of the window, ``mu`` at the newest.
    lag : float or "exact"
        Evaluation point of the derivative, s before the current sample, ``0 <= lag <= T``;
        ``0.0`` is the delay-free (extrapolating) design. ``"exact"`` (default) picks the
        smallest age that makes the design exact for one degree more ([MJF09] low-delay
        design); for ``N = 0`` the evaluation point does not change the weights, the delay
        is always the intrinsic one and ``lag`` is normalised to ``"exact"``.

    Attributes
    ----------
    weights : ndarray
        FIR weights, ``weights[i]`` multiplies ``y[k-i]``, 1/s^order.

    Notes
    -----
    Exact on every polynomial of degree ``order + N`` (module docstring). Build from a window
    in seconds with :meth:`from_window` or from a -3 dB frequency with :meth:`from_cutoff`.

    References
    ----------
    .. [MJF09] Mboup, Join, Fliess, Numer. Algorithms 50 (2009) 439-467.
    .. [OKR22] Othmane, Kiltz, Rudolph, Int. J. Syst. Sci. (2022),
       doi:10.1080/00207721.2022.2025948.
    """

    n: int
    dt: float
    order: int = 1
    N: int = 0
    kappa: float = 0.0
    mu: float = 0.0
    lag: float | str = "exact"
    lag_samples: float = field(init=False, repr=False, compare=False)
    weights: np.ndarray = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        whole("order", self.order, 0, strict=True)
        whole("N", self.N, 0, strict=True)
        if self.order + self.N > MAX_DEGREE:
            raise ValueError(
                f"order + N = {self.order + self.N}: the fit degree must be <= {MAX_DEGREE}"
            )
        whole("n", self.n, self.order + self.N + 1, strict=True)
        object.__setattr__(self, "n", int(self.n))
        object.__setattr__(self, "dt", _check_dt(self.dt))
        for name in ("kappa", "mu"):
            v = getattr(self, name)
            fv = finite(name, v)  # text, booleans, NaN, inf: ValueError
            if not fv > -1.0:
                raise ValueError(f"{name} = {v!r}: Jacobi exponent must be > -1")
            object.__setattr__(self, name, fv)
        T = (self.n - 1) * self.dt
        if isinstance(self.lag, str) and self.lag != "exact":
            raise ValueError(f'lag = {self.lag!r}: expected a time in s or "exact"')
        if not isinstance(self.lag, str):
            lv = finite("lag", self.lag, "s")
            if not 0.0 <= lv <= T * (1.0 + 1e-12):
                raise ValueError(f"lag = {self.lag!r} s: must lie in [0, T = {T!r}] s")
        if self.N == 0:
            # the weights do not depend on the evaluation point: normalise to the intrinsic one
            object.__setattr__(self, "lag", "exact")
        if self.lag == "exact":
            roots = _exact_lag_roots(self.n, self.order, self.N, self.kappa, self.mu)
            lag_s = float(roots[0]) if roots.size else 0.0
        else:
            object.__setattr__(self, "lag", lv)
            lag_s = min(lv / self.dt, self.n - 1.0)
        object.__setattr__(self, "lag_samples", lag_s)
        w = jacobi_weights(
            self.n, self.dt, order=self.order, N=self.N, kappa=self.kappa, mu=self.mu,
            lag_samples=lag_s,
        )
        w.setflags(write=False)
        object.__setattr__(self, "weights", w)

    # -- alternative constructors -------------------------------------------------------
    @classmethod
    def from_window(cls, T: float, dt: float, **kw) -> JacobiDesign:
        """Design with window ``T`` s: ``n = round(T / dt) + 1`` samples."""
        dt = _check_dt(dt)
        Tv = positive("T", T, "s")
        return cls(n=int(round(Tv / dt)) + 1, dt=dt, **kw)

    @classmethod
    def from_cutoff(cls, cutoff_hz: float, dt: float, **kw) -> JacobiDesign:
        """Design whose -3 dB frequency (:func:`cutoff`) is the closest to ``cutoff_hz``.

        The window is found by bisection on ``n`` (cutoff decreases as the window grows).
        """
        dt = _check_dt(dt)
        fc = finite("cutoff_hz", cutoff_hz, "Hz")
        nyq = 0.5 / dt
        if not 0.0 < fc < nyq:
            raise ValueError(f"cutoff_hz = {cutoff_hz!r} Hz: must lie in (0, Nyquist = {nyq}) Hz")
        order, N = kw.get("order", 1), kw.get("N", 0)
        lo = order + N + 1
        dlo = cls(n=lo, dt=dt, **kw)
        if cutoff(dlo) <= fc:
            return dlo
        hi = 2 * lo
        while cutoff(cls(n=hi, dt=dt, **kw)) > fc:
            lo, hi = hi, 2 * hi
            if hi > 10_000_000:
                raise ValueError(f"cutoff_hz = {cutoff_hz!r} Hz: needs a window over 1e7 samples")
        while hi - lo > 1:
            mid = (lo + hi) // 2
            if cutoff(cls(n=mid, dt=dt, **kw)) > fc:
                lo = mid
            else:
                hi = mid
        a, b = cls(n=lo, dt=dt, **kw), cls(n=hi, dt=dt, **kw)
        return a if abs(cutoff(a) - fc) <= abs(cutoff(b) - fc) else b

    @property
    def T(self) -> float:
        """Window length ``(n - 1) dt``, s."""
        return (self.n - 1) * self.dt

    @property
    def degree(self) -> int:
        """Degree of the polynomials the design is exact on (``order + N``; one more when the
        evaluation point is an "exact" root)."""
        return self.order + self.N + (1 if self._at_root() else 0)

    def _at_root(self) -> bool:
        return self.lag == "exact"

    @property
    def delay(self) -> float:
        """Delay of the estimate, s (see :func:`delay`)."""
        return delay(self)

    @property
    def cutoff(self) -> float:
        """-3 dB frequency, Hz (see :func:`cutoff`)."""
        return cutoff(self)

    @property
    def noise_gain(self) -> float:
        """``sqrt(sum w^2)``: output std per unit of white measurement-noise std, 1/s^order."""
        return float(np.sqrt(np.dot(self.weights, self.weights)))


def delay(design: JacobiDesign) -> float:
    """Delay of a design, s.

    ``lag`` for ``N >= 1``; for ``N = 0`` the intrinsic delay, the age at which the estimate is
    exact on polynomials of degree ``order + 1`` (``T/2`` for the paper's derivative kernel with
    ``kappa = mu = 0``). Equals the low-frequency group delay of the filter relative to the ideal
    differentiator ``(jw)^order``.

    References
    ----------
    .. [MJF09] Mboup, Join, Fliess, Numer. Algorithms 50 (2009), Section 4 (delay of the minimal
       estimators, reduced-delay affine estimators).
    """
    return design.lag_samples * design.dt


def frequency_response(design: JacobiDesign, f_hz) -> np.ndarray:
    """Complex frequency response ``H(f) = sum_i w_i exp(-j 2 pi f i dt)`` of the FIR filter."""
    f = np.atleast_1d(real_array("f_hz", f_hz))
    i = np.arange(design.n, dtype=np.float64)
    return np.exp(-2j * np.pi * np.outer(f, i) * design.dt) @ design.weights


def _rel_amp(design: JacobiDesign, f: np.ndarray) -> np.ndarray:
    h = frequency_response(design, f)
    return np.abs(h) / (2.0 * np.pi * f) ** design.order


def cutoff(design: JacobiDesign) -> float:
    """-3 dB frequency of a design, Hz.

    The lowest frequency ``f`` at which ``|H(f)| / (2 pi f)^order = 1/sqrt(2)``, from the exact
    discrete frequency response. ``math.inf`` when the response stays above -3 dB up to
    the Nyquist frequency.
    """
    from scipy.optimize import brentq  # late: scipy.optimize costs ~35 MB to import

    nyq = 0.5 / design.dt
    target = 1.0 / math.sqrt(2.0)
    # cutoff ~ 1/T; scan from well below, on a grid fine enough to never skip the first crossing
    f = np.linspace(0.0, nyq, max(64, 16 * design.n) + 1)[1:]
    a = _rel_amp(design, f) - target
    idx = np.flatnonzero(a <= 0.0)
    if idx.size == 0:
        return math.inf
    k = int(idx[0])
    if k == 0:
        lo_f = f[0] * 1e-6
        return float(brentq(lambda x: _rel_amp(design, np.array([x]))[0] - target, lo_f, f[0]))
    return float(
        brentq(lambda x: _rel_amp(design, np.array([x]))[0] - target, f[k - 1], f[k], xtol=1e-12)
    )
