"""The paper's 3DoF nonlinear two-wheel (bicycle) design model, Section 2.1.

Frame and reference point: ISO 8855 body axes at the CoG (x forward, y left, z up, yaw
counter-clockwise positive). SI units throughout.

State (``BicycleState``)::

    vx  [m/s]    longitudinal speed of the CoG in body axes (must be > 0)
    vy  [m/s]    lateral speed of the CoG in body axes (left positive)
    r   [rad/s]  yaw rate (counter-clockwise positive)

Pose-extended state (``BicyclePoseState``): ``x, y [m]`` position of the CoG in the ground
frame, ``psi [rad]`` yaw angle, then ``vx, vy, r`` as above.

Inputs (``BicycleInput``)::

    tw     [N m]  total wheel torque (drive > 0, brake < 0), summed over all wheels
    delta  [rad]  road-wheel steer angle of the front axle (left positive)

Model (paper eq. (affine_NL_modele), NOTES.md "3DoF model")::

    x_dot = f(x; w_dot_f, w_dot_r) + g(x; w_dot_f) u

    f = [ r vy - (J_f w_dot_f + J_r w_dot_r) / (m R),
          -r vx + ( -C_f (vy + l_f r)/vx - C_r (vy - l_r r)/vx ) / m,
          ( -l_f C_f (vy + l_f r)/vx + l_r C_r (vy - l_r r)/vx ) / I_z ]

    g = [[ 1/(m R),  C_f (vy + l_f r) / (m vx)          ],
         [ 0,        (C_f R - J_f w_dot_f) / (m R)       ],
         [ 0,        l_f (C_f R - J_f w_dot_f) / (I_z R) ]]

with linear tyres in the paper's sign convention ``F_yf = C_f alpha_f``,
``alpha_f = delta - (vy + l_f r)/vx``, ``F_yr = C_r alpha_r``, ``alpha_r = -(vy - l_r r)/vx``
(``C_f, C_r > 0`` per axle; this alpha is minus the ISO slip angle), small steer angles
(sin delta ~ delta, cos delta ~ 1, delta^2 dropped) and the wheel spin equations
``J_i w_dot_i = T_i - R F_xi``. In the lateral and yaw rows the front longitudinal force that
the steer rotates is the inertial part ``-J_f w_dot_f / R`` only: the product of drive torque
and steer angle (``T_f delta / R``, bilinear in the inputs) is not in the paper's affine form.
This is exact for a car whose front axle is not driven, and the affine approximation for a
front-driven one. ``tests/test_bicycle3dof.py`` derives all of this from Newton's equations.

The wheel angular accelerations ``w_dot_f, w_dot_r`` [rad/s^2] are exogenous signals in the
paper: every function takes them as arguments (default 0, i.e. the wheel-inertia terms
vanish). ``J_f, J_r`` [kg m^2] are the spin inertias of the whole front and rear axle (both
wheels); the paper's single ``I_r`` is the case ``J_f = J_r = I_r``. Optionally, the
*rolling closure* ``w_f = w_r = vx / R`` (so ``w_dot = vx_dot / R``) closes the model; the
longitudinal row then solves ``vx_dot (1 + (J_f + J_r)/(m R^2)) = r vy + tw/(m R) +
C_f delta (vy + l_f r)/(m vx)`` and the result is no longer affine in ``u`` (``rolling=True``).

The model divides by ``vx``: the Python API raises ``ValueError`` for ``vx <= 0``; the
compiled kernels do not check (the caller's responsibility) and return inf/NaN there.
Input limits are not part of the model.

References
----------
[paper] B. d'Andrea-Novel, L. Menhour, M. Fliess, H. Mounier, "Some remarks on wheeled
    autonomous vehicles and the evolution of their control design", Section 2.1
    (docs/README.md), with the corrections of NOTES.md.
[Raj] R. Rajamani, Vehicle Dynamics and Control, 2nd ed., 2012, Ch. 2 (bicycle model) and
    Ch. 3 (understeer gradient).
"""

from __future__ import annotations

import enum
import math
from dataclasses import dataclass, field

import numba
import numpy as np

from flatfree._validate import finite, nonnegative, positive, real_array
from flatfree._vecmath import all_finite

__all__ = [
    "BP",
    "BicycleInput",
    "BicyclePoseState",
    "BicycleState",
    "Bicycle3DoFParams",
    "affine_form",
    "vector_field",
    "simulate",
    "affine_kernel",
    "rhs_kernel",
    "rhs_rolling_kernel",
    "rk4_step_into",
    "rk4_step_kernel",
    "rk4_kernel",
]


# --------------------------------------------------------------------------------------------
# Layouts
# --------------------------------------------------------------------------------------------
class BicycleState(enum.IntEnum):
    """State layout of the 3DoF model: vx [m/s], vy [m/s], r [rad/s] (CoG, body axes)."""

    vx = 0
    vy = 1
    r = 2


class BicyclePoseState(enum.IntEnum):
    """Pose-extended layout: x, y [m], psi [rad] (ground frame), vx, vy [m/s], r [rad/s]."""

    x = 0
    y = 1
    psi = 2
    vx = 3
    vy = 4
    r = 5


class BicycleInput(enum.IntEnum):
    """Input layout: tw [N m] total wheel torque, delta [rad] front road-wheel steer angle."""

    tw = 0
    delta = 1


class BP(enum.IntEnum):
    """Index enum of ``Bicycle3DoFParams.to_array()`` (for the compiled kernels)."""

    m = 0
    iz = 1
    lf = 2
    lr = 3
    cf = 4
    cr = 5
    wheel_radius = 6
    wheel_inertia_front = 7
    wheel_inertia_rear = 8


# integer constants for the kernels (numba freezes module-level ints at compile time)
_M, _IZ, _LF, _LR, _CF, _CR, _RW, _JF, _JR = (int(b) for b in BP)


def _u(unit: str):
    return field(metadata={"unit": unit})


# --------------------------------------------------------------------------------------------
# Parameters
# --------------------------------------------------------------------------------------------
@dataclass(frozen=True, slots=True, kw_only=True)
class Bicycle3DoFParams:
    """Parameters of the paper's 3DoF two-wheel model (Section 2.1, Table 1).

    Attributes
    ----------
    m : float
        Vehicle mass [kg].
    iz : float
        Yaw moment of inertia about the CoG [kg m^2].
    lf, lr : float
        Distances from the CoG to the front and rear axle [m].
    cf, cr : float
        Cornering stiffness of the whole front and rear AXLE [N/rad], positive, in the paper's
        convention ``F_yf = C_f alpha_f``, ``alpha_f = delta - (vy + lf r)/vx``.
    wheel_radius : float
        Effective rolling radius R [m].
    wheel_inertia_front, wheel_inertia_rear : float
        Spin inertia of the front and rear axle's wheels together [kg m^2] (>= 0; 0 drops the
        paper's wheel-inertia terms). The paper's single ``I_r`` is the case of equal values.

    Variants come from ``dataclasses.replace`` (e.g. the paper's Figure 2 mismatch
    ``replace(p, cf=0.3 * p.cf, cr=0.3 * p.cr)``). Every value is validated: a bad one raises
    ``ValueError`` naming the field, the value and the unit.

    References
    ----------
    [paper] Section 2.1 and Table 1; NOTES.md "3DoF model".
    """

    m: float = _u("kg")
    iz: float = _u("kg m^2")
    lf: float = _u("m")
    lr: float = _u("m")
    cf: float = _u("N/rad")
    cr: float = _u("N/rad")
    wheel_radius: float = _u("m")
    wheel_inertia_front: float = _u("kg m^2")
    wheel_inertia_rear: float = _u("kg m^2")

    def __post_init__(self) -> None:
        for name in ("m", "iz", "lf", "lr", "cf", "cr", "wheel_radius"):
            positive(name, getattr(self, name), _UNITS[name])
        for name in ("wheel_inertia_front", "wheel_inertia_rear"):
            nonnegative(name, getattr(self, name), _UNITS[name])

    @classmethod
    def from_vehicle(cls, vp) -> Bicycle3DoFParams:
        """The 3DoF parameters of a :class:`~flatfree.vehicles.VehicleParams`.

        ``cf, cr`` = 2 x ``flatfree.tires.cornering_stiffness(tire, F_z)`` at the static load
        per wheel ``F_z`` (half the static axle load m g l_r/L, m g l_f/L); the wheel inertias
        are 2 x the per-wheel spin inertias (the two wheels of an axle spin together in a
        bicycle model). Mass, yaw inertia, lf, lr and the rolling radius are copied.

        References
        ----------
        VEHICLE_MODEL.md section 2.5 (per-axle stiffness at static load), section 4.2
        (peugeot406: C_f / C_r = 97,700 / 73,800 N/rad).
        """
        from flatfree.tires import cornering_stiffness  # per tyre, N/rad, > 0

        fz_front_axle, fz_rear_axle = vp.static_axle_loads
        return cls(
            m=vp.mass,
            iz=vp.iz,
            lf=vp.lf,
            lr=vp.lr,
            cf=2.0 * cornering_stiffness(vp.tire_front, 0.5 * fz_front_axle),
            cr=2.0 * cornering_stiffness(vp.tire_rear, 0.5 * fz_rear_axle),
            wheel_radius=vp.wheel_radius,
            wheel_inertia_front=2.0 * vp.wheel_inertia_front,
            wheel_inertia_rear=2.0 * vp.wheel_inertia_rear,
        )

    # ----- derived quantities -----
    @property
    def wheelbase(self) -> float:
        """L = lf + lr [m]."""
        return self.lf + self.lr

    @property
    def understeer_gradient(self) -> float:
        """K_us = (m/L)(lr/C_f - lf/C_r) [rad/(m/s^2)] ([Raj] Ch. 3, per-axle stiffness)."""
        return self.m / self.wheelbase * (self.lr / self.cf - self.lf / self.cr)

    @property
    def yaw_index(self) -> float:
        """Iz / (m lf lr) [-]; below 1 the flatness maps have a singular speed (NOTES.md)."""
        return self.iz / (self.m * self.lf * self.lr)

    def to_array(self) -> np.ndarray:
        """The parameters as a float64 array laid out by ``BP`` (for compiled kernels)."""
        out = np.empty(len(BP), dtype=np.float64)
        for member in BP:
            out[member] = float(getattr(self, member.name))
        return out


_UNITS = {
    "m": "kg", "iz": "kg m^2", "lf": "m", "lr": "m", "cf": "N/rad", "cr": "N/rad",
    "wheel_radius": "m", "wheel_inertia_front": "kg m^2", "wheel_inertia_rear": "kg m^2",
}


# --------------------------------------------------------------------------------------------
# Compiled kernels (scalar core)
# --------------------------------------------------------------------------------------------
@numba.njit(cache=True)
def _affine(vx, vy, r, p, wdot_f, wdot_r):
    """f and the nonzero entries of g: (f1, f2, f3, g11, g12, g22, g32). g21 = g31 = 0."""
    m = p[_M]
    iz = p[_IZ]
    lf = p[_LF]
    lr = p[_LR]
    cf = p[_CF]
    cr = p[_CR]
    rw = p[_RW]
    sf = (vy + lf * r) / vx  # delta - alpha_f (paper)
    sr = (vy - lr * r) / vx  # -alpha_r (paper)
    f1 = r * vy - (p[_JF] * wdot_f + p[_JR] * wdot_r) / (m * rw)  # paper f_1
    f2 = -r * vx + (-cf * sf - cr * sr) / m  # paper f_2
    f3 = (-lf * cf * sf + lr * cr * sr) / iz  # paper f_3
    kf = (cf * rw - p[_JF] * wdot_f) / rw  # paper g_22 m = (C_f R - I_r w_dot_f)/R
    g11 = 1.0 / (m * rw)  # paper g_11
    g12 = cf * sf / m  # paper g_12
    g22 = kf / m  # paper g_22
    g32 = lf * kf / iz  # paper g_32
    return f1, f2, f3, g11, g12, g22, g32


@numba.njit(cache=True)
def _rates(vx, vy, r, tw, delta, p, wdot_f, wdot_r):
    """(vx_dot, vy_dot, r_dot) of the affine model with exogenous wheel accelerations."""
    f1, f2, f3, g11, g12, g22, g32 = _affine(vx, vy, r, p, wdot_f, wdot_r)
    return f1 + g11 * tw + g12 * delta, f2 + g22 * delta, f3 + g32 * delta


@numba.njit(cache=True)
def _rates_rolling(vx, vy, r, tw, delta, p):
    """(vx_dot, vy_dot, r_dot) with the rolling closure w_dot_f = w_dot_r = vx_dot / R."""
    m = p[_M]
    rw = p[_RW]
    # row 1 with w_dot = vx_dot / R moved to the left-hand side (module docstring)
    f1, _f2, _f3, g11, g12, _g22, _g32 = _affine(vx, vy, r, p, 0.0, 0.0)
    vx_dot = (f1 + g11 * tw + g12 * delta) / (1.0 + (p[_JF] + p[_JR]) / (m * rw * rw))
    wdot = vx_dot / rw
    _a, f2, f3, _b, _c, g22, g32 = _affine(vx, vy, r, p, wdot, wdot)
    return vx_dot, f2 + g22 * delta, f3 + g32 * delta


@numba.njit(cache=True)
def _fill_rhs(x, vx_dot, vy_dot, r_dot, out):
    n = x.shape[0]
    if n == 3:
        out[0] = vx_dot
        out[1] = vy_dot
        out[2] = r_dot
    else:  # pose-extended: ground-frame kinematics of the CoG
        psi = x[2]
        c = math.cos(psi)
        s = math.sin(psi)
        out[0] = x[3] * c - x[4] * s
        out[1] = x[3] * s + x[4] * c
        out[2] = x[5]
        out[3] = vx_dot
        out[4] = vy_dot
        out[5] = r_dot


@numba.njit(cache=True)
def affine_kernel(x, p, wdot_f, wdot_r):
    """Compiled f(x) (shape (3,)) and g(x) (shape (3, 2)) at a 3-state ``x`` (see module doc).

    No checks: ``x[0] = vx`` must be > 0 (the caller's responsibility).
    """
    f1, f2, f3, g11, g12, g22, g32 = _affine(x[0], x[1], x[2], p, wdot_f, wdot_r)
    f = np.empty(3)
    g = np.zeros((3, 2))
    f[0] = f1
    f[1] = f2
    f[2] = f3
    g[0, 0] = g11
    g[0, 1] = g12
    g[1, 1] = g22
    g[2, 1] = g32
    return f, g


@numba.njit(cache=True)
def rhs_kernel(x, u, p, wdot_f, wdot_r):
    """Compiled x_dot = f + g u for a 3-state or 6-state (pose-extended) ``x``.

    Exogenous wheel accelerations ``wdot_f, wdot_r`` [rad/s^2]. No checks (``vx > 0``).
    """
    n = x.shape[0]
    o = n - 3
    a, b, c = _rates(x[o], x[o + 1], x[o + 2], u[0], u[1], p, wdot_f, wdot_r)
    out = np.empty(n)
    _fill_rhs(x, a, b, c, out)
    return out


@numba.njit(cache=True)
def rhs_rolling_kernel(x, u, p):
    """Compiled x_dot with the rolling closure w_dot = vx_dot / R (3 or 6 states, no checks)."""
    n = x.shape[0]
    o = n - 3
    a, b, c = _rates_rolling(x[o], x[o + 1], x[o + 2], u[0], u[1], p)
    out = np.empty(n)
    _fill_rhs(x, a, b, c, out)
    return out


@numba.njit(cache=True)
def _stage(psi, vx, vy, r, tw, delta, p, wdot_f, wdot_r, rolling):
    """All six rates at one RK stage (the pose rates are ignored for a 3-state run)."""
    if rolling:
        a, b, c = _rates_rolling(vx, vy, r, tw, delta, p)
    else:
        a, b, c = _rates(vx, vy, r, tw, delta, p, wdot_f, wdot_r)
    cs = math.cos(psi)
    sn = math.sin(psi)
    return vx * cs - vy * sn, vx * sn + vy * cs, r, a, b, c


@numba.njit(cache=True)
def rk4_step_into(x, u, dt, p, wdot_f, wdot_r, rolling, out):
    """One classical RK4 step of length ``dt`` [s] written into ``out`` (allocation-free).

    ``x`` and ``out`` have 3 or 6 entries (``out`` may be ``x``); the input ``u`` and the
    wheel accelerations are held over the step. No checks (``vx > 0`` along the step).
    """
    n = x.shape[0]
    pose = n == 6
    o = n - 3
    if pose:
        X, Y, psi = x[0], x[1], x[2]
    else:
        X, Y, psi = 0.0, 0.0, 0.0
    vx, vy, r = x[o], x[o + 1], x[o + 2]
    tw, de = u[0], u[1]
    h2 = 0.5 * dt
    a1, b1, c1, d1, e1, f1 = _stage(psi, vx, vy, r, tw, de, p, wdot_f, wdot_r, rolling)
    a2, b2, c2, d2, e2, f2 = _stage(psi + h2 * c1, vx + h2 * d1, vy + h2 * e1, r + h2 * f1,
                                    tw, de, p, wdot_f, wdot_r, rolling)
    a3, b3, c3, d3, e3, f3 = _stage(psi + h2 * c2, vx + h2 * d2, vy + h2 * e2, r + h2 * f2,
                                    tw, de, p, wdot_f, wdot_r, rolling)
    a4, b4, c4, d4, e4, f4 = _stage(psi + dt * c3, vx + dt * d3, vy + dt * e3, r + dt * f3,
                                    tw, de, p, wdot_f, wdot_r, rolling)
    h6 = dt / 6.0
    if pose:
        out[0] = X + h6 * (a1 + 2.0 * a2 + 2.0 * a3 + a4)
        out[1] = Y + h6 * (b1 + 2.0 * b2 + 2.0 * b3 + b4)
        out[2] = psi + h6 * (c1 + 2.0 * c2 + 2.0 * c3 + c4)
    out[o] = vx + h6 * (d1 + 2.0 * d2 + 2.0 * d3 + d4)
    out[o + 1] = vy + h6 * (e1 + 2.0 * e2 + 2.0 * e3 + e4)
    out[o + 2] = r + h6 * (f1 + 2.0 * f2 + 2.0 * f3 + f4)


@numba.njit(cache=True)
def rk4_step_kernel(x, u, dt, p, wdot_f, wdot_r, rolling):
    """One classical RK4 step (see :func:`rk4_step_into`); returns the new state array."""
    out = np.empty(x.shape[0])
    rk4_step_into(x, u, dt, p, wdot_f, wdot_r, rolling, out)
    return out


@numba.njit(cache=True)
def rk4_kernel(x0, u, dt, p, wdot, rolling):
    """Fixed-step RK4 trajectory: ``u`` (n, 2) and ``wdot`` (n, 2) held over each step.

    Returns ``(traj, n_ok)``: ``traj`` has shape (n + 1, len(x0)) with ``traj[0] = x0``.
    The integration stops after step ``n_ok`` if the state leaves the model's domain
    (``vx <= 0`` or a non-finite value); rows after ``n_ok`` are NaN. ``n_ok == n`` on success.
    ``wdot`` is ignored when ``rolling`` is true.
    """
    n = u.shape[0]
    nx = x0.shape[0]
    o = nx - 3
    traj = np.full((n + 1, nx), np.nan)
    traj[0] = x0
    x = x0.copy()
    for k in range(n):
        rk4_step_into(x, u[k], dt, p, wdot[k, 0], wdot[k, 1], rolling, x)
        if not (x[o] > 0.0 and all_finite(x)):
            return traj, k
        traj[k + 1] = x
    return traj, n


# --------------------------------------------------------------------------------------------
# Python API (thin shells with checks)
# --------------------------------------------------------------------------------------------
def _check_state(x, *, allow_pose: bool = True, name: str = "x") -> np.ndarray:
    arr = real_array(name, x)
    sizes = (3, 6) if allow_pose else (3,)
    if arr.ndim != 1 or arr.shape[0] not in sizes:
        raise ValueError(
            f"x has shape {arr.shape}: expected one of {[(s,) for s in sizes]} "
            "(BicycleState or BicyclePoseState layout)"
        )
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"x = {arr.tolist()}: must be finite")
    vx = float(arr[arr.shape[0] - 3])
    if vx <= 0.0:
        raise ValueError(f"vx = {vx!r} m/s: the 3DoF model divides by vx; it must be > 0")
    return np.ascontiguousarray(arr)


def _check_input(u) -> np.ndarray:
    arr = real_array("u", u)
    if arr.shape != (2,):
        raise ValueError(f"u has shape {arr.shape}: expected (2,) = [tw (N m), delta (rad)]")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"u = {arr.tolist()} [N m, rad]: must be finite")
    return np.ascontiguousarray(arr)


def affine_form(
    params: Bicycle3DoFParams, x, *, wdot_f: float = 0.0, wdot_r: float = 0.0
) -> tuple[np.ndarray, np.ndarray]:
    """The paper's affine form: f(x) of shape (3,) and g(x) of shape (3, 2).

    Parameters
    ----------
    params : Bicycle3DoFParams
    x : array_like, shape (3,)
        ``[vx, vy, r]`` (``BicycleState``), ``vx > 0``.
    wdot_f, wdot_r : float
        Front and rear wheel angular accelerations [rad/s^2] (exogenous in the paper).

    Returns
    -------
    f, g : ndarray
        ``x_dot = f + g @ [tw, delta]``.

    Raises
    ------
    ValueError
        ``vx <= 0``, a non-finite value or a wrong shape.

    References
    ----------
    [paper] Section 2.1, eq. (affine_NL_modele); NOTES.md "3DoF model".
    """
    xa = _check_state(x, allow_pose=False)
    wf = finite("wdot_f", wdot_f, "rad/s^2")
    wr = finite("wdot_r", wdot_r, "rad/s^2")
    return affine_kernel(xa, params.to_array(), wf, wr)


def vector_field(
    params: Bicycle3DoFParams,
    x,
    u,
    *,
    wdot_f: float = 0.0,
    wdot_r: float = 0.0,
    rolling: bool = False,
) -> np.ndarray:
    """x_dot of the 3DoF model (3 states) or of its pose extension (6 states).

    Parameters
    ----------
    params : Bicycle3DoFParams
    x : array_like, shape (3,) or (6,)
        ``BicycleState`` or ``BicyclePoseState`` layout, ``vx > 0``.
    u : array_like, shape (2,)
        ``[tw (N m), delta (rad)]``.
    wdot_f, wdot_r : float
        Exogenous wheel angular accelerations [rad/s^2] (ignored when ``rolling``).
    rolling : bool
        Use the rolling closure ``w_dot = vx_dot / R`` instead of exogenous ``wdot``.

    Returns
    -------
    ndarray
        The time derivative of ``x``, same layout.

    References
    ----------
    [paper] Section 2.1; NOTES.md "3DoF model".
    """
    xa = _check_state(x)
    ua = _check_input(u)
    p = params.to_array()
    if rolling:
        return rhs_rolling_kernel(xa, ua, p)
    wf = finite("wdot_f", wdot_f, "rad/s^2")
    wr = finite("wdot_r", wdot_r, "rad/s^2")
    return rhs_kernel(xa, ua, p, wf, wr)


def simulate(
    params: Bicycle3DoFParams,
    x0,
    u,
    dt: float,
    *,
    wdot=None,
    rolling: bool = False,
) -> np.ndarray:
    """Integrate the model with fixed-step RK4, inputs held constant over each step.

    Parameters
    ----------
    params : Bicycle3DoFParams
    x0 : array_like, shape (3,) or (6,)
        Initial state (``BicycleState`` or ``BicyclePoseState``), ``vx > 0``.
    u : array_like, shape (n, 2)
        Inputs ``[tw, delta]`` for each of the ``n`` steps (zero-order hold).
    dt : float
        Step [s], > 0.
    wdot : array_like, shape (n, 2), optional
        Exogenous wheel accelerations ``[w_dot_f, w_dot_r]`` [rad/s^2] per step (default 0).
    rolling : bool
        Use the rolling closure instead of ``wdot`` (then ``wdot`` must be None).

    Returns
    -------
    ndarray, shape (n + 1, len(x0))
        The states at ``t = k dt``, ``k = 0..n``.

    Raises
    ------
    ValueError
        Bad arguments, or the trajectory leaves the model's domain (``vx <= 0`` or a
        non-finite state): the message gives the time.

    References
    ----------
    [paper] Section 2.1. RK4: the classical Runge-Kutta method.
    """
    xa = _check_state(x0, name="x0")
    ua = np.ascontiguousarray(real_array("u", u))
    if ua.ndim != 2 or ua.shape[1] != 2:
        raise ValueError(f"u has shape {ua.shape}: expected (n, 2) = [tw (N m), delta (rad)]")
    if not np.all(np.isfinite(ua)):
        raise ValueError("u: all inputs must be finite [N m, rad]")
    h = positive("dt", dt, "s")
    n = ua.shape[0]
    if wdot is None:
        wa = np.zeros((n, 2))
    else:
        if rolling:
            raise ValueError("wdot is given with rolling=True: the closure defines wdot itself")
        wa = np.ascontiguousarray(real_array("wdot", wdot))
        if wa.shape != (n, 2):
            raise ValueError(f"wdot has shape {wa.shape}: expected {(n, 2)} [rad/s^2]")
        if not np.all(np.isfinite(wa)):
            raise ValueError("wdot: all wheel accelerations must be finite [rad/s^2]")
    traj, n_ok = rk4_kernel(xa, ua, h, params.to_array(), wa, bool(rolling))
    if n_ok < n:
        raise ValueError(
            f"the trajectory leaves the model's domain (vx <= 0 m/s or a non-finite state) "
            f"at t = {(n_ok + 1) * h!r} s (step {n_ok + 1} of {n})"
        )
    return traj
