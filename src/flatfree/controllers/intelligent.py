"""Model-free control: the ultra-local model and the intelligent controllers iP, iPI, iPD, iPID.

The unknown single-input single-output plant is replaced, on a short sliding window, by the
*ultra-local model* (paper eq. (ultralocal))::

    y^(nu) = F + alpha u,        nu = 1 or 2,

where ``alpha`` is chosen by the user (so that ``alpha u`` and ``y^(nu)`` have the same order of
magnitude) and ``F`` lumps everything else: unknown dynamics, disturbances, the mismatch between
``alpha`` and the true input gain. ``F`` is estimated at every sample from the measured ``y`` and
the input **actually applied** (after rate limit and saturation) and cancelled. With the tracking
error ``e = y - y_ref`` (NOTES.md "Intelligent controllers": the sign the paper uses in Section
3.2; Section 3.3 mixes signs) the four controllers are::

    iP   (nu = 1): u = -(F_hat - y_ref'  + Kp e)                         / alpha
    iPI  (nu = 1): u = -(F_hat - y_ref'  + Kp e + Ki int e)              / alpha
    iPD  (nu = 2): u = -(F_hat - y_ref'' + Kp e          + Kd e')        / alpha
    iPID (nu = 2): u = -(F_hat - y_ref'' + Kp e + Ki int e + Kd e')      / alpha

and with a perfect estimate the closed-loop error obeys ``e' + Kp e (+ Ki int e) = 0`` (nu = 1)
or ``e'' + Kd e' + Kp e (+ Ki int e) = 0`` (nu = 2), whatever the plant: see
:func:`error_dynamics_gains`. Beyond the paper, ``IntelligentParams.correction_max`` bounds the
proportional correction ``Kp e`` (not ``Kd e'``, not the integral, not ``F_hat - y_ref^(nu)``),
so that a large error is closed at a bounded speed (default: no bound).

Two doors, one implementation (DESIGN.md "Speed by design"):

* compiled: :func:`intelligent_step` (``numba.njit``) over a flat parameter array
  (:meth:`IntelligentParams.to_array`, layout :class:`IPAR`) and a state array that it mutates
  in place (:func:`make_state`, layout :class:`IST`); allocation-free, callable from another
  compiled loop (one parameter/state pair per controlled channel);
* Python: :class:`IntelligentController` (and the shorthands :class:`IP`, :class:`IPI`,
  :class:`IPD`, :class:`IPID`) with ``reset()``, ``step()`` and ``status``.

Conventions of one step at sample ``k`` (time ``t_k = k dt``)
--------------------------------------------------------------
* ``y`` is the measurement at ``t_k``; the returned ``u_k`` is held (zero-order hold) on
  ``[t_k, t_{k+1})``. The estimator assumes exactly this timing; an actuator delay is part of
  the unknown ``F`` (and degrades it: see the tests on delayed inputs).
* Estimator of F (``estimator=``):

  - ``"algebraic"`` (default): the paper's algebraic estimator (eqs. (integral), (integral_2)
    with the sign corrected in NOTES.md) in its exact discrete form
    :func:`flatfree.estimators.f_estimator_weights`: over a window of ``window`` samples
    (span ``T = (window - 1) dt``) it returns F exactly when F is constant on the window, for any
    zero-order-hold input and any initial conditions;
  - ``"simple"``: ``F_hat = y^(nu)_hat - alpha u_{k-1}`` (NOTES.md, "a common, simpler discrete
    variant"), ``y^(nu)_hat`` from :func:`flatfree.estimators.derivative_weights`. Exact only
    for ``window = nu + 1``; it needs ``alpha > b / 2`` on ``y' = F + b u`` (see below).

* ``e'`` (nu = 2 only, ``derivative=``); neither source needs a measured derivative, both are
  derivative-free variants of the iPD in the sense that only ``y`` and the applied ``u`` are used:

  - ``"algebraic"`` (default): ``y'_hat`` = the paper's algebraic derivative (eq. (Derivative),
    NOTES.md) over ``derivative_window`` samples, exact on ramps; on a parabola it returns the
    derivative at the middle of the window, a lag of ``T_d / 2``;
  - ``"model"``: the F estimator's own derivative: the least-squares fit of the ultra-local
    model ``y'' = F + alpha u`` (constant F, applied input) over the window, evaluated at
    ``t_k``; exact, without lag, whenever F is constant on the window.

  then ``e' = y'_hat - y_ref'``.

Stable range of alpha (measured)
--------------------------------
Numbers from ``test_alpha_sweep_records_the_stable_range`` in ``tests/test_intelligent.py``.
On ``y' = F(t) + b u`` with ``b`` unknown to the controller (``F = 0.2 + 0.3 sin t``, reference
``sin(0.5 t)``, ``Kp = 2 /s``, ``dt = 0.01 s``), the iP with the windowed algebraic estimator
(``window = 10``) stayed bounded for every ``alpha / b`` from 0.24 to 50 and diverged at 0.2
(0.22: a slowly growing oscillation). The issue's reference figure, "stable down to about
0.24 b", is confirmed; the edge moves with the window (about 0.26 at ``window = 5``, below 0.2 at
``window = 20`` in a similar run). Tracking degrades as ``alpha / b`` grows, because the part
``(1 - b / alpha)`` of the input that ``alpha`` misses is supplied through the estimator's lag.
Worst error over the second half of a 20 s run (reference amplitude 1):

    alpha/b   0.24-0.5   1      2      5      10     20     30     50
    max|e|    0.006      0.007  0.020  0.062  0.14   0.34   0.58   1.0

The simple variant ``F = y'_hat - alpha u_{k-1}``: with ``window = 2`` (backward difference) the
input obeys a recursion with the root ``1 - b / alpha``: stable iff ``alpha / b > 1/2`` (0.5
diverged, 0.52 tracked). With ``window = 10`` it diverged for ``alpha / b <= 2`` (a windowed,
delayed derivative mixed with the instantaneous previous input is inconsistent) and tracked
from 3 on, better than the algebraic estimator at large ratios (0.05 at 20: its input term has
no lag). Rule of thumb: choose ``alpha`` near the largest expected input gain; an input delay
moves the lower edge up (with a one-sample delay ``alpha / b = 1/3`` diverged; see the tests).

Start, limits, bad samples
--------------------------
* Bumpless start: until ``window`` (and ``derivative_window``) samples have been received the
  estimator has no full window; the controller then holds ``u0`` (clipped to the limits),
  the integral stays 0 and F_hat is reported 0. The first law output is rate-limited from
  ``u0`` when ``rate_max`` is finite (set a rate limit for a bump-free switch-on).
* Actuator model: the law's command is first rate-limited (``|u_k - u_{k-1}| <= rate_max dt``)
  then clipped to ``[u_min, u_max]``; the result is applied, returned, and fed to the estimator.
* Anti-windup (``anti_windup="clamp"``, default): conditional integration. The integral
  ``I_k = I_{k-1} + e_k dt`` is kept only if the limited output is not limited in the
  direction that the increment pushes; otherwise ``I_k = I_{k-1}``. ``"none"`` always
  integrates (for comparison). Note that the F estimator itself does not wind up: it sees the
  applied input, so a binding limit shows up in F_hat as the unreachable part of the demand.
* A non-finite ``y`` (or reference): the previous output is held, the sample is counted in
  ``status.n_nonfinite`` and flagged in ``status.nonfinite``. To keep the window's time base,
  a missing ``y`` is replaced in the window by the ultra-local model's one-step prediction
  ``y_{k-1} + dt (F_hat + alpha u_{k-1})`` (nu = 1) or
  ``y_{k-1} + dt y'_hat + dt^2 (F_hat + alpha u_{k-1}) / 2`` (nu = 2, and ``y'_hat`` moves on
  by ``dt (F_hat + alpha u_{k-1})``); exact on the ultra-local model with constant F (with the
  ``"model"`` derivative for nu = 2). Before the first finite
  sample nothing is stored, and before the window is full the last finite value is repeated.
  At the first finite ``y`` after such a gap of ``m`` samples, its error ``d`` against the
  prediction is spread back over the gap: the ``i``-th predicted sample moves by
  ``d (i / (m + 1))^nu``, the shape of the prediction's error when F changed at the gap's
  start. The window then holds no step (which made a spike of F_hat and ``y'_hat``), and on
  the ultra-local model with F stepping at the gap's start it holds the samples as measured.
* Overflow: finite values so large that the law's arithmetic overflows (of the order of
  1e300) make the compiled step's output NaN or infinite, and the window then holds them.
  The compiled kernel returns that output as it is (no check in the loop); the Python shell
  (:meth:`IntelligentController.step`) raises ``ValueError`` naming the inputs instead, after
  resetting the controller.
* Outside estimates (:func:`intelligent_step_external`): a loop with a better source of F, y
  and y' (the natural-output controller's inertial estimator) runs the same law, limits and
  bookkeeping on them; the window keeps receiving y and the applied u but forms no estimate
  of its own, and takes over warm at the next plain :func:`intelligent_step` (a fallback on a
  bad sample). :func:`intelligent_override` replaces the output of a step just taken (the
  sample at which the outside estimator starts from the window's estimate).

References
----------
.. [P] paper 000_81cd509a47ab99bc, Section 3.2 (ultra-local model, iP/iPI/iPD/iPID, algebraic
   estimation of F); signs corrected in /work/shared/paper/NOTES.md "Intelligent controllers"
   and "Algebraic estimators".
.. [FJ13] M. Fliess, C. Join, "Model-free control", Int. J. Control 86 (2013) 2228-2252.
.. [AM08] K. J. Astrom, R. M. Murray, Feedback Systems, Princeton 2008, Section 10.4
   (integrator windup, conditional integration).
"""

from __future__ import annotations

import enum
import functools
import math
from dataclasses import dataclass

import numba
import numpy as np

from flatfree._validate import finite, one_of, positive, positive_or_inf, real
from flatfree._vecmath import no_refcount
from flatfree.controllers._shell import CompiledController, nonfinite_command
from flatfree.estimators import derivative_weights, f_estimator_weights

__all__ = [
    "IPAR",
    "IST",
    "IntelligentParams",
    "IntelligentStatus",
    "IntelligentController",
    "IP",
    "IPI",
    "IPD",
    "IPID",
    "ErrorDynamicsGains",
    "error_dynamics_gains",
    "intelligent_step",
    "intelligent_step_external",
    "intelligent_override",
    "intelligent_reset",
    "intelligent_set_applied",
    "intelligent_law_ran",
    "intelligent_predict",
    "make_state",
    "model_derivative_weights",
    "ESTIMATOR_CODES",
    "DERIVATIVE_CODES",
    "ANTI_WINDUP_CODES",
]

ESTIMATOR_CODES = {"algebraic": 0, "simple": 1}
DERIVATIVE_CODES = {"algebraic": 0, "model": 1}
ANTI_WINDUP_CODES = {"clamp": 0, "none": 1}


class IPAR(enum.IntEnum):
    """Header of the parameter array (:meth:`IntelligentParams.to_array`).

    After the header come four weight blocks of ``L`` entries each, ``L = IPAR.L`` (the buffer
    length, ``max(window, derivative_window)``), zero-padded: ``wy`` (F, on ``y[k-i]``), ``wu``
    (F, on ``u[k-1-i]``), ``wdy`` and ``wdu`` (``y'_hat``, same pattern; nu = 2 only); then the
    constants of the sliding-moment form (``MOMENT_BLOCK`` entries, "Sliding moments" in
    :func:`intelligent_step`).
    """

    NU = 0  # order of the ultra-local model, 1 or 2
    ALPHA = 1  # input gain of the ultra-local model, (y-unit / s^nu) per u-unit
    KP = 2  # 1/s^nu
    KI = 3  # 1/s^(nu+1)
    KD = 4  # 1/s (nu = 2)
    DT = 5  # sample time, s
    U_MIN = 6  # u-unit
    U_MAX = 7  # u-unit
    RATE_MAX = 8  # u-unit / s (inf: none)
    U0 = 9  # u-unit, held before the window is full
    AW = 10  # ANTI_WINDUP_CODES
    L = 11  # buffer length, samples
    MOM = 12  # 1: the sums by sliding moments (weights polynomial in the lag), 0: plain sums
    REFRESH = 13  # samples between exact recomputations of the moments
    CORR_MAX = 14  # bound on the proportional correction |kp e|, y-unit/s^nu (inf: none)


_HP = len(IPAR)


class IST(enum.IntEnum):
    """Header of the state array (:func:`make_state`; ``MY`` and ``MU`` start blocks of
    ``MOMENT_DEGREE + 1`` entries, then ``GAP``, ``ESTIMATED``: the header is 27 long); then
    two ring buffers of ``2 L`` entries (measurements ``y`` and applied inputs ``u``, each
    sample written twice so that the last ``L`` are contiguous, newest first)."""

    K = 0  # samples stored in the window so far
    HEAD = 1  # ring position of the newest sample
    N_NONFINITE = 2  # count of held steps (non-finite y or reference)
    NONFINITE = 3  # 1 if the last step held for a non-finite input (see intelligent_law_ran)
    U = 4  # last applied output, u-unit
    INTEGRAL = 5  # int e dt, y-unit s
    F_HAT = 6  # last F estimate, y-unit / s^nu
    E = 7  # last tracking error y - y_ref
    E_DOT = 8  # last e' estimate (nu = 2)
    YDOT = 9  # last y' estimate (nu = 2)
    SAT = 10  # -1 / 0 / +1: output at u_min / inside / at u_max after the last step
    RATE = 11  # -1 / 0 / +1: rate limit active (falling / no / rising)
    Y_LAST = 12  # newest value in the y window
    M_VALID = 13  # 1 when the moments below describe the current (full) window
    M_SINCE = 14  # samples since their last exact recomputation
    MY = 15  # moments of the y window, MOMENT_DEGREE + 1 entries (15-19)
    MU = 20  # moments of the u window (20-24)
    GAP = 25  # samples the window took from the model since the last finite y (a gap)
    ESTIMATED = 26  # 1 once F_hat is an estimate (a full window at a finite y, or given)


#: Degree of the polynomial weights the sliding-moment form represents (``f_estimator_weights``
#: and ``model_derivative_weights`` are of degree 1-4 in the lag).
MOMENT_DEGREE = 4
_ND = MOMENT_DEGREE + 1
#: Entries of the moment block of the parameter array: the shift matrix (ND x ND), the powers
#: of the entering and leaving abscissae (3 ND) and the four weight blocks' coefficients (4 ND).
MOMENT_BLOCK = _ND * _ND + 7 * _ND
#: Smallest buffer length for which the moment form is used (below, the plain sums are as fast).
MOMENT_MIN_LENGTH = 16
_HS = int(IST.ESTIMATED) + 1  # the header's length (the moments take ND entries each)
assert _ND == 5  # _slide_moments is written out for degree 4

# plain ints for the compiled code (numba folds module-level ints into constants)
_NU, _ALPHA, _KP, _KI, _KD, _DT = 0, 1, 2, 3, 4, 5
_UMIN, _UMAX, _RATE, _U0, _AW, _L, _MOM, _REFRESH, _CMAX = 6, 7, 8, 9, 10, 11, 12, 13, 14
_K, _HEAD, _NNF, _NF, _U, _INT, _FH, _E, _ED, _YD, _SAT, _RL, _YL = range(13)
_MVALID, _MSINCE, _MY, _MU, _GAP, _EST = 13, 14, 15, 20, 25, 26
assert [m.value for m in IPAR] == list(range(15)) and _HP == 15
assert [m.value for m in IST] == [*range(13), 13, 14, 15, 20, 25, 26] and _HS == 27
# offsets inside the moment block: shift matrix, x_0^m, x_L^m (y), x_(L-1)^m (u), coefficients
_MB_B, _MB_ADD, _MB_DY, _MB_DU = 0, _ND * _ND, _ND * _ND + _ND, _ND * _ND + 2 * _ND
_MB_CY, _MB_CU, _MB_CDY, _MB_CDU = (_ND * _ND + 3 * _ND, _ND * _ND + 4 * _ND,
                                    _ND * _ND + 5 * _ND, _ND * _ND + 6 * _ND)


# --------------------------------------------------------------------------------------------
# Compiled kernels
# --------------------------------------------------------------------------------------------
# The step kernel and its helper allocate nothing and only index the arrays they are given:
# compiled without numba's reference counting (flatfree._vecmath.no_refcount; in the closed loop
# the increfs and decrefs of the array arguments cost more than the law itself).
_JIT_STEP = no_refcount({"cache": True})
# The step and the helpers it calls once a step, inlined by LLVM wherever they are called: into
# each other, and into the controllers' kernels that call the step (the closed loop's lateral and
# speed loops; ~2 % of the loop, bit for bit, benchmarks/README.md "Inlined controller steps").
_JIT_INLINE = dict(_JIT_STEP, forceinline=True)


@numba.njit(**_JIT_STEP)
def _limit(p: np.ndarray, u_cmd: float, u_prev: float) -> tuple[float, float, float]:
    """Rate limit then saturation; returns (u, sat flag -1/0/1, rate flag -1/0/1)."""
    u = u_cmd
    rl = 0.0
    r = p[_RATE] * p[_DT]
    if u > u_prev + r:
        u = u_prev + r
        rl = 1.0
    elif u < u_prev - r:
        u = u_prev - r
        rl = -1.0
    sat = 0.0
    if u > p[_UMAX]:
        u = p[_UMAX]
        sat = 1.0
    elif u < p[_UMIN]:
        u = p[_UMIN]
        sat = -1.0
    return u, sat, rl


@numba.njit(**_JIT_STEP)
def intelligent_law_ran(p: np.ndarray, s: np.ndarray) -> bool:
    """Whether the last step applied the control law (else it held its previous output: the
    window not full yet, ``K < L``, or a non-finite input, ``NONFINITE``)."""
    return s[_K] >= p[_L] and s[_NF] == 0.0


@numba.njit("void(float64[::1], float64[::1], float64)", cache=True)
def intelligent_set_applied(p: np.ndarray, s: np.ndarray, u: float) -> None:
    """Record that ``u`` (not the controller's own output) was applied over the last sample.

    The F estimator (and the model derivative) must see the input actually applied. When
    something after the controller changes it (an actuator's lag or dead time, a limit the
    controller does not know, a term added to its output such as a damper), call this with the
    applied value before the next :func:`intelligent_step`. Nothing happens before the first
    step or for a non-finite ``u``.
    """
    if not math.isfinite(u) or s[_K] == 0.0:
        return
    n = int(p[_L])
    head = int(s[_HEAD])
    ub0 = _HS + 2 * n  # the u ring buffer (IST docstring), newest sample at HEAD and HEAD + L
    s[ub0 + head] = u
    s[ub0 + head + n] = u
    s[_U] = u


@numba.njit("void(float64[::1], float64[::1])", cache=True)
def intelligent_reset(p: np.ndarray, s: np.ndarray) -> None:
    """Reset a state array in place (compiled; callable from another compiled loop).

    Parameters
    ----------
    p : ndarray
        Parameter array from :meth:`IntelligentParams.to_array`.
    s : ndarray
        State array of length ``27 + 4 L`` (the IST header, then the rings; :func:`make_state`).
    """
    s[:] = 0.0
    u0 = min(max(p[_U0], p[_UMIN]), p[_UMAX])
    s[_U] = u0


@numba.njit(**_JIT_INLINE)
def _slide_moments(p, s, y_new, y_old, u_new, u_old, L):
    """Move the window moments by one sample ("Sliding moments" in :func:`intelligent_step`).

    ``M_m <- sum_n C(m, n) h^(m-n) M_n + x_0^m v_new - x_drop^m v_old`` for both windows
    (``C(m, m) h^0 = 1``), written out for ``MOMENT_DEGREE = 4`` with the moments in locals.
    """
    mb = _HP + 4 * L
    b = p[mb + _MB_B: mb + _MB_B + _ND * _ND]  # row m: C(m, n) h^(m-n), n <= m
    a = p[mb + _MB_ADD: mb + _MB_ADD + _ND]
    dy = p[mb + _MB_DY: mb + _MB_DY + _ND]
    du = p[mb + _MB_DU: mb + _MB_DU + _ND]
    y0, y1, y2, y3, y4 = s[_MY], s[_MY + 1], s[_MY + 2], s[_MY + 3], s[_MY + 4]
    u0, u1, u2, u3, u4 = s[_MU], s[_MU + 1], s[_MU + 2], s[_MU + 3], s[_MU + 4]
    s[_MY] = y0 + a[0] * y_new - dy[0] * y_old
    s[_MU] = u0 + a[0] * u_new - du[0] * u_old
    s[_MY + 1] = (y1 + b[5] * y0) + a[1] * y_new - dy[1] * y_old
    s[_MU + 1] = (u1 + b[5] * u0) + a[1] * u_new - du[1] * u_old
    s[_MY + 2] = (y2 + b[11] * y1 + b[10] * y0) + a[2] * y_new - dy[2] * y_old
    s[_MU + 2] = (u2 + b[11] * u1 + b[10] * u0) + a[2] * u_new - du[2] * u_old
    s[_MY + 3] = ((y3 + b[17] * y2) + (b[16] * y1 + b[15] * y0)) + a[3] * y_new - dy[3] * y_old
    s[_MU + 3] = ((u3 + b[17] * u2) + (b[16] * u1 + b[15] * u0)) + a[3] * u_new - du[3] * u_old
    s[_MY + 4] = (((y4 + b[23] * y3) + (b[22] * y2 + b[21] * y1)) + b[20] * y0
                  + a[4] * y_new - dy[4] * y_old)
    s[_MU + 4] = (((u4 + b[23] * u3) + (b[22] * u2 + b[21] * u1)) + b[20] * u0
                  + a[4] * u_new - du[4] * u_old)


@numba.njit(**_JIT_STEP)
def _push_y(s, y_in, L):
    """Push ``y_in`` into the y ring buffer (IST docstring) and ``Y_LAST``; returns the new head
    and the sample it overwrote (the oldest, leaving the window). The one push of
    :func:`intelligent_step` and :func:`intelligent_step_external`."""
    head = int(s[_HEAD]) - 1
    if head < 0:
        head += L
    s[_HEAD] = head
    yb0 = _HS
    y_old = s[yb0 + head]
    s[yb0 + head] = y_in
    s[yb0 + head + L] = y_in
    s[_YL] = y_in
    return head, y_old


@numba.njit(**_JIT_INLINE)
def _predict(p, s):
    """The ultra-local model's prediction of the next sample over one zero-order-hold step,
    ``y' = F + alpha u`` (nu = 1) or ``y'' = F + alpha u`` (nu = 2), from the last sample, the
    window's estimates and the last output (NOTES.md ultra-local model); the last sample
    itself while there is no estimate yet (``ESTIMATED`` 0: the window not full, or full only
    with samples of a gap, its F_hat never estimated; once set the window stays full)."""
    if s[_EST] == 0.0:
        return s[_YL]
    dt = p[_DT]
    acc = s[_FH] + p[_ALPHA] * s[_U]
    if int(p[_NU]) == 1:
        return s[_YL] + dt * acc
    return s[_YL] + dt * s[_YD] + 0.5 * dt * dt * acc


@numba.njit(**_JIT_INLINE)
def gap_weight(i: int, m: int, nu: int) -> float:
    """The share ``(i / (m + 1))^nu`` of the prediction error at the first sample after a gap
    that the gap's ``i``-th of ``m`` model-given samples takes (:func:`_end_gap`)."""
    w = i / (m + 1.0)
    return w if nu == 1 else w * w


@numba.njit(**_JIT_STEP)
def intelligent_predict(p: np.ndarray, s: np.ndarray) -> float:
    """The model's prediction of the next sample, the one a non-finite ``y`` would store
    (:func:`intelligent_step`)."""
    return _predict(p, s)


@numba.njit(**_JIT_STEP)
def _end_gap(p, s, y, L):
    """At the first finite ``y`` after a gap (``GAP`` > 0 samples the window took from the
    model): move those samples toward ``y`` so that the window sees no step.

    The model held F over the gap; a change of F at its start by ``dF`` makes the prediction
    err by ``dF t^nu / nu!`` after the time ``t``, so the ``i``-th of ``m`` predicted samples
    (``i = m`` the last) is moved by ``d (i / (m + 1))^nu``, ``d = y - prediction`` of this
    sample. Without it the window's sums meet a step of ``d`` at its newest end: a spike of F
    and ``y'`` that, after a 0.2 s gap in the position, sent the steer at its rate limit into
    a growing weave (benchmarks/README.md "Bridging a gap in the position"). Moments are
    marked stale (recomputed exactly at the step). The weights are a model of the error, not
    a measurement: where F moved otherwise, what is left of the step still enters, smaller.
    """
    m = int(s[_GAP])
    if m <= 0:
        return
    s[_GAP] = 0.0
    s[_MVALID] = 0.0
    d = y - _predict(p, s)
    if not math.isfinite(d):
        return
    nu = int(p[_NU])
    head = int(s[_HEAD])  # the newest stored sample: the gap's last (i = m)
    yb0 = _HS
    for j in range(min(m, L)):
        c = d * gap_weight(m - j, m, nu)
        idx = head + j
        if idx >= L:
            idx -= L
        s[yb0 + idx] += c
        s[yb0 + idx + L] += c
    s[_YL] += d * gap_weight(m, m, nu)


@numba.njit(**_JIT_STEP)
def _moment_sum(c, m):
    """``sum_m c_m M_m`` (degree 4) as a short tree."""
    return (c[0] * m[0] + c[1] * m[1]) + (c[2] * m[2] + c[3] * m[3]) + c[4] * m[4]


@numba.njit(**_JIT_STEP)
def _exact_moments(p, s, head, L):
    """The window moments ``sum_i x_i^m v[i]`` from the ring buffers (full window)."""
    h = 2.0 / (L - 1)
    yw = s[_HS + head: _HS + head + L]  # y[k - i], newest first
    uw = s[_HS + 2 * L + head + 1: _HS + 2 * L + head + L]  # u[k - 1 - i], i < L - 1
    y0 = y1 = y2 = y3 = y4 = 0.0  # in locals: the views alias s, so sums in s would be
    u0 = u1 = u2 = u3 = u4 = 0.0  # stored and reloaded at every term
    for i in range(L):
        x = -1.0 + i * h
        x2 = x * x
        x3 = x2 * x
        x4 = x3 * x
        yi = yw[i]
        ui = uw[i] if i < L - 1 else 0.0
        y0 += yi
        y1 += x * yi
        y2 += x2 * yi
        y3 += x3 * yi
        y4 += x4 * yi
        u0 += ui
        u1 += x * ui
        u2 += x2 * ui
        u3 += x3 * ui
        u4 += x4 * ui
    s[_MY] = y0
    s[_MY + 1] = y1
    s[_MY + 2] = y2
    s[_MY + 3] = y3
    s[_MY + 4] = y4
    s[_MU] = u0
    s[_MU + 1] = u1
    s[_MU + 2] = u2
    s[_MU + 3] = u3
    s[_MU + 4] = u4
    s[_MVALID] = 1.0
    s[_MSINCE] = 0.0


@numba.njit(**_JIT_INLINE)
def _law(p, s, f_hat, e, e_dot, y_ref_dot, y_ref_ddot, u_prev, de_int):
    """The control law at the estimates ``f_hat``, ``e``, ``e_dot`` (``e_dot`` read for nu = 2
    only), with the limits and conditional integration; the integral moves by ``de_int``.
    Writes ``E``, ``E_DOT`` (nu = 2), ``INTEGRAL``, ``SAT``, ``RATE``, ``NONFINITE``; returns
    the limited output (the caller stores it)."""
    alpha = p[_ALPHA]
    s[_E] = e
    nu1 = int(p[_NU]) == 1
    pe = p[_KP] * e
    cmax = p[_CMAX]
    if cmax < math.inf:
        # the proportional correction bounded (IntelligentParams.correction_max); within the
        # bound the law as without it, bit for bit. Tested only when set: the default pays
        # nothing per step
        if pe > cmax:
            pe = cmax
        elif pe < -cmax:
            pe = -cmax
    if nu1:
        v0 = f_hat - y_ref_dot + pe  # paper eq. (ip), NOTES.md sign
    else:
        s[_ED] = e_dot
        v0 = f_hat - y_ref_ddot + pe + p[_KD] * e_dot  # paper eq. (iPD_c), NOTES.md
    ki = p[_KI]
    i_old = s[_INT]
    i_new = i_old + de_int  # rectangle rule, includes e_k
    u_cmd = -(v0 + ki * i_new) / alpha  # paper eqs. (iPI_c), (iPID_c)
    u_lim, sat, rl = _limit(p, u_cmd, u_prev)
    if ki != 0.0 and int(p[_AW]) == 0 and (sat != 0.0 or rl != 0.0):
        # conditional integration [AM08 10.4]: drop the increment if it pushes u further
        # into the active limit; du/dI = -ki/alpha
        push = -ki / alpha * e
        lim_dir = sat if sat != 0.0 else rl
        if push * lim_dir > 0.0:
            i_new = i_old
            u_cmd = -(v0 + ki * i_new) / alpha
            u_lim, sat, rl = _limit(p, u_cmd, u_prev)
    s[_INT] = i_new
    s[_SAT] = sat
    s[_RL] = rl
    s[_NF] = 0.0
    return u_lim


@numba.njit(
    "float64(float64[::1], float64[::1], float64, float64, float64, float64)",
    fastmath=False,
    **_JIT_INLINE,
)
def intelligent_step(
    p: np.ndarray,
    s: np.ndarray,
    y: float,
    y_ref: float,
    y_ref_dot: float,
    y_ref_ddot: float,
) -> float:
    """One sample of an intelligent controller (iP/iPI/iPD/iPID); mutates ``s``, returns ``u_k``.

    Parameters
    ----------
    p : ndarray
        Parameter array (:meth:`IntelligentParams.to_array`, layout :class:`IPAR`).
    s : ndarray
        State array (:func:`make_state`, layout :class:`IST`), updated in place.
    y : float
        Measurement at ``t_k``.
    y_ref, y_ref_dot, y_ref_ddot : float
        Reference and its first two time derivatives at ``t_k`` (``y_ref_ddot`` is used by
        nu = 2 only; ``y_ref_dot`` by nu = 1 in the law and by nu = 2 in ``e'``).

    Returns
    -------
    float
        The applied output ``u_k`` (after rate limit and saturation), to hold on
        ``[t_k, t_{k+1})``.

    Notes
    -----
    The law (module docstring, paper eqs. (iPID_c), (iPI_c), (ip), NOTES.md signs)::

        u = -(F_hat - y_ref^(nu) + Kp e + Ki int e + Kd e') / alpha,   e = y - y_ref.

    Sliding moments. The weights of the algebraic F estimator and of the model derivative are
    polynomials of low degree (<= :data:`MOMENT_DEGREE`) in the lag ``i``. With the abscissae
    ``x_i = -1 + i h``, ``h = 2 / (L - 1)``, and ``w(i) = sum_m c_m x_i^m`` a window sum is
    ``sum_i w(i) v[k-i] = sum_m c_m M_m`` with the moments ``M_m = sum_i x_i^m v[k-i]``. When a
    sample enters, every other moves from ``x_i`` to ``x_i + h``, so (binomial theorem)::

        M_m <- sum_{n<=m} C(m, n) h^(m-n) M_n + x_0^m v_new - x_drop^m v_old

    (``x_drop = x_L`` for ``y``, ``x_(L-1)`` for ``u``): 2 x 15 multiply-adds per sample instead
    of 2 or 4 sums of ``L`` terms. The recursion adds a rounding error per sample that would
    walk without bound, so the moments are recomputed exactly every ``IPAR.REFRESH`` samples
    (default ``L``), and that step uses the plain sums (bit for bit the plain form); between
    two recomputations the error stays at round-off (``tests/test_speed_equivalence.py`` bounds
    it over a 10-minute run). :meth:`IntelligentParams.to_array` switches the form on when the
    fitted coefficients reproduce all four weight blocks to 1e-12 of their size and
    ``L >= MOMENT_MIN_LENGTH`` (zero-padded blocks, the "simple" estimator: plain sums).

    References
    ----------
    .. [P] paper Section 3.2.2-3.2.3, corrected in NOTES.md "Intelligent controllers".
    """
    L = int(p[_L])
    nu = int(p[_NU])
    alpha = p[_ALPHA]
    dt = p[_DT]
    wy0 = _HP
    wu0 = _HP + L
    wdy0 = _HP + 2 * L
    wdu0 = _HP + 3 * L
    yb0 = _HS
    ub0 = _HS + 2 * L
    u_prev = s[_U]
    k = int(s[_K])

    y_ok = math.isfinite(y)
    # y_ref_ddot enters the law for nu = 2 only: a nu = 1 loop does not miss it
    ref_ok = (math.isfinite(y_ref) and math.isfinite(y_ref_dot)
              and (nu == 1 or math.isfinite(y_ref_ddot)))

    if not y_ok and k == 0:
        # nothing known yet: hold, store nothing (the window starts at the first finite y)
        s[_NNF] += 1.0
        s[_NF] = 1.0
        return u_prev

    # ---- push the measurement (or the model's prediction of it) into the y ring buffer ----
    if y_ok:
        y_in = y
        if s[_GAP] > 0.0:
            _end_gap(p, s, y, L)  # the gap's predicted samples moved toward y
    else:
        # NOTES.md ultra-local model, one zero-order-hold step: y' = F + alpha u
        y_in = _predict(p, s)
        if nu == 2 and s[_EST] != 0.0:
            s[_YD] += dt * (s[_FH] + alpha * u_prev)  # the velocity moves on too
        s[_GAP] += 1.0
    head, y_old = _push_y(s, y_in, L)
    use_mom = p[_MOM] != 0.0
    exact_moments = False
    if use_mom:
        if k >= L and s[_MVALID] != 0.0 and s[_MSINCE] < p[_REFRESH]:
            # slide the moments by one sample (y_old: the oldest y, which the push overwrote)
            _slide_moments(p, s, y_in, y_old, s[ub0 + head + 1], s[ub0 + head], L)
            s[_MSINCE] += 1.0
        else:
            exact_moments = True
    if k < L:
        k += 1
        s[_K] = k
    full = k >= L
    if full and exact_moments:
        _exact_moments(p, s, head, L)

    u_out = u_prev
    if full and y_ok and use_mom and not exact_moments:
        # the sliding-moment form ("Sliding moments" in the docstring): the same sums as below
        # to round-off, in O(1) instead of O(L)
        mb = _HP + 4 * L
        my = s[_MY: _MY + _ND]
        mu = s[_MU: _MU + _ND]
        s[_EST] = 1.0
        s[_FH] = _moment_sum(p[mb + _MB_CY: mb + _MB_CY + _ND], my) + alpha * _moment_sum(
            p[mb + _MB_CU: mb + _MB_CU + _ND], mu)
        if nu == 2:
            s[_YD] = _moment_sum(p[mb + _MB_CDY: mb + _MB_CDY + _ND], my) + alpha * _moment_sum(
                p[mb + _MB_CDU: mb + _MB_CDU + _ND], mu)
    elif full and y_ok:
        # F_hat = sum wy[i] y[k-i] + alpha sum wu[j] u[k-1-j]   (estimators.f_estimator_weights)
        # y'_hat = sum wdy[i] y[k-i] + alpha sum wdu[j] u[k-1-j]  (nu = 2; wdu = 0: algebraic)
        # the sums are fused into one loop: independent accumulators, not one long add chain.
        # Contiguous views indexed by the loop counter alone: an index whose sign the compiler
        # cannot prove (base + i) costs a negative-index fix-up per load (4 instructions), which
        # made this loop twice as slow; the sums and their order are unchanged.
        last = L - 1
        yw = s[yb0 + head: yb0 + head + L]  # y[k - i], newest first
        uw = s[ub0 + head + 1: ub0 + head + L]  # u[k - 1 - i], i < L - 1
        wy = p[wy0: wy0 + L]
        wu = p[wu0: wu0 + last]
        ay = wy[last] * yw[last]
        au = 0.0
        if nu == 1:
            for i in range(last):
                ay += wy[i] * yw[i]
                au += wu[i] * uw[i]
        else:
            wdy = p[wdy0: wdy0 + L]
            wdu = p[wdu0: wdu0 + last]
            dy = wdy[last] * yw[last]
            du = 0.0
            for i in range(last):
                yi = yw[i]
                ui = uw[i]
                ay += wy[i] * yi
                au += wu[i] * ui
                dy += wdy[i] * yi
                du += wdu[i] * ui
            s[_YD] = dy + alpha * du
        s[_FH] = ay + alpha * au
        s[_EST] = 1.0
    if full and y_ok and ref_ok:
        e = y - y_ref
        e_dot = s[_YD] - y_ref_dot if nu == 2 else 0.0
        u_out = _law(p, s, s[_FH], e, e_dot, y_ref_dot, y_ref_ddot, u_prev, e * dt)
    elif not (y_ok and ref_ok):
        s[_NNF] += 1.0
        s[_NF] = 1.0
    else:
        s[_NF] = 0.0  # window not full yet: hold u0 (bumpless start, module docstring)

    s[_U] = u_out
    s[ub0 + head] = u_out
    s[ub0 + head + L] = u_out
    return u_out


_SIG_EXT = ("float64(float64[::1], float64[::1], float64, float64, float64, float64, float64, "
            "float64, float64)")


@numba.njit(_SIG_EXT, fastmath=False, **_JIT_STEP)
def intelligent_step_external(p, s, y, y_ref, y_ref_dot, y_ref_ddot, f_hat, y_hat, y_dot_hat):
    """One sample of an intelligent controller whose estimates come from outside its window.

    For a loop that has a better estimate of F, y and y' than the window's: flatfree's
    natural-output controller with ``estimator_lat = "imu"`` takes them from the measured
    acceleration (:mod:`flatfree.controllers.vehicle`). The law, its limits and the state's
    bookkeeping are those of :func:`intelligent_step`, with ``e = y_hat - y_ref`` and
    ``e' = y_dot_hat - y_ref_dot``; ``f_hat`` and ``y_dot_hat`` are stored as the step's
    ``F_HAT`` and ``YDOT``. The measurement ``y`` and the output enter the window as there, so
    that :func:`intelligent_step` can take over at the next sample (a fault fallback) with a
    full, current window; what is saved is the window's own estimate: its sums are not formed,
    and its sliding moments are marked stale (``M_VALID`` cleared), so the next
    :func:`intelligent_step` recomputes them exactly.

    With a window that is not full yet, or any argument not finite, this is
    :func:`intelligent_step` (``y``, the reference): the window's estimate and its policy for
    missing samples. Returns the applied output ``u_k``, as :func:`intelligent_step`.
    """
    L = int(p[_L])
    if (int(s[_K]) < L or not (math.isfinite(y) and math.isfinite(y_ref)
                               and math.isfinite(y_ref_dot) and math.isfinite(y_ref_ddot)
                               and math.isfinite(f_hat) and math.isfinite(y_hat)
                               and math.isfinite(y_dot_hat))):
        return intelligent_step(p, s, y, y_ref, y_ref_dot, y_ref_ddot)
    u_prev = s[_U]
    if s[_GAP] > 0.0:
        _end_gap(p, s, y, L)
    _push_y(s, y, L)
    s[_MVALID] = 0.0
    e = y_hat - y_ref
    u = _law(p, s, f_hat, e, y_dot_hat - y_ref_dot, y_ref_dot, y_ref_ddot, u_prev, e * p[_DT])
    s[_FH] = f_hat
    s[_EST] = 1.0
    s[_YD] = y_dot_hat
    intelligent_set_applied(p, s, u)  # the output into the u ring (finite, window full)
    return u


@numba.njit(_SIG_EXT, fastmath=False, **_JIT_STEP)
def intelligent_override(p, s, y, y_ref, y_ref_dot, y_ref_ddot, f_hat, y_hat, y_dot_hat):
    """Replace the output of the :func:`intelligent_step` just taken by the law at outside
    estimates (:func:`intelligent_step_external`'s arguments; ``y`` is not used: the step has
    already entered it). The limits act against the output applied before that step; the
    integral keeps the value the step gave it. For the sample at which an outside estimator
    starts: the window's estimate of this sample is still at hand (``YDOT``) to start it with.
    A window that is not full or an argument that is not finite leaves the step's output.
    Returns the applied output.
    """
    L = int(p[_L])
    head = int(s[_HEAD])
    ub0 = _HS + 2 * L
    if (int(s[_K]) < L or not (math.isfinite(y_ref) and math.isfinite(y_ref_dot)
                               and math.isfinite(y_ref_ddot) and math.isfinite(f_hat)
                               and math.isfinite(y_hat) and math.isfinite(y_dot_hat))):
        return s[ub0 + head]
    u_prev = s[ub0 + head + 1]  # the output applied over the period before the step
    e = y_hat - y_ref
    u = _law(p, s, f_hat, e, y_dot_hat - y_ref_dot, y_ref_dot, y_ref_ddot, u_prev, 0.0)
    s[_FH] = f_hat
    s[_EST] = 1.0
    intelligent_set_applied(p, s, u)  # replaces the step's output in the u ring
    return u

# --------------------------------------------------------------------------------------------
# Weights
# --------------------------------------------------------------------------------------------
def model_derivative_weights(n: int, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """Weights of ``y'(t_k)`` from the nu = 2 ultra-local model fitted on the window.

    ``y'_hat[k] = sum_{i=0}^{n-1} wy[i] y[k-i] + alpha sum_{j=0}^{n-2} wu[j] u[k-1-j]`` is exact
    (to rounding) when ``y'' = F + alpha u`` with F constant on the window and ``u`` held on each
    sample interval, for any initial position and velocity. It is the derivative at the window's
    end of the least-squares quadratic through the input-corrected samples.

    Parameters
    ----------
    n : int
        Window length in samples, >= 3.
    dt : float
        Sample time, s.

    Returns
    -------
    wy : ndarray, shape (n,)
        1/s; ``wy[0]`` multiplies the newest sample.
    wu : ndarray, shape (n - 1,)
        s; ``wu[0]`` multiplies ``u[k-1]``.

    Notes
    -----
    With ``z_m = y_m - alpha dt^2 sum_{l<m} (m - l - 1/2) u_l`` (exact double integral of the
    held input from the window start) ``z`` is a quadratic in time, so any weights ``c`` with
    ``sum c = 0, sum c tau = 1, sum c tau^2 = 0`` (``tau_i = -i dt``) give ``z'(t_k)``, and
    ``y'(t_k) = z'(t_k) + alpha dt sum u_l``. Collecting the input terms:
    ``wu[j] = dt - dt^2 sum_{i<=j} c_i (j - i + 1/2)``.

    References
    ----------
    .. [P] paper Section 3.2.3 (estimation on the ultra-local model); NOTES.md nu = 2 model.
    """
    n = int(n)
    if n < 3:
        raise ValueError(f"derivative_window = {n!r} samples: must be >= 3 for nu = 2")
    dt = positive("dt", dt, "s")
    x = -np.arange(n, dtype=np.float64)  # tau_i / dt, newest first
    xc = x - x.mean()
    v = np.column_stack([np.ones(n), xc, 0.5 * xc * xc])
    # coefficients of the fitted quadratic in xc: z = a0 + a1 xc + a2 xc^2/2
    pinv = np.linalg.pinv(v)
    # derivative at tau = 0, i.e. xc = -mean(x): a1 + a2 * (-mean(x))
    c = (pinv[1] + pinv[2] * (-x.mean())) / dt
    wu = np.empty(n - 1)
    for j in range(n - 1):
        i = np.arange(j + 1)
        wu[j] = dt - dt * dt * float(np.sum(c[: j + 1] * (j - i + 0.5)))
    return np.ascontiguousarray(c), wu


# --------------------------------------------------------------------------------------------
# Parameters, gains
# --------------------------------------------------------------------------------------------
@dataclass(frozen=True, slots=True, kw_only=True)
class IntelligentParams:
    """Parameters of an intelligent controller (iP/iPI with nu = 1, iPD/iPID with nu = 2).

    Attributes
    ----------
    nu : int
        Order of the ultra-local model ``y^(nu) = F + alpha u``, 1 or 2.
    alpha : float
        Input gain of the ultra-local model, (y-unit / s^nu) per u-unit, nonzero. Chosen by the
        user near the plant's input gain; see the module docstring for the measured stable
        range of ``alpha / b``.
    dt : float
        Sample time, s, > 0 (never assumed).
    kp, ki, kd : float
        Gains, >= 0: ``kp`` in 1/s^nu, ``ki`` in 1/s^(nu+1), ``kd`` in 1/s (nu = 2 only).
        :func:`error_dynamics_gains` picks them from desired error dynamics.
    window : int
        Samples in the F estimator's window (span ``(window - 1) dt``); ``>= nu + 1``. Required,
        like ``dt``: the window's duration is a design choice, never assumed.
    estimator : str
        ``"algebraic"`` (paper, default) or ``"simple"`` (``y^(nu)_hat - alpha u_{k-1}``).
    derivative : str
        Source of ``e'`` for nu = 2: ``"algebraic"`` (default) or ``"model"``.
    derivative_window : int or None
        Samples of the ``e'`` estimator (nu = 2 only: unused for nu = 1, though still checked);
        None: ``window``. ``>= 2`` (algebraic) or ``>= 3`` (model).
    u_min, u_max : float
        Actuator limits, u-unit (infinite: none).
    rate_max : float
        Rate limit, u-unit/s, > 0 (inf: none).
    u0 : float
        Output held before the estimator's window is full, u-unit.
    anti_windup : str
        ``"clamp"`` (conditional integration, default) or ``"none"``.
    correction_max : float
        Bound on the law's proportional correction ``|kp e|``, in y-unit/s^nu, > 0 (default
        inf: none, the paper's law): ``kp e`` is replaced by ``clip(kp e, -c, c)``; ``kd e'``,
        the integral and ``-F + y_ref^(nu)`` are not bounded. For nu = 1 the error then closes
        at a speed of at most ``c``; for nu = 2 the law reads ``e'' = -kd (e' + clip(kp e,
        -c, c) / kd)``, a nested saturation [T92]: a large error closes at a speed of at most
        ``c / kd`` instead of at once through a command the actuators' rate limit cannot
        follow. Within the bound the law is the paper's, bit for bit. Bounding ``kd e'`` as
        well (the whole ``kp e + kd e'``, this field's meaning before 2026-11-23) kept less
        of the region of attraction (benchmarks/README.md "The bound on the proportional
        correction"). Beyond the paper.

    References
    ----------
    .. [P] paper Section 3.2; NOTES.md "Intelligent controllers".
    .. [T92] A. R. Teel, "Global stabilization and restricted tracking for multiple
       integrators with bounded controls", Systems & Control Letters 18 (1992) 165-171.
    """

    nu: int
    alpha: float
    dt: float
    window: int
    kp: float = 0.0
    ki: float = 0.0
    kd: float = 0.0
    estimator: str = "algebraic"
    derivative: str = "algebraic"
    derivative_window: int | None = None
    u_min: float = -math.inf
    u_max: float = math.inf
    rate_max: float = math.inf
    u0: float = 0.0
    anti_windup: str = "clamp"
    correction_max: float = math.inf

    def __post_init__(self) -> None:
        one_of("nu", self.nu, (1, 2))  # the ultra-local model's order (True is not one)
        a = finite("alpha", self.alpha, "(y-unit/s^nu) per u-unit")
        if a == 0.0:
            raise ValueError(f"alpha = {self.alpha!r} (y-unit/s^nu) per u-unit: must be nonzero")
        positive("dt", self.dt, "s")
        for name, unit in (("kp", "1/s^nu"), ("ki", "1/s^(nu+1)"), ("kd", "1/s")):
            v = finite(name, getattr(self, name), unit)
            if v < 0.0:
                raise ValueError(f"{name} = {v!r} {unit}: must be >= 0")
        if self.nu == 1 and self.kd != 0.0:
            raise ValueError(f"kd = {self.kd!r} 1/s: must be 0 for nu = 1 (iP, iPI)")
        if not isinstance(self.estimator, str) or self.estimator not in ESTIMATOR_CODES:
            raise ValueError(
                f"estimator = {self.estimator!r}: must be one of {sorted(ESTIMATOR_CODES)}"
            )
        if not isinstance(self.derivative, str) or self.derivative not in DERIVATIVE_CODES:
            raise ValueError(
                f"derivative = {self.derivative!r}: must be one of {sorted(DERIVATIVE_CODES)}"
            )
        if not isinstance(self.anti_windup, str) or self.anti_windup not in ANTI_WINDUP_CODES:
            raise ValueError(
                f"anti_windup = {self.anti_windup!r}: must be one of {sorted(ANTI_WINDUP_CODES)}"
            )
        _check_window("window", self.window, self.nu + 1, f"the nu = {self.nu} estimator")
        if self.derivative_window is not None:
            lo = 3 if self.derivative == "model" else 2
            _check_window("derivative_window", self.derivative_window, lo, "the e' estimator")
        elif self.nu == 2 and self.derivative == "model":
            _check_window("window", self.window, 3, "the model derivative")
        umin = real("u_min", self.u_min, "u-unit")
        umax = real("u_max", self.u_max, "u-unit")
        if math.isnan(umin) or math.isnan(umax) or not umin < umax:
            raise ValueError(
                f"u_min = {self.u_min!r}, u_max = {self.u_max!r} u-unit: need u_min < u_max"
            )
        positive_or_inf("rate_max", self.rate_max, "u-unit/s")
        finite("u0", self.u0, "u-unit")
        positive_or_inf("correction_max", self.correction_max, "y-unit/s^nu")

    @property
    def buffer_length(self) -> int:
        """Ring buffer length ``L = max(window, derivative_window)`` (samples)."""
        dw = self.window if self.derivative_window is None else self.derivative_window
        return max(int(self.window), int(dw)) if self.nu == 2 else int(self.window)

    def to_array(self) -> np.ndarray:
        """The parameters and estimator weights as one float64 array (layout :class:`IPAR`)."""
        L = self.buffer_length
        n = int(self.window)
        p = np.zeros(_HP + 4 * L + MOMENT_BLOCK, dtype=np.float64)
        p[_NU] = self.nu
        p[_ALPHA] = self.alpha
        p[_KP] = self.kp
        p[_KI] = self.ki
        p[_KD] = self.kd
        p[_DT] = self.dt
        p[_UMIN] = self.u_min
        p[_UMAX] = self.u_max
        p[_RATE] = self.rate_max
        p[_U0] = self.u0
        p[_AW] = ANTI_WINDUP_CODES[self.anti_windup]
        p[_L] = L
        p[_CMAX] = self.correction_max
        nd = 0
        if self.nu == 2:
            nd = n if self.derivative_window is None else int(self.derivative_window)
        # the weights and their moment form: the same for every controller of these settings
        # (a run builds two, a sweep hundreds; the natural-output design's lateral iPD, window
        # 185: 2.0 ms to build, 0.03 ms cached, measured)
        w = _estimator_block(int(self.nu), n, L, float(self.dt), self.estimator,
                             self.derivative, nd)
        p[_HP:] = w[_HP:]
        p[_MOM] = w[_MOM]
        p[_REFRESH] = w[_REFRESH]
        return p


@functools.lru_cache(maxsize=64)
def _estimator_block(nu: int, n: int, L: int, dt: float, estimator: str, derivative: str,
                     nd: int) -> np.ndarray:
    """A read-only parameter array holding only the estimator's weights (window ``n``, the
    derivative's ``nd`` for nu = 2, buffer ``L``) and their moment form
    (:func:`_moment_constants`: the block and the header's ``MOM``, ``REFRESH``)."""
    p = np.zeros(_HP + 4 * L + MOMENT_BLOCK, dtype=np.float64)
    if estimator == "algebraic":
        wy, wu = f_estimator_weights(nu, n, dt)  # NOTES.md algebraic estimators
    else:
        # NOTES.md simple variant: F = y^(nu)_hat - alpha u_{k-1}
        wy = derivative_weights(n, dt, order=nu)
        wu = np.zeros(n - 1)
        wu[0] = -1.0
    p[_HP : _HP + n] = wy
    p[_HP + L : _HP + L + n - 1] = wu
    if nu == 2:
        if derivative == "algebraic":
            wdy = derivative_weights(nd, dt, order=1)  # paper eq. (Derivative), NOTES
            wdu = np.zeros(nd - 1)
        else:
            wdy, wdu = model_derivative_weights(nd, dt)
        p[_HP + 2 * L : _HP + 2 * L + nd] = wdy
        p[_HP + 3 * L : _HP + 3 * L + nd - 1] = wdu
    _moment_constants(p, L)
    p.setflags(write=False)
    return p


#: A fit of the weights by the moment polynomials counts as exact within this fraction of the
#: block's largest weight (the fit's own round-off is ~1e-15 of it).
_MOMENT_FIT_RTOL = 1e-12


def _moment_constants(p: np.ndarray, L: int) -> None:
    """Fill the moment block of ``p`` and switch the moment form on if it represents the
    weights ("Sliding moments" in :func:`intelligent_step`)."""
    p[_MOM] = 0.0
    p[_REFRESH] = float(L)
    if L < MOMENT_MIN_LENGTH:
        return
    h = 2.0 / (L - 1)
    x = -1.0 + np.arange(L + 1) * h  # as the kernel: -1.0 + i * h
    powers = np.arange(_ND)
    vand = x[:L, None] ** powers
    mb = _HP + 4 * L
    blocks = ((_HP, L, _MB_CY), (_HP + L, L - 1, _MB_CU), (_HP + 2 * L, L, _MB_CDY),
              (_HP + 3 * L, L - 1, _MB_CDU))
    coefs = []
    for start, n, dest in blocks:
        w = p[start:start + n]
        c = np.linalg.lstsq(vand[:n], w, rcond=None)[0]
        scale = float(np.max(np.abs(w)))
        if float(np.max(np.abs(vand[:n] @ c - w), initial=0.0)) > _MOMENT_FIT_RTOL * scale:
            return  # not polynomial of degree <= MOMENT_DEGREE: the plain sums
        coefs.append((dest, c))
    for dest, c in coefs:
        p[mb + dest: mb + dest + _ND] = c
    for m in range(_ND):
        for j in range(m + 1):
            p[mb + _MB_B + m * _ND + j] = math.comb(m, j) * h ** (m - j)  # binomial shift
        p[mb + _MB_ADD + m] = x[0] ** m  # the entering sample, lag 0
        p[mb + _MB_DY + m] = x[L] ** m  # the leaving y, lag L after the shift
        p[mb + _MB_DU + m] = x[L - 1] ** m  # the leaving u, lag L - 1 after the shift
    p[_MOM] = 1.0


def _check_window(name: str, value, lo: int, what: str) -> None:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        raise ValueError(f"{name} = {value!r} samples: expected an integer")
    if value < lo:
        raise ValueError(f"{name} = {value!r} samples: {what} needs at least {lo}")


def make_state(p: np.ndarray) -> np.ndarray:
    """A fresh (reset) state array for the parameter array ``p`` (layout :class:`IST`)."""
    s = np.zeros(_HS + 4 * int(p[_L]), dtype=np.float64)
    intelligent_reset(p, s)
    return s


@dataclass(frozen=True, slots=True)
class ErrorDynamicsGains:
    """Gains of an intelligent controller: ``kp`` (1/s^nu), ``ki`` (1/s^(nu+1)), ``kd`` (1/s)."""

    kp: float
    ki: float
    kd: float


def error_dynamics_gains(
    nu: int,
    *,
    time_constant: float | None = None,
    natural_frequency: float | None = None,
    damping: float | None = None,
    integral_pole: float | None = None,
) -> ErrorDynamicsGains:
    """Gains that give the closed-loop error the desired linear dynamics.

    With a perfect F estimate the plant disappears from the loop (paper Section 3.2.2) and the
    error ``e = y - y_ref`` obeys

    * iP  (nu = 1): ``e' + Kp e = 0``; ``Kp = 1 / time_constant``;
    * iPI (nu = 1): ``e'' + Kp e' + Ki e = 0`` (differentiated), poles ``-1/time_constant`` and
      ``-integral_pole``: ``Kp = 1/tau + p``, ``Ki = p / tau``;
    * iPD (nu = 2): ``e'' + Kd e' + Kp e = 0``; ``Kp = wn^2``, ``Kd = 2 zeta wn``;
    * iPID (nu = 2): ``e''' + Kd e'' + Kp e' + Ki e = 0``, characteristic polynomial
      ``(s^2 + 2 zeta wn s + wn^2)(s + p)``: ``Kd = 2 zeta wn + p``, ``Kp = wn^2 + 2 zeta wn p``,
      ``Ki = wn^2 p``.

    Parameters
    ----------
    nu : int
        1 or 2.
    time_constant : float
        Desired error time constant ``tau``, s (nu = 1).
    natural_frequency, damping : float
        ``wn`` in rad/s and ``zeta`` (nu = 2).
    integral_pole : float, optional
        ``p`` in 1/s, the extra real pole that the integral adds; None: no integral (Ki = 0).

    Returns
    -------
    ErrorDynamicsGains

    References
    ----------
    .. [P] paper Section 3.2.2 (closed-loop error equation); NOTES.md "Intelligent controllers".
    """
    p = 0.0 if integral_pole is None else positive("integral_pole", integral_pole, "1/s")
    nu = one_of("nu", nu, (1, 2))
    if nu == 1:
        if time_constant is None:
            raise ValueError("time_constant = None: required for nu = 1 (the error's time "
                             "constant, s)")
        if natural_frequency is not None or damping is not None:
            given = [f"{name} = {value!r}{unit}" for name, value, unit in
                     (("natural_frequency", natural_frequency, " rad/s"), ("damping", damping, ""))
                     if value is not None]
            raise ValueError(f"{', '.join(given)}: not used for nu = 1 (give time_constant)")
        tau = positive("time_constant", time_constant, "s")
        return ErrorDynamicsGains(kp=1.0 / tau + p, ki=p / tau, kd=0.0)
    if nu == 2:
        if natural_frequency is None or damping is None:
            raise ValueError(
                f"natural_frequency = {natural_frequency!r} rad/s, damping = {damping!r}: "
                "both required for nu = 2"
            )
        if time_constant is not None:
            raise ValueError(f"time_constant = {time_constant!r} s: not used for nu = 2 (give "
                             "natural_frequency, damping)")
        wn = positive("natural_frequency", natural_frequency, "rad/s")
        z = positive("damping", damping, "-")
        return ErrorDynamicsGains(
            kp=wn * wn + 2.0 * z * wn * p, ki=wn * wn * p, kd=2.0 * z * wn + p
        )


# --------------------------------------------------------------------------------------------
# Python shell
# --------------------------------------------------------------------------------------------
@dataclass(frozen=True, slots=True)
class IntelligentStatus:
    """Snapshot of an intelligent controller's state after its last step.

    Attributes
    ----------
    samples : int
        Samples stored in the window (saturates at the buffer length).
    window_full : bool
        The estimator is running (before: ``u0`` is held).
    n_nonfinite : int
        Steps held because ``y`` or the reference was not finite.
    nonfinite : bool
        The last step was such a held step.
    saturated : int
        -1 / 0 / +1: the last output is clipped at ``u_min`` / not clipped / at ``u_max``.
    rate_limited : int
        -1 / 0 / +1: the rate limit cut the last output's fall / nothing / its rise.
    f_hat : float
        Last F estimate, y-unit/s^nu.
    error : float
        Last ``e = y - y_ref`` (the paper's sign for the ultra-local model's law; the flatness
        controller's errors are reference minus output).
    error_rate : float
        Last ``e'`` estimate (nu = 2).
    integral : float
        ``int e dt``.
    u : float
        Last applied output.
    """

    samples: int
    window_full: bool
    n_nonfinite: int
    nonfinite: bool
    saturated: int
    rate_limited: int
    f_hat: float
    error: float
    error_rate: float
    integral: float
    u: float


def intelligent_status(p: np.ndarray, s: np.ndarray) -> IntelligentStatus:
    """The :class:`IntelligentStatus` of the state array ``s`` (parameters ``p``)."""
    return IntelligentStatus(
        samples=int(s[_K]),
        window_full=int(s[_K]) >= int(p[_L]),
        n_nonfinite=int(s[_NNF]),
        nonfinite=bool(s[_NF]),
        saturated=int(s[_SAT]),
        rate_limited=int(s[_RL]),
        f_hat=float(s[_FH]),
        error=float(s[_E]),
        error_rate=float(s[_ED]),
        integral=float(s[_INT]),
        u=float(s[_U]),
    )


class IntelligentController(CompiledController):
    """Python shell over :func:`intelligent_step` (one SISO loop; use one instance per loop).

    Parameters
    ----------
    params : IntelligentParams

    Examples
    --------
    >>> c = IP(alpha=2.0, kp=5.0, dt=0.01, window=10)
    >>> u = c.step(y=0.0, y_ref=1.0, y_ref_dot=0.0)

    References
    ----------
    .. [P] paper Section 3.2; NOTES.md "Intelligent controllers".
    """

    __slots__ = ()

    def __init__(self, params: IntelligentParams) -> None:
        super().__init__(params, IntelligentParams, make_state)

    def reset(self) -> None:
        """Back to the state right after construction."""
        intelligent_reset(self._p, self._s)

    def step(
        self, y: float, y_ref: float, y_ref_dot: float = 0.0, y_ref_ddot: float = 0.0, *,
        applied: float | None = None,
    ) -> float:
        """One sample: measurement ``y`` at ``t_k`` and the reference; returns the applied ``u_k``.

        ``applied`` (u-unit, optional) is the input actually applied over the last sample, when
        something after the controller changed its output: an actuator's lag, range or rate
        limit the controller does not know, a fault. The F estimator must see the applied input
        (module docstring; :func:`intelligent_set_applied`), and the rate limit then acts from
        it. ``None``, or a non-finite value (a lost feedback frame), takes the controller's own
        last output; before the first step it is ignored.

        Until the estimator's window is full (its first ``window - 1`` samples) the output is
        the start value ``u0`` (a bumpless start, module docstring), not the law's.
        See :func:`intelligent_step`. Each argument must be one real number (``ValueError``
        naming it otherwise: text, ``None``, an array); a non-finite ``y`` or reference
        (``y_ref_ddot`` for nu = 2 only) is a missing sample (the previous output is held,
        module docstring). The returned output is always finite: should the law overflow
        (values of the order of 1e300 in ``y``, the reference, or a sample still in the
        window), the step raises ``ValueError`` naming the inputs, after resetting the
        controller (as :meth:`reset`: the window held the overflowed values, which would make
        every later output NaN).
        """
        # the common path (floats) costs one type test per argument (_shell docstring)
        y = y if isinstance(y, float) else real("y", y)
        y_ref = y_ref if isinstance(y_ref, float) else real("y_ref", y_ref)
        if not isinstance(y_ref_dot, float):
            y_ref_dot = real("y_ref_dot", y_ref_dot)
        if not isinstance(y_ref_ddot, float):
            y_ref_ddot = real("y_ref_ddot", y_ref_ddot)
        if applied is not None:
            if not isinstance(applied, float):
                applied = real("applied", applied)
            intelligent_set_applied(self._p, self._s, applied)  # non-finite: ignored there
        u = intelligent_step(self._p, self._s, y, y_ref, y_ref_dot, y_ref_ddot)
        if not math.isfinite(u):  # the law overflowed (a finite u0 is always held)
            self.reset()
            raise nonfinite_command(
                type(self).__name__, {"u": u},
                {"y": y, "y_ref": y_ref, "y_ref_dot": y_ref_dot, "y_ref_ddot": y_ref_ddot},
                "the controller was reset (its window held the overflowed values)")
        return u

    @property
    def status(self) -> IntelligentStatus:
        """Counters and flags after the last step (:class:`IntelligentStatus`)."""
        return intelligent_status(self._p, self._s)

    def __repr__(self) -> str:
        return f"{type(self).__name__}({self._params!r})"


def _no_integral(cls: str, options: dict, unit: str, instead: str) -> None:
    """Refuse a nonzero ``ki`` in a shorthand without an integral term (IP, IPD); ``kd`` of an
    IP is refused by :class:`IntelligentParams` itself (nu = 1)."""
    if "ki" in options and finite("ki", options["ki"], unit) != 0.0:
        raise ValueError(f"ki = {options['ki']!r} {unit}: must be 0 for an {cls} (use {instead} "
                         "for an integral term)")


class IP(IntelligentController):
    """Intelligent proportional controller, nu = 1: ``u = -(F_hat - y_ref' + Kp e) / alpha``.

    Keyword arguments as :class:`IntelligentParams` (``nu = 1``, ``ki = kd = 0`` fixed: a
    nonzero ``ki`` or ``kd`` raises ``ValueError``); the same holds for :class:`IPI`
    (``kd = 0``), :class:`IPD` (``ki = 0``) and :class:`IPID` with their own gains.

    References
    ----------
    .. [P] paper eq. (ip); NOTES.md "Intelligent controllers".
    """

    __slots__ = ()

    def __init__(
        self, *, alpha: float, kp: float, dt: float, window: int, **options
    ) -> None:
        _no_integral("IP", options, "1/s^2", "IPI")
        super().__init__(
            IntelligentParams(nu=1, alpha=alpha, kp=kp, dt=dt, window=window, **options)
        )


class IPI(IntelligentController):
    """Intelligent PI, nu = 1: ``u = -(F_hat - y_ref' + Kp e + Ki int e) / alpha`` (``kd = 0``).

    References
    ----------
    .. [P] paper eq. (iPI_c); NOTES.md "Intelligent controllers".
    """

    __slots__ = ()

    def __init__(
        self, *, alpha: float, kp: float, ki: float, dt: float, window: int, **options
    ) -> None:
        super().__init__(
            IntelligentParams(nu=1, alpha=alpha, kp=kp, ki=ki, dt=dt, window=window, **options)
        )


class IPD(IntelligentController):
    """Intelligent PD, nu = 2: ``u = -(F_hat - y_ref'' + Kp e + Kd e') / alpha`` (``ki = 0``).

    References
    ----------
    .. [P] paper eq. (iPD_c) (without the typo "Kp e dt"); NOTES.md "Intelligent controllers".
    """

    __slots__ = ()

    def __init__(
        self, *, alpha: float, kp: float, kd: float, dt: float, window: int, **options
    ) -> None:
        _no_integral("IPD", options, "1/s^3", "IPID")
        super().__init__(
            IntelligentParams(nu=2, alpha=alpha, kp=kp, kd=kd, dt=dt, window=window, **options)
        )


class IPID(IntelligentController):
    """Intelligent PID, nu = 2: ``u = -(F_hat - y_ref'' + Kp e + Ki int e + Kd e') / alpha``.

    References
    ----------
    .. [P] paper eq. (iPID_c); NOTES.md "Intelligent controllers".
    """

    __slots__ = ()

    def __init__(
        self,
        *,
        alpha: float,
        kp: float,
        ki: float,
        kd: float,
        dt: float,
        window: int,
        **options,
    ) -> None:
        super().__init__(
            IntelligentParams(
                nu=2, alpha=alpha, kp=kp, ki=ki, kd=kd, dt=dt, window=window, **options
            )
        )
