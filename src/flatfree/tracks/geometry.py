"""Track geometry: arc-length resampling and smoothing, curvature, widths, Frenet projection.

A :class:`Track` is a path sampled at a **uniform arc-length step** ``ds``. Its compiled
representation is the table :attr:`Track.geometry` (rows = nodes, columns = :class:`GC`), which
the numba kernels below read. Between nodes the path is the cubic Hermite curve through the
node positions with the node unit tangents (C1, error O(ds^4 kappa^3)); heading and curvature
are the cubic Hermite curves with slopes kappa and dkappa/ds.

Conventions: ISO 8855 x-y plane (z up), heading psi counter-clockwise from +x, unwrapped along
the path; curvature kappa > 0 for a left (counter-clockwise) turn; Frenet lateral deviation
e_y > 0 when the point lies to the LEFT of the path; heading error e_psi = psi_vehicle -
psi_path wrapped to [-pi, pi).

A closed track stores N + 1 rows: the last row repeats the first point at s = L (with the heading
advanced by 2 pi times the turning number), so segment i always runs from row i to row i + 1.

References
----------
[Hermite] cubic Hermite basis: e.g. C. de Boor, A Practical Guide to Splines, rev. ed., 2001,
    ch. IV.
[curv] do Carmo, Differential Geometry of Curves and Surfaces, 1976, sec. 1-5:
    kappa = (x' y'' - y' x'') / (x'^2 + y'^2)^(3/2) for any regular parametrisation.
"""

from __future__ import annotations

import enum
import math
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numba
import numpy as np
from scipy.interpolate import make_interp_spline

from flatfree._validate import real, real_array
from flatfree._warn import warn
from flatfree.tracks._io import MIN_SEGMENT_M, validate_polyline

__all__ = [
    "GC",
    "DEFAULT_DS",
    "DEFAULT_SMOOTHING_LENGTH",
    "Track",
    "FrenetProjector",
    "frenet_project",
    "frenet_init",
    "lateral_deviation_acceleration",
    "project_points",
    "path_eval",
    "path_eval_many",
    "progress",
]


class GC(enum.IntEnum):
    """Columns of :attr:`Track.geometry` (all SI)."""

    S = 0  #: arc length [m]
    X = 1  #: position x [m]
    Y = 2  #: position y [m]
    TX = 3  #: unit tangent x = cos(psi) [-]
    TY = 4  #: unit tangent y = sin(psi) [-]
    PSI = 5  #: heading, unwrapped [rad]
    KAPPA = 6  #: curvature [1/m]
    DKAPPA = 7  #: d kappa / d s [1/m^2]
    W_LEFT = 8  #: distance to the left edge [m] (NaN when unknown)
    W_RIGHT = 9  #: distance to the right edge [m] (NaN when unknown)


N_GC = len(GC)
#: Default arc-length step of the resampled path [m]: well below the 5 m spacing of the TUMFTM
#: files, so the Hermite interpolation error (~ds^4 kappa^3 / 384) is below 1e-6 m for R >= 10 m.
DEFAULT_DS = 1.0
#: Default smoothing cut-off wavelength [m]. Chosen on the bundled TUMFTM centerlines (5 m
#: spacing): it removes the sample-to-sample wiggles (wavelengths of 2-4 samples) that make
#: the raw curvature spike (PROVENANCE.md: raw 3-pt max |kappa| 0.125 vs 0.075 smoothed on Spa),
#: and keeps hairpins (features >= 40 m long) within a few percent.
DEFAULT_SMOOTHING_LENGTH = 20.0
#: Order of the zero-phase low-pass H(f) = 1 / (1 + (f lambda_c)^(2n)), n = 4 (Butterworth magnitude
#: shape squared); a circle of radius R passes with gain 1 - (lambda_c / 2 pi R)^8.
_FILTER_ORDER = 4
#: How far an open path's ends are continued before the low-pass [cut-off lengths] (_lowpass)
_END_PAD = 2.0
#: Relative shortening of a path by its smoothing above which :meth:`Track.from_points` warns:
#: the bundled tracks and race lines change by at most 0.02 % at their cut-offs; Norisring
#: passes 2 % at a cut-off of ~135 m (its hairpins' curvature rises before: 0.101 1/m at the
#: default 20 m, 0.121 at 100 m) and Spa at ~240 m. Engineering choice (session 16).
_SMOOTH_SHRINK_WARN = 0.02
#: ``closed=None`` closes a path whose end is less than this many median point spacings from its
#: start (the TUMFTM files end one spacing before their first point, PROVENANCE.md).
_CLOSE_GAP_SPACINGS = 3.0
#: ... and warns when that closing segment is longer than this many median spacings: it then
#: bridges a gap that no segment of the data has, as an open road digitised sparsely (an
#: out-and-back) has between its ends. The bundled closed files' gap is one spacing (ratio
#: 1.0000-1.0002 on every TUMFTM centerline and race line); 1.5 leaves room for uneven spacing.
_CLOSE_WARN_SPACINGS = 1.5

_S, _X, _Y, _TX, _TY, _PSI, _K, _DK, _WL, _WR = (int(c) for c in GC)
_TWO_PI = 2.0 * math.pi
#: Newton stops when the foot-point update is below this [m] (quadratic convergence: the last
#: iterate is then ~1e-18 m off; 1e-9 m is far below any use of the projection).
_NEWTON_TOL_M = 1e-9


# ----------------------------------------------------------------------------------------------
# compiled kernels
# ----------------------------------------------------------------------------------------------
@numba.njit(cache=True, inline="always")
def _wrap(a: float) -> float:
    """Wrap an angle to [-pi, pi)."""
    return a - _TWO_PI * math.floor((a + math.pi) / _TWO_PI)


@numba.njit(cache=True, inline="always")
def _hermite_combine(g, i, h, h00, h10, h01, h11, d00, d10, d01, d11, e00, e10, e01, e11):
    """Position and its first two arc-length derivatives on segment i from the Hermite basis
    values (h..), their first (d..) and second (e..) derivatives [Hermite]; shared by
    :func:`_hermite` and :func:`_hermite_inv`, which differ only in how they form the basis."""
    x0 = g[i, _X]
    y0 = g[i, _Y]
    x1 = g[i + 1, _X]
    y1 = g[i + 1, _Y]
    tx0 = g[i, _TX] * h
    ty0 = g[i, _TY] * h
    tx1 = g[i + 1, _TX] * h
    ty1 = g[i + 1, _TY] * h
    px = h00 * x0 + h10 * tx0 + h01 * x1 + h11 * tx1
    py = h00 * y0 + h10 * ty0 + h01 * y1 + h11 * ty1
    dx = d00 * x0 + d10 * g[i, _TX] + d01 * x1 + d11 * g[i + 1, _TX]
    dy = d00 * y0 + d10 * g[i, _TY] + d01 * y1 + d11 * g[i + 1, _TY]
    ddx = e00 * x0 + e10 * g[i, _TX] + e01 * x1 + e11 * g[i + 1, _TX]
    ddy = e00 * y0 + e10 * g[i, _TY] + e01 * y1 + e11 * g[i + 1, _TY]
    return px, py, dx, dy, ddx, ddy


@numba.njit(cache=True, inline="always")
def _hermite_basis(t):
    """The cubic Hermite basis at ``t`` in [0, 1] [Hermite]: the four basis values, then the
    numerators of their first and of their second arc-length derivatives (the callers divide
    by the segment length h, or multiply by 1 / h: d00 = (6 t^2 - 6 t) / h, d10 = 3 t^2 - 4 t + 1
    (tangents scale by h), e00 = (12 t - 6) / h^2, e10 = (6 t - 4) / h, ...)."""
    t2 = t * t
    t3 = t2 * t
    return (2.0 * t3 - 3.0 * t2 + 1.0, t3 - 2.0 * t2 + t, -2.0 * t3 + 3.0 * t2, t3 - t2,
            6.0 * t2 - 6.0 * t, 3.0 * t2 - 4.0 * t + 1.0, -6.0 * t2 + 6.0 * t, 3.0 * t2 - 2.0 * t,
            12.0 * t - 6.0, 6.0 * t - 4.0, -12.0 * t + 6.0, 6.0 * t - 2.0)


@numba.njit(cache=True, inline="always")
def _hermite(g, i, sigma, h):
    """Position, first and second derivative w.r.t. arc length on segment i [Hermite]."""
    h00, h10, h01, h11, p00, d10, p01, d11, q00, q10, q01, q11 = _hermite_basis(sigma / h)
    return _hermite_combine(g, i, h, h00, h10, h01, h11, p00 / h, d10, p01 / h, d11,
                            q00 / (h * h), q10 / h, q01 / (h * h), q11 / h)


@numba.njit(cache=True, inline="always")
def _hermite_scalar(v0, m0, v1, m1, sigma, h):
    """Cubic Hermite value and derivative of a scalar with node values v and slopes m [Hermite]."""
    h00, h10, h01, h11, p00, d10, p01, d11, _, _, _, _ = _hermite_basis(sigma / h)
    val = h00 * v0 + h10 * h * m0 + h01 * v1 + h11 * h * m1
    der = p00 / h * v0 + d10 * m0 + p01 / h * v1 + d11 * m1
    return val, der


@numba.njit(cache=True, inline="always")
def _hermite_inv(g, i, sigma, h, inv_h):
    """:func:`_hermite` with the divisions by ``h`` as multiplications by ``inv_h = 1 / h``
    (the projection's Newton loop: same formulas to round-off, a multiplication where
    :func:`_hermite` divides)."""
    inv_h2 = inv_h * inv_h
    h00, h10, h01, h11, p00, d10, p01, d11, q00, q10, q01, q11 = _hermite_basis(sigma * inv_h)
    return _hermite_combine(g, i, h, h00, h10, h01, h11, p00 * inv_h, d10, p01 * inv_h, d11,
                            q00 * inv_h2, q10 * inv_h, q01 * inv_h2, q11 * inv_h)


@numba.njit(cache=True, inline="always")
def _hermite_scalar_value(v0, m0, v1, m1, sigma, h, inv_h):
    """The value of :func:`_hermite_scalar` (``inv_h = 1 / h``; the projection's heading and
    curvature, whose derivatives it does not use)."""
    h00, h10, h01, h11, _, _, _, _, _, _, _, _ = _hermite_basis(sigma * inv_h)
    return h00 * v0 + h10 * h * m0 + h01 * v1 + h11 * h * m1


@numba.njit(cache=True)
def path_eval(g, closed, s):
    """Path quantities at arc length ``s``.

    Parameters
    ----------
    g : ndarray (N+1, len(GC))
        :attr:`Track.geometry`.
    closed : bool
    s : float
        Arc length [m]; wrapped into [0, L) on a closed track. On an open track, ``s`` outside
        [0, L] lies on the straight extension of the end tangent (curvature 0 there).

    Returns
    -------
    (x, y, psi, kappa, dkappa_ds, w_left, w_right) : tuple of float
        SI units; psi is unwrapped (continuous along the path).
    """
    n_seg = g.shape[0] - 1
    h = g[1, _S] - g[0, _S]
    length = g[n_seg, _S]
    if closed:
        s = s - length * math.floor(s / length)
    else:
        if s < 0.0:
            return (g[0, _X] + s * g[0, _TX], g[0, _Y] + s * g[0, _TY], g[0, _PSI], 0.0, 0.0,
                    g[0, _WL], g[0, _WR])
        if s > length:
            d = s - length
            return (g[n_seg, _X] + d * g[n_seg, _TX], g[n_seg, _Y] + d * g[n_seg, _TY],
                    g[n_seg, _PSI], 0.0, 0.0, g[n_seg, _WL], g[n_seg, _WR])
    i = int(math.floor(s / h))
    if i > n_seg - 1:
        i = n_seg - 1
    if i < 0:
        i = 0
    sigma = s - g[i, _S]
    px, py, _, _, _, _ = _hermite(g, i, sigma, h)
    psi, _ = _hermite_scalar(g[i, _PSI], g[i, _K], g[i + 1, _PSI], g[i + 1, _K], sigma, h)
    kap, dkap = _hermite_scalar(g[i, _K], g[i, _DK], g[i + 1, _K], g[i + 1, _DK], sigma, h)
    w = sigma / h
    wl = (1.0 - w) * g[i, _WL] + w * g[i + 1, _WL]
    wr = (1.0 - w) * g[i, _WR] + w * g[i + 1, _WR]
    return px, py, psi, kap, dkap, wl, wr


@numba.njit(cache=True)
def path_eval_many(g, closed, s):
    """:func:`path_eval` over an array; returns an array (len(s), 7)."""
    out = np.empty((s.shape[0], 7))
    for k in range(s.shape[0]):
        r = path_eval(g, closed, s[k])
        for j in range(7):
            out[k, j] = r[j]
    return out


@numba.njit(cache=True, inline="always")
def _chord_t(g, i, x, y):
    ax = g[i + 1, _X] - g[i, _X]
    ay = g[i + 1, _Y] - g[i, _Y]
    return ((x - g[i, _X]) * ax + (y - g[i, _Y]) * ay) / (ax * ax + ay * ay)


@numba.njit(cache=True)
def frenet_project(g, closed, x, y, psi, seg):
    """Project a point onto the path by a **local** search that starts at segment ``seg``.

    The search walks along the segment chords from ``seg`` towards the foot point, then refines
    the foot point on the cubic Hermite segment with Newton's method on
    (P(sigma) - q) . P'(sigma) = 0. It never looks at the whole path, so on a self-crossing
    path it stays on the branch the vehicle is on, and the cost per call is O(1) when the
    vehicle moves less than a few segments between calls (amortised O(1) along a lap).

    Parameters
    ----------
    g : ndarray (N+1, len(GC))
        :attr:`Track.geometry`.
    closed : bool
    x, y : float
        Point (vehicle reference point) [m].
    psi : float
        Vehicle heading [rad], any branch.
    seg : int
        Segment of the previous projection (the state to carry between calls); for the first
        call use :func:`frenet_init` or a segment known to be near the point.

    Returns
    -------
    s : float
        Arc length of the foot point [m]; in [0, L) on a closed track; on an open track it is
        < 0 or > L beyond the ends (straight extension of the end tangents).
    e_y : float
        Signed lateral deviation [m], > 0 to the left of the path.
    e_psi : float
        psi - psi_path wrapped to [-pi, pi) [rad].
    kappa : float
        Path curvature at the foot point [1/m].
    seg : int
        Segment of the foot point, to pass to the next call.
    """
    n_seg = g.shape[0] - 1
    h = g[1, _S] - g[0, _S]
    inv_h = 1.0 / h  # the Hermite formulas multiply by it (one division per call)
    i = seg
    if closed:
        i = i % n_seg
    elif i < 0:
        i = 0
    elif i > n_seg - 1:
        i = n_seg - 1
    # 1) walk along the chords (bounded by n_seg steps; a few steps in a simulation loop)
    last = 0
    t = _chord_t(g, i, x, y)
    for _ in range(n_seg):
        if t < 0.0:
            if last == 1 or (i == 0 and not closed):
                break
            i = i - 1 if i > 0 else n_seg - 1
            last = -1
        elif t > 1.0:
            if last == -1 or (i == n_seg - 1 and not closed):
                break
            i = i + 1 if i < n_seg - 1 else 0
            last = 1
        else:
            break
        t = _chord_t(g, i, x, y)
    # 2) Newton on the cubic segment; move to a neighbour when the foot point leaves it
    sigma = min(max(t, 0.0), 1.0) * h
    px = py = dx = dy = 0.0
    done = False
    for _shift in range(4):
        done = False
        for _it in range(5):
            px, py, dx, dy, ddx, ddy = _hermite_inv(g, i, sigma, h, inv_h)
            rx = px - x
            ry = py - y
            fp = dx * dx + dy * dy + rx * ddx + ry * ddy
            if fp <= 0.0:  # point at/behind the centre of curvature: keep the estimate
                break
            step = (rx * dx + ry * dy) / fp
            sigma -= step
            if abs(step) < _NEWTON_TOL_M:
                done = True
                break
        if sigma < 0.0 and (closed or i > 0) and _shift < 3:
            i = i - 1 if i > 0 else n_seg - 1
            sigma += h
        elif sigma > h and (closed or i < n_seg - 1) and _shift < 3:
            i = i + 1 if i < n_seg - 1 else 0
            sigma -= h
        else:
            break
    if not closed and ((i == 0 and sigma < 0.0) or (i == n_seg - 1 and sigma > h)):
        # beyond an end of an open path: straight extension of the end tangent
        j = 0 if sigma < 0.0 else n_seg
        tx = g[j, _TX]
        ty = g[j, _TY]
        rx = x - g[j, _X]
        ry = y - g[j, _Y]
        along = rx * tx + ry * ty
        e_y = -rx * ty + ry * tx
        return g[j, _S] + along, e_y, _wrap(psi - g[j, _PSI]), 0.0, i
    if not done or sigma < 0.0 or sigma > h:
        sigma = min(max(sigma, 0.0), h)
        px, py, dx, dy, _, _ = _hermite_inv(g, i, sigma, h, inv_h)
    # (when Newton converged, px..dy are those of the last iterate, < 1e-9 m away)
    nrm = math.sqrt(dx * dx + dy * dy)
    e_y = (-(x - px) * dy + (y - py) * dx) / nrm
    psi_p = _hermite_scalar_value(g[i, _PSI], g[i, _K], g[i + 1, _PSI], g[i + 1, _K], sigma, h,
                                  inv_h)
    kap = _hermite_scalar_value(g[i, _K], g[i, _DK], g[i + 1, _K], g[i + 1, _DK], sigma, h,
                                inv_h)
    s = g[i, _S] + sigma
    if closed and s >= g[n_seg, _S]:
        s -= g[n_seg, _S]
    return s, e_y, _wrap(psi - psi_p), kap, i


@numba.njit(cache=True)
def lateral_deviation_acceleration_kernel(ax, ay, vx, vy, e_y, e_psi, kappa):
    """:func:`lateral_deviation_acceleration` compiled, for compiled loops: no argument checks,
    and NaN (not an error) at the path's centre of curvature, ``kappa e_y = 1``."""
    c = math.cos(e_psi)
    sn = math.sin(e_psi)
    vt = vx * c - vy * sn
    den = 1.0 - kappa * e_y
    if den == 0.0:
        return math.nan
    return ay * c + ax * sn - kappa * vt * vt / den


def lateral_deviation_acceleration(ax, ay, vx, vy, e_y, e_psi, kappa) -> float:
    """Second time derivative of the lateral deviation from the path [m/s^2] (kinematics).

    With the path's unit tangent t and left normal n at the foot point, e_y' = v . n and
    n' = -kappa t s', s' = (v . t) / (1 - kappa e_y), so

        e_y'' = a . n - kappa (v . t)^2 / (1 - kappa e_y),
        a . n = ay cos(e_psi) + ax sin(e_psi),  v . t = vx cos(e_psi) - vy sin(e_psi),

    for the CoG acceleration (ax, ay) and velocity (vx, vy) in body axes [m/s^2, m/s], the
    lateral deviation e_y [m] (left positive), the heading error e_psi [rad] and the path
    curvature kappa at the foot point [1/m]. No vehicle parameter; exact for a point moving
    in the plane (checked against the second difference of a simulated e_y in
    tests/test_imu_estimator.py). Not finite where an input is not (a lost measurement stays
    lost).

    Raises
    ------
    ValueError
        An argument that is not a real number (text, None, an array), or a point at the path's
        centre of curvature (``kappa e_y = 1``: no foot point moves with it).
    """
    args = (ax, ay, vx, vy, e_y, e_psi, kappa)
    if not all(type(a) is float for a in args):
        names = ("ax", "ay", "vx", "vy", "e_y", "e_psi", "kappa")
        units = ("m/s^2", "m/s^2", "m/s", "m/s", "m", "rad", "1/m")
        ax, ay, vx, vy, e_y, e_psi, kappa = (
            real(name, a, unit) for name, unit, a in zip(names, units, args, strict=True))
    if 1.0 - kappa * e_y == 0.0:
        raise ValueError(f"e_y = {e_y!r} m, kappa = {kappa!r} 1/m: the point is at the path's "
                         "centre of curvature (kappa e_y = 1), where e_y'' is not defined")
    return lateral_deviation_acceleration_kernel(ax, ay, vx, vy, e_y, e_psi, kappa)


@numba.njit(cache=True)
def frenet_init(g, closed, x, y, psi):
    """Segment to start :func:`frenet_project` from: the nearest node whose heading agrees with
    ``psi`` (within 90 degrees), or the nearest node if none agrees. O(N): call it once.

    At a self-crossing the heading picks the branch the vehicle drives on.
    """
    n_seg = g.shape[0] - 1
    best = -1
    best_d = np.inf
    any_best = 0
    any_d = np.inf
    c = math.cos(psi)
    sn = math.sin(psi)
    for k in range(n_seg + (0 if closed else 1)):
        d = (g[k, _X] - x) ** 2 + (g[k, _Y] - y) ** 2
        if d < any_d:
            any_d = d
            any_best = k
        if g[k, _TX] * c + g[k, _TY] * sn > 0.0 and d < best_d:
            best_d = d
            best = k
    k = best if best >= 0 else any_best
    return min(k, n_seg - 1)


@numba.njit(cache=True)
def project_points(g, closed, xs, ys, psis, seg):
    """Project a sequence of points in order (each from the previous foot point).

    Returns an array (n, 4) of (s, e_y, e_psi, kappa) and the last segment.
    """
    out = np.empty((xs.shape[0], 4))
    for k in range(xs.shape[0]):
        s, ey, ep, kap, seg = frenet_project(g, closed, xs[k], ys[k], psis[k], seg)
        out[k, 0] = s
        out[k, 1] = ey
        out[k, 2] = ep
        out[k, 3] = kap
    return out, seg


@numba.njit(cache=True)
def progress(s_new, s_old, length, closed):
    """Arc length travelled from ``s_old`` to ``s_new`` [m], unwrapped across the start/finish
    line of a closed track (assumes less than half a lap between the two calls)."""
    d = s_new - s_old
    if closed:
        d -= length * math.floor(d / length + 0.5)
    return d


# ----------------------------------------------------------------------------------------------
# building a track from points
# ----------------------------------------------------------------------------------------------
def _lowpass(v: np.ndarray, h: float, cutoff: float, periodic: bool) -> np.ndarray:
    """Zero-phase low-pass of uniformly spaced samples (rows), H(f) = 1/(1 + (f cutoff)^8).

    Periodic data are filtered as they are. Open data: each end is first continued over
    :data:`_END_PAD` cut-off lengths by the mirror image of the points next to it across the
    end's normal (the tangent from a parabola fitted over one cut-off length), so that the
    curvature runs on through the end (a circle continues as itself); then the straight line
    through the two new end points is removed, the residual (zero at both ends) is extended by
    odd reflection into a periodic signal without jumps (a sine series), filtered, the line
    added back and the continuations cut off. Straight lines are kept exactly. Measured on arcs
    sampled every metre, 20 m cut-off: the curvature at the end is 0.988 of the arc's at R = 100
    m, 0.963 at R = 50 m (before the continuation: -0.04, the curvature pulled to 0 within
    about one cut-off length of the ends and overshooting 14 % at 10 m); with 2 cm of white
    noise on the points its error at the ends is 3.3 % RMS, as inside the path (3.6 %),
    against 12 % for a cubic's tangent (benchmarks/open_path_ends.py; the tests hold the first
    three figures: tests/test_tracks_geometry.py).
    """
    n = v.shape[0]
    pad = 0
    if periodic:
        ext = v
        trend = 0.0
    else:
        # each end continued by its mirror image across the end's normal over two cut-off
        # lengths (a circle continues as itself: the curvature runs on through the end), so
        # the odd reflection's forced zero curvature lies beyond them
        fit = min(n, max(3, int(math.ceil(cutoff / h)) + 1))  # one cut-off length
        pad = min(n - 1, int(math.ceil(_END_PAD * cutoff / h)))
        head = _mirrored(v[:pad + 1], _end_tangent(v[:fit]))
        tail = _mirrored(v[::-1][:pad + 1], _end_tangent(v[::-1][:fit]))[::-1]
        v = np.concatenate([head, v, tail], axis=0)
        w = np.linspace(0.0, 1.0, v.shape[0])[:, None]
        trend = v[:1] + (v[-1:] - v[:1]) * w
        r = v - trend
        ext = np.concatenate([r, -r[-2:0:-1]], axis=0)
    m = ext.shape[0]
    f = np.fft.rfftfreq(m, h)
    gain = 1.0 / (1.0 + (f * cutoff) ** (2 * _FILTER_ORDER))
    out = np.fft.irfft(np.fft.rfft(ext, axis=0) * gain[:, None], m, axis=0)
    return out if periodic else (out[:v.shape[0]] + trend)[pad:pad + n]


def _end_tangent(y: np.ndarray) -> np.ndarray:
    """Unit tangent at the first row of ``y`` (points from the end inwards), from the
    least-squares parabola through them (rows at positions 0, 1, ...)."""
    c = np.polynomial.polynomial.polyfit(np.arange(y.shape[0], dtype=float), y, 2)
    return c[1] / np.linalg.norm(c[1])


def _mirrored(y: np.ndarray, t: np.ndarray) -> np.ndarray:
    """The rows ``y[1:]`` mirrored across the normal of ``t`` through ``y[0]``, in the order
    that continues the path beyond ``y[0]`` (the mirror of ``y[k]`` first for the largest k)."""
    d = y[1:] - y[0]
    return (y[1:] - 2.0 * (d @ t)[:, None] * t[None, :])[::-1]


_GL = {n: np.polynomial.legendre.leggauss(n) for n in (4, 6)}


def _arc(spl, a: np.ndarray, b: np.ndarray, n: int = 6) -> np.ndarray:
    """Arc length of the spline between parameters a and b within one knot interval
    (Gauss-Legendre with n points; |c'| is smooth there, the error is ~(h/L)^(2n))."""
    gx, gw = _GL[n]
    mid = 0.5 * (a + b)
    half = 0.5 * (b - a)
    pts = mid[:, None] + half[:, None] * gx[None, :]
    d = spl(pts.ravel(), 1)
    speed = np.hypot(d[:, 0], d[:, 1]).reshape(pts.shape)
    # (an elementwise sum, not ``speed @ gw``: a BLAS call here spawns threads that fight
    # for the cores of a busy machine and made the whole build 3x slower in the benchmark)
    return half * (speed * gw).sum(axis=1)


def _build_geometry(
    x: np.ndarray,
    y: np.ndarray,
    w_left: np.ndarray,
    w_right: np.ndarray,
    closed: bool,
    ds: float,
    smoothing_length: float,
) -> np.ndarray:
    """Smooth, fit, resample at uniform arc length; return the geometry table."""
    if closed:
        xc = np.append(x, x[0])
        yc = np.append(y, y[0])
    else:
        xc, yc = x, y
    u = np.concatenate([[0.0], np.cumsum(np.hypot(np.diff(xc), np.diff(yc)))])
    period = u[-1]
    pts = np.column_stack([xc, yc])
    u_fit = u
    if smoothing_length > 0.0:
        # uniform resampling in the chord parameter, then the zero-phase low-pass
        h_u = smoothing_length / 8.0  # 8 samples per cut-off wavelength
        n_u = max(int(math.ceil(period / h_u)), 8)
        cs = make_interp_spline(u, pts, k=3, bc_type="periodic" if closed else None, axis=0)
        if closed:
            uu = np.arange(n_u) * (period / n_u)
            filt = _lowpass(cs(uu), period / n_u, smoothing_length, True)
            pts = np.vstack([filt, filt[:1]])
            u_fit = np.append(uu, period)
        else:
            uu = np.linspace(0.0, period, n_u + 1)
            pts = _lowpass(cs(uu), period / n_u, smoothing_length, False)
            u_fit = uu
    n_fit = pts.shape[0] - (1 if closed else 0)
    k = 5 if n_fit >= 6 else 3
    spl = make_interp_spline(u_fit, pts, k=k, bc_type="periodic" if closed else None, axis=0)
    # arc length at the fit parameters, then invert s(u) at the uniform targets
    seg = _arc(spl, u_fit[:-1], u_fit[1:])
    big_s = np.concatenate([[0.0], np.cumsum(seg)])
    length = big_s[-1]
    n_seg = max(int(round(length / ds)), 3)
    s_t = np.linspace(0.0, length, n_seg + 1)
    j = np.clip(np.searchsorted(big_s, s_t, side="right") - 1, 0, len(seg) - 1)
    # u(s) on each knot interval: cubic Hermite with the exact end slopes du/ds = 1/|c'(u)|
    # (|c'| is nearly constant for a chord-length parameter), then Newton steps on
    # S(u) - s = 0 with S' = |c'| until the node arc lengths are right to 1e-9 m
    speed_k = np.hypot(*spl(u_fit, 1).T)
    tau = (s_t - big_s[j]) / seg[j]
    t2 = tau * tau
    t3 = t2 * tau
    ua = u_fit[j]
    ub = u_fit[j + 1]
    ut = ((2.0 * t3 - 3.0 * t2 + 1.0) * ua + (t3 - 2.0 * t2 + tau) * seg[j] / speed_k[j]
          + (-2.0 * t3 + 3.0 * t2) * ub + (t3 - t2) * seg[j] / speed_k[j + 1])
    for _ in range(4):
        res = big_s[j] + _arc(spl, ua, ut, 4) - s_t
        if np.abs(res).max() < 1e-9:
            break
        ut = np.clip(ut - res / np.hypot(*spl(ut, 1).T), ua, ub)
    ut[0] = u_fit[0]
    ut[-1] = u_fit[-1]
    p = spl(ut)
    d1 = spl(ut, 1)
    d2 = spl(ut, 2)
    d3 = spl(ut, 3)
    speed = np.hypot(d1[:, 0], d1[:, 1])
    cross = d1[:, 0] * d2[:, 1] - d1[:, 1] * d2[:, 0]
    dot12 = d1[:, 0] * d2[:, 0] + d1[:, 1] * d2[:, 1]
    cross13 = d1[:, 0] * d3[:, 1] - d1[:, 1] * d3[:, 0]
    kappa = cross / speed**3  # [curv]
    dkappa_du = cross13 / speed**3 - 3.0 * cross * dot12 / speed**5  # d/du of [curv]
    g = np.empty((n_seg + 1, N_GC))
    g[:, _S] = s_t
    g[:, _X] = p[:, 0]
    g[:, _Y] = p[:, 1]
    g[:, _TX] = d1[:, 0] / speed
    g[:, _TY] = d1[:, 1] / speed
    g[:, _PSI] = np.unwrap(np.arctan2(d1[:, 1], d1[:, 0]))
    g[:, _K] = kappa
    g[:, _DK] = dkappa_du / speed
    if closed:  # exact periodic closure of the table
        for c in (_X, _Y, _TX, _TY, _K, _DK):
            g[-1, c] = g[0, c]
    # widths: linear in the chord parameter of the input points
    u_in = u[: len(x)]
    if closed:
        g[:, _WL] = np.interp(ut, u_in, w_left, period=period)
        g[:, _WR] = np.interp(ut, u_in, w_right, period=period)
    else:
        g[:, _WL] = np.interp(ut, u_in, w_left)
        g[:, _WR] = np.interp(ut, u_in, w_right)
    return g


def _as_1d(name: str, v, n: int | None = None) -> np.ndarray:
    a = real_array(name, v)
    if a.ndim != 1:
        raise ValueError(f"{name}: expected a 1-D array, got shape {a.shape}")
    if n is not None and a.shape[0] != n:
        raise ValueError(f"{name}: expected {n} values, got {a.shape[0]}")
    return a


@dataclass(frozen=True, slots=True, kw_only=True, eq=False)
class Track:
    """A path (track centerline, race line or maneuver) resampled at uniform arc length.

    Build one with :meth:`Track.from_points` or :func:`flatfree.tracks.load_track`.

    Attributes
    ----------
    name : str
    closed : bool
        True for a loop (periodic in s with period :attr:`length`).
    geometry : ndarray (N+1, len(GC)), read-only
        The node table read by the compiled kernels (:func:`frenet_project`, :func:`path_eval`).
    source : str
        Where the points came from (file name or description).

    References
    ----------
    See the module docstring.
    """

    name: str = ""
    closed: bool
    geometry: np.ndarray = field(repr=False)
    source: str = ""

    def __post_init__(self) -> None:
        g = np.ascontiguousarray(real_array("geometry", self.geometry))
        if g.ndim != 2 or g.shape[1] != N_GC or g.shape[0] < 4:
            raise ValueError(f"geometry: expected shape (>=4, {N_GC}), got {g.shape}")
        cols = [c for c in GC if c not in (GC.W_LEFT, GC.W_RIGHT)]
        if not np.isfinite(g[:, cols]).all():
            raise ValueError("geometry: non-finite values")
        h = np.diff(g[:, _S])
        if g[0, _S] != 0.0 or not np.allclose(h, h[0], rtol=1e-9, atol=0.0) or h[0] <= 0.0:
            raise ValueError("geometry: the S column must start at 0 and be uniformly spaced")
        w = g[:, [_WL, _WR]]
        if (w[~np.isnan(w)] < 0.0).any():
            raise ValueError("geometry: negative track width")
        # locked: a copy of its own (not the caller's array), read-only, held through a view,
        # whose flag cannot be set back (bundled Tracks are shared: tracks.load_track)
        g = g.copy()
        g.setflags(write=False)
        object.__setattr__(self, "geometry", g.view())
        object.__setattr__(self, "closed", bool(self.closed))

    # -- construction ------------------------------------------------------------------------
    @classmethod
    def from_points(
        cls,
        x,
        y,
        *,
        w_left=None,
        w_right=None,
        closed: bool | None = None,
        ds: float = DEFAULT_DS,
        smoothing_length: float = DEFAULT_SMOOTHING_LENGTH,
        name: str = "",
        source: str = "",
        _where: Callable[[int], str] | None = None,
    ) -> Track:
        """Fit, smooth and resample a sequence of points.

        Parameters
        ----------
        x, y : array_like (n,)
            Points in driving order [m]; n >= 4, no repeated consecutive point.
        w_left, w_right : array_like (n,), optional
            Distances from each point to the left / right edge [m] (NaN = unknown, the default).
        closed : bool, optional
            Loop or open path. ``None`` (default): closed when the last point repeats the first
            (that repeat is then dropped, it only marks the closure) or when the end-to-start gap
            is under 3 median spacings (the TUMFTM files, PROVENANCE.md); open otherwise. A
            path closed by that rule across a gap of more than 1.5 median spacings gets a
            ``UserWarning`` (it may be an open road whose ends lie close): pass
            ``closed=False`` to keep it open, ``closed=True`` to confirm the loop.
        ds : float
            Arc-length step of the resampled nodes [m]; the actual step is L / round(L / ds).
        smoothing_length : float
            Cut-off wavelength of the zero-phase low-pass applied to x(u), y(u) before fitting
            [m] (gain 1/2 at that wavelength, 1/(1 + (lambda_c/lambda)^8) elsewhere); 0 = none
            (the quintic spline then interpolates the points exactly). Periodic for closed paths;
            on open paths each end is continued by its mirror image across the end's normal
            first, so the curvature runs on through the ends (within ~1-4 % of an arc's at the
            end point for radii of 5-2.5 cut-off lengths; 0.81 of it for a half-turn of R = 20
            m ending the path, 20 m cut-off) and straight lines stay exact; the end points are
            smoothed like the others: an end curve tighter than the cut-off moves its end point
            as the low-pass cuts such a curve anywhere (that half-turn's by 9 cm, one of R = 3
            m by 2.1 m, with the shrink warning below).
        name, source : str

        Returns
        -------
        Track

        Notes
        -----
        Steps: chord-length parameter u; optional low-pass on a uniform u grid; quintic
        interpolating B-spline c(u) (periodic when closed; cubic below 6 points); arc length by
        6-point Gauss-Legendre per knot interval; nodes at uniform arc length found by Newton on
        S(u) = s; heading, curvature [curv] and d kappa/ds from the spline derivatives at the
        nodes. Widths are interpolated linearly in u. A self-crossing (figure-eight) path is fine.
        """
        x = _as_1d("x", x)
        y = _as_1d("y", y, len(x))
        n = len(x)
        wl = np.full(n, np.nan) if w_left is None else _as_1d("w_left", w_left, n)
        wr = np.full(n, np.nan) if w_right is None else _as_1d("w_right", w_right, n)
        where = _where or (lambda i: f"point {i}")
        src = source or name or "points"
        for arr, nm in ((x, "x"), (y, "y")):
            bad = ~np.isfinite(arr)
            if bad.any():
                raise ValueError(f"{where(int(np.flatnonzero(bad)[0]))}: {nm} is not finite")
        for arr, nm in ((wl, "w_left"), (wr, "w_right")):
            if (arr < 0.0).any():
                i = int(np.flatnonzero(arr < 0.0)[0])
                raise ValueError(f"{where(i)}: {nm} = {float(arr[i])!r} m must be >= 0")
        if not (isinstance(ds, (int, float)) and math.isfinite(ds) and ds > 0.0):
            raise ValueError(f"ds = {ds!r} m: must be a finite number > 0")
        if not (math.isfinite(smoothing_length) and smoothing_length >= 0.0):
            raise ValueError(f"smoothing_length = {smoothing_length!r} m: must be >= 0")
        repeat = validate_polyline(x, y, where, src)
        if repeat:
            x, y, wl, wr = x[:-1], y[:-1], wl[:-1], wr[:-1]
            if closed is False:
                raise ValueError(
                    f"{src}: the last point repeats the first (a closed loop) but closed=False"
                )
            closed = True
        gap = math.hypot(x[-1] - x[0], y[-1] - y[0])
        seg = np.hypot(np.diff(x), np.diff(y))
        spacing = float(np.median(seg))
        what = f"{name} ({source})" if name and source and name != source else src
        if closed is True and not repeat and gap >= _CLOSE_GAP_SPACINGS * spacing:
            warn(f"{what}: closed=True joins its end to its start across {gap:.3g} m "
                 f"({gap / spacing:.2g} median point spacings of {spacing:.3g} m), a closing "
                 "segment that is not in the data (load_track, Track.from_points; a scenario's "
                 "reference.closed)")
        if closed is None:
            closed = gap < _CLOSE_GAP_SPACINGS * spacing
            if closed and gap > _CLOSE_WARN_SPACINGS * spacing:
                warn(f"{what}: closed into a loop because its end is {gap:.3g} m from its start "
                     f"({gap / spacing:.2g} median point spacings of {spacing:.3g} m), across a "
                     "closing segment that is not in the data; pass closed=False to keep the "
                     "path open, closed=True to confirm the loop (load_track, "
                     "Track.from_points; a scenario's reference.closed)")
        if closed and gap < MIN_SEGMENT_M:
            raise ValueError(f"{where(len(x) - 1)}: zero-length closing segment to the first "
                             f"point ({gap:.3g} m)")
        extent = max(np.ptp(x), np.ptp(y))
        if ds > extent:
            raise ValueError(f"ds = {ds!r} m: larger than the path extent ({extent:.3g} m)")
        raw = float(seg.sum()) + (gap if closed else 0.0)
        if smoothing_length > raw / 4.0:
            raise ValueError(
                f"smoothing_length = {smoothing_length!r} m: longer than a quarter of the path "
                f"({raw:.4g} m), whose shape it would smooth away (a scenario's "
                "reference.smoothing_length_m)")
        g = _build_geometry(x, y, wl, wr, bool(closed), float(ds), float(smoothing_length))
        if g[-1, _S] < (1.0 - _SMOOTH_SHRINK_WARN) * raw:
            warn(f"{what}: smoothing_length = {smoothing_length:g} m shortens the path from "
                 f"{raw:.4g} m to {g[-1, _S]:.4g} m ({100.0 * (1.0 - g[-1, _S] / raw):.2g} %): "
                 "the low-pass cuts its corners and tightens its hairpins; a shorter cut-off "
                 "keeps its shape (load_track's smoothing_length; a scenario's "
                 "reference.smoothing_length_m)")
        return cls(name=name, closed=bool(closed), geometry=g, source=src)

    # -- columns -----------------------------------------------------------------------------
    @property
    def length(self) -> float:
        """Path length L [m] (a closed track includes the closing segment)."""
        return float(self.geometry[-1, _S])

    @property
    def ds(self) -> float:
        """Arc-length step of the nodes [m]."""
        return float(self.geometry[1, _S])

    @property
    def s(self) -> np.ndarray:
        """Node arc lengths [m]."""
        return self.geometry[:, _S]

    @property
    def x(self) -> np.ndarray:
        """Node x [m]."""
        return self.geometry[:, _X]

    @property
    def y(self) -> np.ndarray:
        """Node y [m]."""
        return self.geometry[:, _Y]

    @property
    def psi(self) -> np.ndarray:
        """Node heading, unwrapped [rad]."""
        return self.geometry[:, _PSI]

    @property
    def kappa(self) -> np.ndarray:
        """Node curvature [1/m], > 0 turning left."""
        return self.geometry[:, _K]

    @property
    def dkappa_ds(self) -> np.ndarray:
        """Node d kappa / d s [1/m^2]."""
        return self.geometry[:, _DK]

    @property
    def w_left(self) -> np.ndarray:
        """Node distance to the left edge [m] (NaN when unknown)."""
        return self.geometry[:, _WL]

    @property
    def w_right(self) -> np.ndarray:
        """Node distance to the right edge [m] (NaN when unknown)."""
        return self.geometry[:, _WR]

    @property
    def turning_number(self) -> float:
        """Total heading change / 2 pi [-]: +1 a counter-clockwise loop, -1 clockwise, 0 a
        figure-eight."""
        return float((self.psi[-1] - self.psi[0]) / _TWO_PI)

    def __repr__(self) -> str:
        kind = "closed" if self.closed else "open"
        return (f"Track(name={self.name!r}, {kind}, length={self.length:.1f} m, "
                f"ds={self.ds:.3f} m, nodes={self.geometry.shape[0]})")

    # -- export ------------------------------------------------------------------------------
    def to_csv(self, path: str | Path) -> Path:
        """Write the nodes as a track file that :func:`flatfree.tracks.load_track` reads.

        The TUMFTM layout (``# x_m,y_m,w_tr_right_m,w_tr_left_m``) when both widths are known
        at every node, else plain ``x_m,y_m``; values in ``%.17g``, so the numbers read back
        are the nodes' bit for bit. A closed track's last row repeats its first point, which
        the reader takes as the explicit closure of a loop (an open track's file does not, and
        is read back open unless its ends meet). Reading the file back resamples and smooths
        the nodes again (``load_track``'s ``ds`` and ``smoothing_length``): a smoothed track
        written here (``load_track(name, smoothing_length=...)``) is a user's track file like
        any other.

        Parameters
        ----------
        path : str or Path
            File to write (overwritten).

        Returns
        -------
        Path
            ``path``.
        """
        path = Path(path)
        cols = [self.x, self.y]
        header = "x_m,y_m"
        if np.isfinite(self.w_left).all() and np.isfinite(self.w_right).all():
            cols += [self.w_right, self.w_left]
            header += ",w_tr_right_m,w_tr_left_m"
        np.savetxt(path, np.column_stack(cols), fmt="%.17g", delimiter=",", header=header)
        return path

    # -- evaluation --------------------------------------------------------------------------
    def at(self, s) -> dict[str, np.ndarray]:
        """Path quantities at arc lengths ``s`` (array_like) [m].

        Returns a dict of arrays: ``x, y, psi, kappa, dkappa_ds, w_left, w_right``.
        """
        sa = np.atleast_1d(real_array("s", s))
        out = path_eval_many(self.geometry, self.closed, sa)
        names = ("x", "y", "psi", "kappa", "dkappa_ds", "w_left", "w_right")
        return {n: out[:, j] for j, n in enumerate(names)}

    def edges(self) -> tuple[np.ndarray, np.ndarray]:
        """Left and right edge polylines at the nodes, arrays (N+1, 2) [m]."""
        nx = -self.geometry[:, _TY]
        ny = self.geometry[:, _TX]
        left = np.column_stack([self.x + self.w_left * nx, self.y + self.w_left * ny])
        right = np.column_stack([self.x - self.w_right * nx, self.y - self.w_right * ny])
        return left, right

    def projector(self) -> FrenetProjector:
        """A :class:`FrenetProjector` on this track."""
        return FrenetProjector(self)

    def project(self, x, y, psi=None, *, s0: float | None = None) -> dict[str, np.ndarray]:
        """Project a sequence of points in order (local search from point to point).

        Parameters
        ----------
        x, y : array_like (n,)
            Positions [m], in driving order.
        psi : array_like (n,), optional
            Headings [rad] (default: the path heading, i.e. e_psi is then meaningless).
        s0 : float, optional
            Arc length to start the search from (default: :func:`frenet_init` on the first point).

        Returns
        -------
        dict of arrays ``s, e_y, e_psi, kappa``.
        """
        xs = np.ascontiguousarray(real_array("x", x))
        ys = np.ascontiguousarray(real_array("y", y))
        ps = np.zeros_like(xs) if psi is None else np.ascontiguousarray(real_array("psi", psi))
        if s0 is None:
            seg = frenet_init(self.geometry, self.closed, xs[0], ys[0], ps[0]) if psi is not None \
                else int(np.argmin(np.hypot(self.x - xs[0], self.y - ys[0])))
        else:
            seg = self._segment_of(s0)
        out, _ = project_points(self.geometry, self.closed, xs, ys, ps, seg)
        return {"s": out[:, 0], "e_y": out[:, 1], "e_psi": out[:, 2], "kappa": out[:, 3]}

    def _segment_of(self, s: float) -> int:
        n_seg = self.geometry.shape[0] - 1
        if self.closed:
            s = s % self.length
        return int(min(max(math.floor(s / self.ds), 0), n_seg - 1))

    def offset(self, d, *, name: str | None = None) -> Track:
        """The line at signed lateral distance ``d`` from this path (> 0 to the left).

        Parameters
        ----------
        d : float, array_like (N+1,) or callable
            Offset [m]: a constant, values at the nodes, or a function of the arc length
            ``s`` (vectorised) of this path.

        Raises
        ------
        ValueError
            If |d| reaches the radius of curvature (the offset line would fold back).
        """
        s = self.s
        if callable(d):
            dv = real_array("d(s)", d(s)) * np.ones_like(s)
        else:
            dv = real_array("d", d) * np.ones_like(s)
        if dv.shape != s.shape or not np.isfinite(dv).all():
            raise ValueError(f"offset d: expected a finite scalar or {s.shape[0]} values")
        fold = dv * self.kappa >= 1.0
        if fold.any():
            i = int(np.flatnonzero(fold)[0])
            raise ValueError(
                f"offset d = {dv[i]:.3g} m at s = {s[i]:.1f} m reaches the radius of curvature "
                f"{1.0 / abs(self.kappa[i]):.3g} m: the offset line would fold back"
            )
        nx = -self.geometry[:, _TY]
        ny = self.geometry[:, _TX]
        px = self.x + dv * nx
        py = self.y + dv * ny
        wl = self.w_left - dv
        wr = self.w_right + dv
        m = len(s) - 1 if self.closed else len(s)
        return Track.from_points(
            px[:m], py[:m], w_left=np.maximum(wl[:m], 0.0), w_right=np.maximum(wr[:m], 0.0),
            closed=self.closed, ds=self.ds, smoothing_length=0.0,
            name=name if name is not None else f"{self.name} offset",
            source=f"offset of {self.name or self.source}",
        )


class FrenetProjector:
    """Stateful Frenet projection of a moving vehicle (a thin shell over :func:`frenet_project`).

    Examples
    --------
    >>> proj = track.projector()            # doctest: +SKIP
    >>> proj.reset(x0, y0, psi0)            # doctest: +SKIP
    >>> s, e_y, e_psi, kappa = proj.project(x, y, psi)   # doctest: +SKIP
    """

    __slots__ = ("track", "seg", "_g", "_closed")

    def __init__(self, track: Track) -> None:
        self.track = track
        self._g = track.geometry
        self._closed = track.closed
        self.seg = 0

    def reset(self, x: float | None = None, y: float | None = None, psi: float | None = None,
              *, s: float | None = None) -> None:
        """Start from arc length ``s``, or from the node nearest to (x, y) with a heading that
        agrees with ``psi`` (:func:`frenet_init`); default: the start of the path."""
        if s is not None:
            self.seg = self.track._segment_of(s)
        elif x is not None and y is not None:
            self.seg = int(frenet_init(self._g, self._closed, float(x), float(y),
                                       0.0 if psi is None else float(psi)))
        else:
            self.seg = 0

    def project(self, x: float, y: float, psi: float = 0.0) -> tuple[float, float, float, float]:
        """Return ``(s, e_y, e_psi, kappa)`` and remember the segment for the next call."""
        s, ey, ep, kap, self.seg = frenet_project(self._g, self._closed, float(x), float(y),
                                                  float(psi), self.seg)
        return s, ey, ep, kap
