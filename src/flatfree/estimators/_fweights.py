"""Exact discrete weights of the paper's algebraic F estimators and minimal differentiators.

The continuous kernels (NOTES.md "Algebraic estimators", paper eqs. (integral), (integral_2),
(Derivative)) are least-squares polynomial fits over the sliding window: the nu = 1 kernel
``(T - 2 sigma)`` is the shifted Legendre polynomial of degree 1, the nu = 2 kernel
``T^2 - 6 T sigma + 6 sigma^2`` the one of degree 2. Their exact discrete counterparts are the
discrete least-squares fits (Gram polynomials) on the samples of the window: the sampled
continuous kernel projected onto the moment conditions that make the discrete filter exact.

Signal model behind "exact" (zero-order-hold input, constant F on the window, local sample
index ``j = 0 .. n-1`` from the window start, ``s_j = y[k-n+1+j]``, ``v_m = u[k-n+1+m]`` held on
``[t_m, t_{m+1})``):

* nu = 1, ``y' = F + alpha u``:
  ``s_j = s_0 + F j dt + alpha dt sum_{m<j} v_m``.
* nu = 2, ``y'' = F + alpha u``:
  ``s_j = s_0 + s'_0 j dt + F (j dt)^2 / 2 + alpha dt^2 sum_{m<j} (j - m - 1/2) v_m``.

With ``F_hat = sum_j a_j s_j + alpha sum_m b_m v_m`` the estimate is exact for every ``s_0``
(and ``s'_0``), every F and every input sequence iff

* nu = 1: ``sum a_j = 0``, ``dt sum j a_j = 1``, ``b_m = -dt sum_{j>m} a_j``;
* nu = 2: ``sum a_j = 0``, ``sum j a_j = 0``, ``(dt^2/2) sum j^2 a_j = 1``,
  ``b_m = -dt^2 sum_{j>m} (j - m - 1/2) a_j``.

Among those, ``a`` is the Euclidean projection of the sampled continuous kernel onto the
constraint set; because the sampled kernel is a polynomial of the same degree as the constraints,
the projection is the unique polynomial in ``j`` of that degree meeting them: the discrete
least-squares slope (nu = 1) and curvature (nu = 2). As ``n -> infinity`` with ``T`` fixed,
``a_j / dt`` tends to the continuous kernel and ``b_m / dt`` to the continuous input kernel.

References
----------
.. [P] paper 000_81cd509a47ab99bc, Sections 2.4 and 3.2.3; corrected in docs/NOTES.md.
.. [MJF09] M. Mboup, C. Join, M. Fliess, "Numerical differentiation with annihilators in noisy
   environment", Numerical Algorithms 50 (2009) 439-467 (minimal estimators = least squares).
"""

from __future__ import annotations

import numpy as np

from flatfree._validate import one_of, positive, whole

__all__ = ["f_estimator_weights", "derivative_weights", "denoising_weights"]


def _check_dt(dt: float) -> float:
    """A sampling period: a finite real number > 0, s."""
    return positive("dt", dt, "s")


def _gram_coeffs(n: int, degree: int) -> np.ndarray:
    """Sample weights ``a_j`` (j = 0..n-1, oldest first) of the discrete least-squares estimate
    of ``d^degree y / dj^degree`` (per sample^degree) from a degree-``degree`` fit, degree 1 or 2:
    ``sum a_j j^p = 0`` for ``p < degree`` and ``sum a_j j^degree = degree!``.

    Closed forms in the centred variable ``x = j - (n-1)/2`` (well conditioned for any n).
    """
    x = np.arange(n, dtype=np.float64) - 0.5 * (n - 1)
    if degree == 1:
        # sum a = 0, sum j a = 1  ->  a = x / sum x^2,  sum x^2 = n (n^2 - 1) / 12
        return x / (n * (n * n - 1) / 12.0)
    # degree 2: a = lam (x^2 - m2), orthogonal to 1 and x; (1/2) sum j^2 a = 1
    # <=> (1/2) sum x^2 a = 1 (the 1 and x parts of j^2 are annihilated).
    m2 = (n * n - 1) / 12.0  # mean of x^2
    g = x * x - m2
    return g / (0.5 * float(np.dot(x * x, g)))


def f_estimator_weights(nu: int, n: int, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """Exact discrete weights of the algebraic F estimator for ``y^(nu) = F + alpha u``.

    ``F_hat[k] = sum_{i=0}^{n-1} wy[i] y[k-i] + alpha * sum_{j=0}^{n-2} wu[j] u[k-1-j]``,
    where ``u[m]`` is the input held (zero-order hold) on ``[t_m, t_{m+1})`` and the window
    spans ``T = (n - 1) dt``.

    Parameters
    ----------
    nu : int
        Order of the ultra-local model, 1 or 2.
    n : int
        Samples in the window: ``n >= 2`` for ``nu = 1``, ``n >= 3`` for ``nu = 2``.
    dt : float
        Sampling period, s, > 0.

    Returns
    -------
    wy : ndarray, shape (n,)
        Output weights, 1/s^nu; ``wy[0]`` multiplies the newest sample ``y[k]``.
    wu : ndarray, shape (n - 1,)
        Input weights, dimensionless; ``wu[0]`` multiplies ``u[k-1]``.

    Notes
    -----
    Exact (to rounding) for a constant F on the window, any zero-order-hold input and any
    initial conditions, for every allowed ``n``. ``wy`` is the discrete least-squares slope
    (nu = 1) or curvature (nu = 2), the exact discrete counterpart of the corrected continuous
    kernels of NOTES.md; ``wu`` follows from ``wy`` (module docstring). The continuous
    estimator is recovered as ``n -> infinity`` at fixed ``T``.

    References
    ----------
    .. [P] paper eqs. (integral), (integral_2) corrected in NOTES.md "Algebraic estimators".
    .. [MJF09] Mboup, Join, Fliess, Numer. Algorithms 50 (2009) 439-467.
    """
    nu = one_of("nu", nu, (1, 2))
    n = whole("n", n, nu + 1, strict=True)
    dt = _check_dt(dt)
    a = _gram_coeffs(n, nu)  # oldest first, per sample^nu
    if nu == 1:
        a = a / dt  # NOTES.md nu=1: dt sum j a_j = 1
        # b_m = -dt sum_{j>m} a_j, m = 0..n-2 (oldest first)
        tail = np.cumsum(a[::-1])[::-1]  # tail[m] = sum_{j>=m} a_j
        b = -dt * tail[1:]
    else:
        a = a / (dt * dt)  # NOTES.md nu=2: (dt^2/2) sum j^2 a_j = 1
        # b_m = -dt^2 sum_{j>m} (j - m - 1/2) a_j = -dt^2 (S1_m - (m + 1/2) S0_m),
        # S0_m = sum_{j>m} a_j, S1_m = sum_{j>m} j a_j
        j = np.arange(n, dtype=np.float64)
        s0 = np.cumsum(a[::-1])[::-1][1:]
        s1 = np.cumsum((j * a)[::-1])[::-1][1:]
        m = np.arange(n - 1, dtype=np.float64)
        b = -dt * dt * (s1 - (m + 0.5) * s0)
    wy = np.ascontiguousarray(a[::-1])  # wy[i] multiplies y[k-i]: i = n-1-j
    wu = np.ascontiguousarray(b[::-1])  # wu[i] multiplies u[k-1-i]: i = n-2-m
    return wy, wu


def derivative_weights(n: int, dt: float, order: int = 1) -> np.ndarray:
    """Causal FIR weights of the minimal algebraic estimator of the ``order``-th derivative.

    ``y_hat^(order)[k] = sum_{i=0}^{n-1} w[i] y[k-i]``. For ``order = 1`` this is the paper's
    corrected derivative kernel ``(6/T^3)(T - 2d)`` discretised exactly (discrete least-squares
    slope over ``T = (n - 1) dt``): exact on ramps, and on a parabola it returns the derivative
    at the middle of the window (delay ``T/2``). ``order = 2`` is the least-squares curvature,
    exact on parabolas.

    Parameters
    ----------
    n : int
        Samples in the window, ``n >= order + 1``.
    dt : float
        Sampling period, s, > 0.
    order : int
        Derivative order, 1 or 2 (higher orders: :class:`JacobiDesign`).

    Returns
    -------
    w : ndarray, shape (n,)
        Weights in 1/s^order, ``w[0]`` multiplies the newest sample.

    References
    ----------
    .. [P] paper eq. (Derivative), corrected in NOTES.md ("the extra T is a typo").
    .. [MJF09] Mboup, Join, Fliess, Numer. Algorithms 50 (2009) 439-467.
    """
    order = one_of("order", order, (1, 2), " (use JacobiDesign for higher orders)")
    n = whole("n", n, order + 1, strict=True)
    dt = _check_dt(dt)
    a = _gram_coeffs(n, order)
    a = a / dt**order  # _gram_coeffs estimates d^order y / dj^order per sample^order
    return np.ascontiguousarray(a[::-1])


def denoising_weights(n: int) -> np.ndarray:
    """Causal FIR weights of the paper's denoiser, corrected: the value at the CURRENT sample.

    ``y_hat[k] = sum_{i=0}^{n-1} w[i] y[k-i]``: the discrete least-squares line over the window
    evaluated at the newest sample, the exact discrete counterpart of NOTES.md's kernel
    ``(2/T^2)(2T - 3d)``. Returns a ramp unchanged (no delay on ramps); dimensionless weights,
    ``sum w = 1``.

    Parameters
    ----------
    n : int
        Samples in the window, >= 2.

    References
    ----------
    .. [P] paper eq. (filtering), corrected in NOTES.md (the printed kernel ``3d - T`` returns the
       value at the start of the window).
    """
    n = whole("n", n, 2, strict=True)
    c = 0.5 * (n - 1)
    x = np.arange(n, dtype=np.float64) - c  # oldest first
    a = 1.0 / n + x * c / (n * (n * n - 1) / 12.0)  # mean + slope * (newest - centre)
    return np.ascontiguousarray(a[::-1])
