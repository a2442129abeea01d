"""Flatness of the paper's 3DoF model: flat outputs, the maps A and B, and the singular speed.

The 3DoF design model (:mod:`flatfree.models.bicycle3dof`, paper Section 2.1) is flat with the
outputs (paper eq. (flatness_outputs), NOTES.md "Flat outputs")::

    y1 = vx                       [m/s]
    y2 = lf m vy - Iz r           [kg m^2/s]   (minus the angular momentum about the
                                                centre of the front axle)

The steer angle and the wheel accelerations cancel in the derivative of y2 (NOTES.md)::

    y2' = -lf m vx r - Cr L (vy - lr r) / vx,         L = lf + lr

so the state follows from (y1, y2, y2') (map A, paper eq. (x_A_y1_y2_y2p), printed correctly)::

    D(y1) = Cr L (Iz - lf lr m) + (lf m y1)^2
    r     = -(lf m y1 y2' + Cr L y2) / D(y1)
    vy    = (y2 + Iz r) / (lf m)
    vx    = y1

and the inputs u = [tw, delta] enter the next derivatives affinely (paper eq. (U_B_y1_y2_y2p))::

    [y1', y2''] = Delta(y1, y2, y2') u + Phi(y1, y2, y2')
    u = B(y1, y1', y2, y2', y2'') = Delta^-1 ([y1', y2''] - Phi)

Here Delta and Phi are computed from the model's f and g at the state A(y): with
``h(x) = y2'``, row 1 is ``(g[0, :], f[0])`` and row 2 is ``(dh/dx g, dh/dx f)``. Their
determinant is the paper's eq. (delta_matrice), correct with L = lf + lr (NOTES.md)::

    det Delta = (J_f w_dot_f - Cf R) (lf^2 m^2 y1^2 - Cr L lf lr m + Cr Iz L) / (Iz R^2 y1 m^2)

It depends on y1 only (and on the front wheel acceleration). The wheel accelerations
``w_dot_f, w_dot_r`` are exogenous, as in the model (default 0). With the model's rolling
closure ``w_dot = vx_dot / R`` pass ``wdot_f = wdot_r = y1' / R`` (y1' being the commanded
value): B then inverts the closed model exactly.

The singular speed
------------------
The factor ``D(y1)`` of det Delta (the same D as in map A) vanishes when ``Iz < lf lr m``
(yaw index below 1, common for real cars; the paper's condition "Iz > lf m" is a typo,
NOTES.md) at ::

    vx* = sqrt(Cr L (lf lr m - Iz)) / (lf m)

(:func:`singular_speed`). At vx* neither A nor B exists; near it they divide by ~0. So:

* the maps here refuse a speed inside the band ``vx*/(1 + margin) < y1 < vx* (1 + margin)``
  (default ``margin = MAP_MARGIN`` = 5 %): the Python functions raise ``ValueError``, the
  compiled kernels return a :class:`FlatStatus` code and zeros, never a division by ~0 or a NaN.
  Outside that band ``|D(y1)| / (|Cr L (Iz - lf lr m)| + (lf m y1)^2) >= ((1 + margin)^2 - 1) /
  ((1 + margin)^2 + 1)`` (about 0.049 for 5 %): the normalized determinant stays away from 0
  (:func:`singularity_ratio`);
* the flatness *controller* (closed loop, a later step, not in this module) must use these
  helpers to refuse, at construction, a speed reference that enters the band
  ``(vx*/(1 + margin), vx* (1 + margin))`` or crosses vx* (:func:`check_reference_speeds`),
  and, at run time, to hand over (report a status, stop computing B) when the measured speed
  falls below :func:`safe_speed` ``= (1 + margin) vx*``. The default controller margin
  ``SAFE_MARGIN`` = 50 % keeps the normalized determinant above 0.38.

When ``Iz >= lf lr m`` there is no singular speed (:func:`singular_speed` returns None,
:func:`safe_speed` returns 0). For the bundled presets: peugeot406 vx* = 0.58 m/s, bmw320i
1.08 m/s (yaw indices 0.998, 0.996), dallara_av21 10.8 m/s (yaw index 0.59).

The other factor, ``J_f w_dot_f - Cf R``, vanishes only at an absurd front wheel acceleration
(``Cf R / J_f``, about 1.7e4 rad/s^2 for the 406): the maps refuse ``J_f |w_dot_f| > Cf R / 2``.

Two doors (DESIGN.md "Speed by design"): compiled kernels (``*_kernel``, ``numba.njit``) over
the parameter array ``Bicycle3DoFParams.to_array()`` (layout ``BP``), and checked Python
functions. The controller's model parameters are a separate ``Bicycle3DoFParams`` from the
plant's, so a mismatch study (the paper's Figure 2, 0.3 Cf and 0.3 Cr) is
``dataclasses.replace(p, cf=0.3 * p.cf, cr=0.3 * p.cr)``.

References
----------
[paper] B. d'Andrea-Novel, L. Menhour, M. Fliess, H. Mounier, "Some remarks on wheeled
    autonomous vehicles and the evolution of their control design", Sections 2.2-2.3
    (docs/README.md).
NOTES.md "Flat outputs (Section 2.3)": the corrected singularity condition.
"""

from __future__ import annotations

import enum
import math

import numba
import numpy as np

from flatfree._validate import finite, positive, real_array
from flatfree.models.bicycle3dof import BP, Bicycle3DoFParams, _affine

__all__ = [
    "FlatStatus",
    "MAP_MARGIN",
    "SAFE_MARGIN",
    "flat_outputs",
    "flat_output_rates",
    "state_from_flat",
    "decoupling_matrices",
    "input_from_flat",
    "det_delta",
    "singular_speed",
    "singular_band",
    "safe_speed",
    "singularity_ratio",
    "check_reference_speeds",
    "flat_outputs_kernel",
    "flat_rates_kernel",
    "state_from_flat_kernel",
    "decoupling_kernel",
    "input_from_flat_kernel",
    "det_delta_kernel",
    "singular_speed_kernel",
    "map_status_kernel",
]

#: Default relative half-width of the speed band around vx* refused by the maps [-].
MAP_MARGIN = 0.05
#: Default margin of :func:`safe_speed` for the closed-loop controller [-]: vx >= 1.5 vx*.
SAFE_MARGIN = 0.5
#: The maps refuse J_f |w_dot_f| > WHEEL_ACCEL_FRACTION * Cf R (det Delta factor) [-].
WHEEL_ACCEL_FRACTION = 0.5


class FlatStatus(enum.IntEnum):
    """Status code of the compiled maps (0 = computed; otherwise outputs are zeros)."""

    ok = 0
    bad_speed = 1  # y1 <= 0 or a non-finite argument
    singular_speed = 2  # y1 inside the refused band around vx*
    wheel_accel = 3  # J_f |w_dot_f| > WHEEL_ACCEL_FRACTION Cf R


_M, _IZ, _LF, _LR, _CF, _CR, _RW, _JF, _JR = (int(b) for b in BP)
_OK = int(FlatStatus.ok)
_BAD = int(FlatStatus.bad_speed)
_SING = int(FlatStatus.singular_speed)
_WHEEL = int(FlatStatus.wheel_accel)


# --------------------------------------------------------------------------------------------
# Compiled kernels
# --------------------------------------------------------------------------------------------
@numba.njit(cache=True)
def flat_outputs_kernel(vx, vy, r, p):
    """(y1, y2, y2') from the state (vx > 0, not checked). NOTES.md "Flat outputs"."""
    m = p[_M]
    lf = p[_LF]
    lr = p[_LR]
    L = lf + lr
    y2 = lf * m * vy - p[_IZ] * r  # paper eq. (flatness_outputs)
    y2d = -lf * m * vx * r - p[_CR] * L * (vy - lr * r) / vx  # NOTES.md: y2_dot
    return vx, y2, y2d


@numba.njit(cache=True)
def _h_grad(vx, vy, r, p):
    """Gradient of h(x) = y2' with respect to (vx, vy, r)."""
    m = p[_M]
    lf = p[_LF]
    lr = p[_LR]
    crl = p[_CR] * (lf + lr)
    return (
        -lf * m * r + crl * (vy - lr * r) / (vx * vx),
        -crl / vx,
        -lf * m * vx + crl * lr / vx,
    )


@numba.njit(cache=True)
def flat_rates_kernel(vx, vy, r, tw, delta, p, wdot_f, wdot_r):
    """(y1', y2'') along the model from a state and an input (vx > 0, not checked).

    Chain rule: y1' = vx_dot, y2'' = grad h . x_dot with the model's x_dot.
    """
    f1, f2, f3, g11, g12, g22, g32 = _affine(vx, vy, r, p, wdot_f, wdot_r)
    vxd = f1 + g11 * tw + g12 * delta
    vyd = f2 + g22 * delta
    rd = f3 + g32 * delta
    hx, hy, hr = _h_grad(vx, vy, r, p)
    return vxd, hx * vxd + hy * vyd + hr * rd


@numba.njit(cache=True)
def _d_of(y1, p):
    """D(y1) = Cr L (Iz - lf lr m) + (lf m y1)^2 and its normalization scale."""
    m = p[_M]
    lf = p[_LF]
    lr = p[_LR]
    a = p[_CR] * (lf + lr) * (p[_IZ] - lf * lr * m)
    b = (lf * m * y1) ** 2
    return a + b, abs(a) + b


@numba.njit(cache=True)
def singular_speed_kernel(p):
    """vx* [m/s] where det Delta = 0, or 0.0 when Iz >= lf lr m (no singular speed)."""
    m = p[_M]
    lf = p[_LF]
    lr = p[_LR]
    k = lf * lr * m - p[_IZ]  # NOTES.md: the factor is (Iz - Lf Lr m)
    if k <= 0.0:
        return 0.0
    return math.sqrt(p[_CR] * (lf + lr) * k) / (lf * m)  # NOTES.md: Vx*


@numba.njit(cache=True)
def map_status_kernel(y1, p, wdot_f, margin):
    """FlatStatus code of the maps at speed y1 (refused band ``margin`` around vx*)."""
    if not (math.isfinite(y1) and math.isfinite(wdot_f)) or not y1 > 0.0:
        return _BAD
    vs = singular_speed_kernel(p)
    if vs > 0.0 and vs / (1.0 + margin) < y1 < vs * (1.0 + margin):
        return _SING
    if p[_JF] * abs(wdot_f) > WHEEL_ACCEL_FRACTION * p[_CF] * p[_RW]:
        return _WHEEL
    return _OK


@numba.njit(cache=True)
def state_from_flat_kernel(y1, y2, y2d, p, margin):
    """Map A: (vx, vy, r, status) from (y1, y2, y2'); zeros and a status code when refused."""
    st = map_status_kernel(y1, p, 0.0, margin)
    if st != _OK or not (math.isfinite(y2) and math.isfinite(y2d)):
        return 0.0, 0.0, 0.0, (st if st != _OK else _BAD)
    m = p[_M]
    lf = p[_LF]
    lr = p[_LR]
    d, _scale = _d_of(y1, p)
    r = -(lf * m * y1 * y2d + p[_CR] * (lf + lr) * y2) / d  # paper eq. (x_A_y1_y2_y2p)
    vy = (y2 + p[_IZ] * r) / (lf * m)  # paper eq. (x_A_y1_y2_y2p)
    return y1, vy, r, _OK


@numba.njit(cache=True)
def _decoupling_at_state(vx, vy, r, p, wdot_f, wdot_r):
    f1, f2, f3, g11, g12, g22, g32 = _affine(vx, vy, r, p, wdot_f, wdot_r)
    hx, hy, hr = _h_grad(vx, vy, r, p)
    d11 = g11  # y1' = f1 + g11 tw + g12 delta
    d12 = g12
    d21 = hx * g11  # y2'' = grad h . (f + g u); g21 = g31 = 0
    d22 = hx * g12 + hy * g22 + hr * g32
    phi1 = f1
    phi2 = hx * f1 + hy * f2 + hr * f3
    return d11, d12, d21, d22, phi1, phi2


@numba.njit(cache=True)
def decoupling_kernel(y1, y2, y2d, p, wdot_f, wdot_r, margin):
    """(Delta11, Delta12, Delta21, Delta22, Phi1, Phi2, status) at (y1, y2, y2').

    paper eq. (U_B_y1_y2_y2p). Zeros and a status code when refused.
    """
    st = map_status_kernel(y1, p, wdot_f, margin)
    if st != _OK or not math.isfinite(wdot_r):
        return 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, (st if st != _OK else _BAD)
    vx, vy, r, st = state_from_flat_kernel(y1, y2, y2d, p, margin)
    if st != _OK:
        return 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, st
    d11, d12, d21, d22, phi1, phi2 = _decoupling_at_state(vx, vy, r, p, wdot_f, wdot_r)
    return d11, d12, d21, d22, phi1, phi2, _OK


@numba.njit(cache=True)
def det_delta_kernel(y1, p, wdot_f):
    """det Delta, the paper's closed form eq. (delta_matrice) with L = lf + lr (no checks)."""
    m = p[_M]
    lf = p[_LF]
    lr = p[_LR]
    rw = p[_RW]
    L = lf + lr
    num = (p[_JF] * wdot_f - p[_CF] * rw) * (
        lf * lf * y1 * y1 * m * m - p[_CR] * L * lr * lf * m + p[_CR] * p[_IZ] * L
    )
    return num / (p[_IZ] * rw * rw * y1 * m * m)


@numba.njit(cache=True)
def input_from_flat_kernel(y1, y1d, y2, y2d, y2dd, p, wdot_f, wdot_r, margin):
    """Map B: (tw, delta, status) = Delta^-1 ([y1', y2''] - Phi); zeros and a status when refused.

    paper eq. (u_B_y1_y1p_y2_y2p_y2pp). Outside the refused band det Delta is bounded away
    from 0 (module docstring), so the explicit 2x2 inverse is safe.
    """
    if not (math.isfinite(y1d) and math.isfinite(y2dd)):
        return 0.0, 0.0, _BAD
    d11, d12, d21, d22, phi1, phi2, st = decoupling_kernel(y1, y2, y2d, p, wdot_f, wdot_r, margin)
    if st != _OK:
        return 0.0, 0.0, st
    det = d11 * d22 - d12 * d21
    a = y1d - phi1
    b = y2dd - phi2
    tw = (d22 * a - d12 * b) / det
    delta = (-d21 * a + d11 * b) / det
    return tw, delta, _OK


# --------------------------------------------------------------------------------------------
# Python API
# --------------------------------------------------------------------------------------------
def _state(x) -> tuple[float, float, float]:
    arr = real_array("x", x)
    if arr.shape != (3,):
        raise ValueError(
            f"x has shape {arr.shape}: expected (3,) = [vx (m/s), vy (m/s), r (rad/s)]"
        )
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"x = {arr.tolist()}: must be finite")
    if arr[0] <= 0.0:
        raise ValueError(f"vx = {float(arr[0])!r} m/s: the flat outputs divide by vx; must be > 0")
    return float(arr[0]), float(arr[1]), float(arr[2])


def _margin(margin) -> float:
    return positive("margin", margin, "-")


def _raise_status(params: Bicycle3DoFParams, status: int, y1: float, wdot_f: float,
                  margin: float) -> None:
    if status == FlatStatus.ok:
        return
    if status == FlatStatus.singular_speed:
        vs = singular_speed(params)
        raise ValueError(
            f"y1 = vx = {y1!r} m/s is within {100 * margin:g} % of the singular speed "
            f"vx* = {vs!r} m/s of the flatness maps (Iz = {params.iz!r} kg m^2 < lf lr m = "
            f"{params.lf * params.lr * params.m!r} kg m^2): det(Delta) ~ 0 there. A flatness "
            f"controller must refuse such a reference, or hand over below safe_speed(params) "
            f"= {safe_speed(params)!r} m/s"
        )
    if status == FlatStatus.wheel_accel:
        raise ValueError(
            f"wdot_f = {wdot_f!r} rad/s^2: J_f |wdot_f| exceeds {WHEEL_ACCEL_FRACTION} Cf R "
            f"= {WHEEL_ACCEL_FRACTION * params.cf * params.wheel_radius!r} N m, near the "
            "det(Delta) factor J_f wdot_f - Cf R = 0"
        )
    raise ValueError(f"y1 = vx = {y1!r} m/s: must be finite and > 0 (flat outputs divide by vx)")


def flat_outputs(params: Bicycle3DoFParams, x) -> np.ndarray:
    """Flat outputs and the derivative that map A needs: ``[y1, y2, y2']``.

    Parameters
    ----------
    params : Bicycle3DoFParams
        The (controller's) model parameters.
    x : array_like, shape (3,)
        ``[vx, vy, r]`` [m/s, m/s, rad/s], ``vx > 0``.

    Returns
    -------
    ndarray, shape (3,)
        ``y1 = vx`` [m/s], ``y2 = lf m vy - Iz r`` [kg m^2/s],
        ``y2' = -lf m vx r - Cr L (vy - lr r)/vx`` [kg m^2/s^2].

    References
    ----------
    [paper] eq. (flatness_outputs); NOTES.md "Flat outputs".
    """
    vx, vy, r = _state(x)
    return np.array(flat_outputs_kernel(vx, vy, r, params.to_array()))


def flat_output_rates(
    params: Bicycle3DoFParams, x, u, *, wdot_f: float = 0.0, wdot_r: float = 0.0
) -> np.ndarray:
    """``[y1', y2'']`` along the 3DoF model at state ``x`` and input ``u = [tw, delta]``.

    Computed by the chain rule from the model's vector field (not from Delta and Phi).

    References
    ----------
    [paper] eqs. (affine_NL_modele), (flatness_outputs).
    """
    vx, vy, r = _state(x)
    ua = real_array("u", u)
    if ua.shape != (2,) or not np.all(np.isfinite(ua)):
        raise ValueError(f"u = {ua.tolist()}: expected 2 finite values [tw (N m), delta (rad)]")
    wf = finite("wdot_f", wdot_f, "rad/s^2")
    wr = finite("wdot_r", wdot_r, "rad/s^2")
    return np.array(
        flat_rates_kernel(vx, vy, r, float(ua[0]), float(ua[1]), params.to_array(), wf, wr)
    )


def state_from_flat(
    params: Bicycle3DoFParams, y1: float, y2: float, y2d: float, *, margin: float = MAP_MARGIN
) -> np.ndarray:
    """Map A: the state ``[vx, vy, r]`` from ``(y1, y2, y2')``.

    Parameters
    ----------
    params : Bicycle3DoFParams
        The (controller's) model parameters.
    y1, y2, y2d : float
        ``y1 = vx`` [m/s] (> 0), ``y2`` [kg m^2/s], ``y2'`` [kg m^2/s^2].
    margin : float
        Relative half-width of the refused speed band around vx* [-], > 0.

    Returns
    -------
    ndarray, shape (3,)
        ``[vx, vy, r]`` [m/s, m/s, rad/s].

    Raises
    ------
    ValueError
        ``y1 <= 0``, a non-finite value, or ``y1`` within ``margin`` of the singular speed.

    References
    ----------
    [paper] eq. (x_A_y1_y2_y2p) (printed correctly, NOTES.md).
    """
    y1 = finite("y1", y1, "m/s")
    y2 = finite("y2", y2, "kg m^2/s")
    y2d = finite("y2d", y2d, "kg m^2/s^2")
    mg = _margin(margin)
    vx, vy, r, st = state_from_flat_kernel(y1, y2, y2d, params.to_array(), mg)
    _raise_status(params, st, y1, 0.0, mg)
    return np.array([vx, vy, r])


def decoupling_matrices(
    params: Bicycle3DoFParams,
    y1: float,
    y2: float,
    y2d: float,
    *,
    wdot_f: float = 0.0,
    wdot_r: float = 0.0,
    margin: float = MAP_MARGIN,
) -> tuple[np.ndarray, np.ndarray]:
    """``Delta`` (2, 2) and ``Phi`` (2,) with ``[y1', y2''] = Delta u + Phi``.

    Parameters
    ----------
    params : Bicycle3DoFParams
        The (controller's) model parameters.
    y1, y2, y2d : float
        Flat outputs and derivative as in :func:`state_from_flat`.
    wdot_f, wdot_r : float
        Exogenous front and rear wheel angular accelerations [rad/s^2].
    margin : float
        Relative half-width of the refused speed band around vx* [-], > 0.

    Returns
    -------
    Delta : ndarray, shape (2, 2)
        Rows ``y1', y2''``, columns ``tw`` [N m], ``delta`` [rad].
    Phi : ndarray, shape (2,)
        ``[y1', y2'']`` at ``u = 0`` [m/s^2, kg m^2/s^3].

    Raises
    ------
    ValueError
        As :func:`state_from_flat`, or a front wheel acceleration near ``Cf R / J_f``.

    References
    ----------
    [paper] eq. (U_B_y1_y2_y2p).
    """
    y1 = finite("y1", y1, "m/s")
    y2 = finite("y2", y2, "kg m^2/s")
    y2d = finite("y2d", y2d, "kg m^2/s^2")
    wf = finite("wdot_f", wdot_f, "rad/s^2")
    wr = finite("wdot_r", wdot_r, "rad/s^2")
    mg = _margin(margin)
    *vals, st = decoupling_kernel(y1, y2, y2d, params.to_array(), wf, wr, mg)
    _raise_status(params, st, y1, wf, mg)
    d11, d12, d21, d22, phi1, phi2 = vals
    return np.array([[d11, d12], [d21, d22]]), np.array([phi1, phi2])


def input_from_flat(
    params: Bicycle3DoFParams,
    y1: float,
    y1d: float,
    y2: float,
    y2d: float,
    y2dd: float,
    *,
    wdot_f: float = 0.0,
    wdot_r: float = 0.0,
    margin: float = MAP_MARGIN,
) -> np.ndarray:
    """Map B: the input ``[tw (N m), delta (rad)]`` that gives ``y1'`` and ``y2''``.

    ``u = Delta^-1 ([y1', y2''] - Phi)`` at ``(y1, y2, y2')``. With the rolling closure of the
    model pass ``wdot_f = wdot_r = y1d / R``.

    Parameters
    ----------
    params : Bicycle3DoFParams
        The (controller's) model parameters.
    y1, y1d : float
        ``vx`` [m/s] (> 0) and the wanted ``vx_dot`` [m/s^2].
    y2, y2d, y2dd : float
        ``y2`` [kg m^2/s], ``y2'`` [kg m^2/s^2] and the wanted ``y2''`` [kg m^2/s^3].
    wdot_f, wdot_r : float
        Exogenous front and rear wheel angular accelerations [rad/s^2].
    margin : float
        Relative half-width of the refused speed band around vx* [-], > 0.

    Returns
    -------
    ndarray, shape (2,)
        ``[tw (N m), delta (rad)]``.

    Raises
    ------
    ValueError
        ``y1 <= 0``, a non-finite value, ``y1`` within ``margin`` of the singular speed
        (the message gives vx* and :func:`safe_speed`), or an absurd front wheel acceleration.

    References
    ----------
    [paper] eq. (u_B_y1_y1p_y2_y2p_y2pp).
    """
    y1 = finite("y1", y1, "m/s")
    y1d = finite("y1d", y1d, "m/s^2")
    y2 = finite("y2", y2, "kg m^2/s")
    y2d = finite("y2d", y2d, "kg m^2/s^2")
    y2dd = finite("y2dd", y2dd, "kg m^2/s^3")
    wf = finite("wdot_f", wdot_f, "rad/s^2")
    wr = finite("wdot_r", wdot_r, "rad/s^2")
    mg = _margin(margin)
    tw, delta, st = input_from_flat_kernel(y1, y1d, y2, y2d, y2dd, params.to_array(), wf, wr, mg)
    _raise_status(params, st, y1, wf, mg)
    return np.array([tw, delta])


def det_delta(params: Bicycle3DoFParams, vx: float, *, wdot_f: float = 0.0) -> float:
    """det Delta at speed ``vx`` > 0 [units of Delta11 Delta22: 1/(kg m) x kg m^2/s^2 /rad].

    The paper's closed form (eq. (delta_matrice), L = lf + lr); it is evaluated, not refused,
    so it can be plotted through the singular speed.

    References
    ----------
    [paper] eq. (delta_matrice); NOTES.md "Flat outputs".
    """
    v = positive("vx", vx, "m/s")
    wf = finite("wdot_f", wdot_f, "rad/s^2")
    return float(det_delta_kernel(v, params.to_array(), wf))


def singular_speed(params: Bicycle3DoFParams) -> float | None:
    """The speed vx* [m/s] where det Delta and map A are singular, or None if Iz >= lf lr m.

    ``vx* = sqrt(Cr L (lf lr m - Iz)) / (lf m)``, real only for a yaw index Iz / (m lf lr) < 1.
    There the steer loses its authority over the flat output y2 = lf m Vy - Iz r: it cancels in
    y2' (NOTES.md) and acts on y2'' with ``d y2'' / d delta = C_f C_r L G(Vx) / (m Iz Vx)``,
    G the steady ratio d y2 / d r (:func:`flatfree.controllers.vehicle.y2_per_r`; sympy,
    tests/test_paper_scenarios.py), which vanishes at vx*. So both flat-output designs fail
    near it: the flatness controller's decoupling matrix is singular and the flat-output
    model-free loop has no input gain (its sign reversed below vx*). The peugeot406 (yaw index
    1.00) has vx* = 0.58 m/s; the dallara_av21 (0.59) 10.8 m/s, which its recording passes
    when it stops at the end.

    References
    ----------
    NOTES.md "Flat outputs (Section 2.3)" (the paper's condition has a typo).
    """
    vs = float(singular_speed_kernel(params.to_array()))
    return vs if vs > 0.0 else None


def singular_band(
    params: Bicycle3DoFParams, margin: float = MAP_MARGIN
) -> tuple[float, float] | None:
    """The refused speed band ``(vx*/(1 + margin), vx* (1 + margin))`` [m/s], or None."""
    mg = _margin(margin)
    vs = singular_speed(params)
    if vs is None:
        return None
    return vs / (1.0 + mg), vs * (1.0 + mg)


def safe_speed(params: Bicycle3DoFParams, margin: float = SAFE_MARGIN) -> float:
    """Lowest speed [m/s] at which a flatness controller should run: ``(1 + margin) vx*``.

    0.0 when there is no singular speed (Iz >= lf lr m). Below it the controller (a later
    step) hands over; see the module docstring.
    """
    mg = _margin(margin)
    vs = singular_speed(params)
    return 0.0 if vs is None else (1.0 + mg) * vs


def singularity_ratio(params: Bicycle3DoFParams, vx):
    """Normalized determinant ``D(vx) / (|Cr L (Iz - lf lr m)| + (lf m vx)^2)`` in [-1, 1].

    1 far from the singular speed (and always when Iz >= lf lr m), 0 at vx*, negative below
    it. ``det Delta`` is proportional to ``D(vx) / vx``. Accepts a scalar or an array.
    """
    v = real_array("vx", vx)
    if not np.all(np.isfinite(v)):
        raise ValueError("vx: must be finite [m/s]")
    m, lf, lr = params.m, params.lf, params.lr
    a = params.cr * (lf + lr) * (params.iz - lf * lr * m)
    b = (lf * m * v) ** 2
    out = (a + b) / (abs(a) + b)
    return float(out) if out.ndim == 0 else out


def check_reference_speeds(
    params: Bicycle3DoFParams, vx_ref, *, margin: float = SAFE_MARGIN
) -> None:
    """Refuse a speed reference that a flatness controller cannot follow.

    Raises ``ValueError`` if any speed is <= 0 or non-finite, enters the band
    ``(vx*/(1 + margin), vx* (1 + margin))`` around the singular speed, or if the reference
    has speeds on both sides of vx* (it crosses the singularity). Returns None otherwise.
    """
    v = np.atleast_1d(real_array("vx_ref", vx_ref))
    if v.size == 0:
        raise ValueError("vx_ref: empty speed reference")
    if not np.all(np.isfinite(v)) or np.any(v <= 0.0):
        raise ValueError("vx_ref: every reference speed must be finite and > 0 m/s")
    band = singular_band(params, margin)
    if band is None:
        return
    lo, hi = band
    vs = singular_speed(params)
    inside = (v > lo) & (v < hi)
    if np.any(inside):
        k = int(np.argmax(inside))
        raise ValueError(
            f"vx_ref[{k}] = {float(v[k])!r} m/s lies within {100 * margin:g} % of the singular "
            f"speed vx* = {vs!r} m/s of the flatness maps; the reference must stay above "
            f"safe_speed = {hi!r} m/s (or below {lo!r} m/s without crossing vx*)"
        )
    if np.any(v < vs) and np.any(v > vs):
        raise ValueError(
            f"vx_ref crosses the singular speed vx* = {vs!r} m/s of the flatness maps "
            f"(min {float(v.min())!r}, max {float(v.max())!r} m/s)"
        )
