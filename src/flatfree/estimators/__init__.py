"""Algebraic estimation: denoising, differentiation and the estimation of F, batch and streaming.

Causal, low-delay estimators built on the algebraic (Jacobi) differentiators of Mboup, Join and
Fliess, discretised exactly: every FIR filter here annihilates the polynomials its continuous
counterpart annihilates (no quadrature leak), at every window length.

Weights (exact, NOTES.md "Algebraic estimators")
    :func:`f_estimator_weights` (nu = 1, 2), :func:`derivative_weights`,
    :func:`denoising_weights`.
The Jacobi family
    :class:`JacobiDesign` (order, kappa, mu, N, window or cutoff, lag: low-delay / delay-free),
    :func:`delay`, :func:`cutoff`, :func:`frequency_response`, :func:`jacobi_weights`.
Choosing a design
    :func:`design_for` (documented rule from bandwidth and noise), :func:`predicted_rms`,
    :func:`signal_std_estimate`, and the one-call :func:`differentiate`.
Two doors, one implementation
    batch :func:`causal_filter`, :func:`estimate_f` (``scipy.signal.lfilter``); streaming
    :class:`Stream`, :class:`FEstimator` (``reset()``, ``update()``); compiled-loop form
    :func:`fir_new`, :func:`fir_reset`, :func:`fir_update`, :func:`f_update`
    (``numba.njit``; one float array per estimator holds weights, ring buffer and index).

References
----------
.. [P] paper 000_81cd509a47ab99bc, Sections 2.4 and 3.2.3, corrected in NOTES.md.
.. [MJF09] M. Mboup, C. Join, M. Fliess, Numerical Algorithms 50 (2009) 439-467.
.. [OKR22] A. Othmane, L. Kiltz, J. Rudolph, Int. J. Syst. Sci. (2022),
   doi:10.1080/00207721.2022.2025948.
"""

from flatfree.estimators._auto import design_for, predicted_rms, signal_std_estimate
from flatfree.estimators._fir import fir_new, fir_reset, fir_update
from flatfree.estimators._fweights import (
    denoising_weights,
    derivative_weights,
    f_estimator_weights,
)
from flatfree.estimators._jacobi import (
    JacobiDesign,
    cutoff,
    delay,
    frequency_response,
    jacobi_weights,
)
from flatfree.estimators._streams import (
    SHRINK_MAX_TAPS,
    FEstimator,
    Stream,
    causal_filter,
    check_timestamps,
    differentiate,
    estimate_f,
    f_update,
)

__all__ = [
    "FEstimator",
    "JacobiDesign",
    "SHRINK_MAX_TAPS",
    "Stream",
    "causal_filter",
    "check_timestamps",
    "cutoff",
    "delay",
    "denoising_weights",
    "derivative_weights",
    "design_for",
    "differentiate",
    "estimate_f",
    "f_estimator_weights",
    "f_update",
    "fir_new",
    "fir_reset",
    "fir_update",
    "frequency_response",
    "jacobi_weights",
    "predicted_rms",
    "signal_std_estimate",
]
