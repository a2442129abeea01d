"""Speed profile: never above any limit, continuous, maximal, and closed forms on simple paths."""

from __future__ import annotations

import math
import re

import numpy as np
import pytest

import flatfree.tracks as T
from flatfree.units import G

# Feasibility is checked with a relative slack of 1e-9: the profile is computed in floating
# point from square roots of the same expressions, so rounding is ~1e-15 relative; 1e-9 leaves
# room for that and nothing else.
SLACK = 1e-9


def check_limits(prof: T.SpeedProfile) -> None:
    """Every segment and node inside the limits (the definition in speed.py's docstring)."""
    lim = prof.limits
    ay, ad, ab = lim.ay, lim.ax_drive, lim.ax_brake
    v, a, k = prof.v, prof.a, prof.track.kappa
    assert (v >= 0).all()
    assert (v <= lim.v_max * (1 + SLACK)).all()
    assert (np.abs(v**2 * k) <= ay * (1 + SLACK)).all()
    amax = np.where(a > 0, ad, ab)
    for j in (slice(None, -1), slice(1, None)):  # both end nodes of every segment
        lat = (v[j] ** 2 * k[j] / ay) ** 2
        assert ((a / amax) ** 2 + lat <= 1 + 4 * SLACK).all()
    # the accelerations are those of the speeds: v^2 changes by 2 a ds on each segment
    np.testing.assert_allclose(np.diff(v**2), 2 * a * prof.track.ds, rtol=1e-12, atol=1e-12)


LIMITS = [
    T.SpeedLimits(),
    T.SpeedLimits(a_lat_max=9.0, a_drive_max=5.0, a_brake_max=10.0, v_max=80.0, mu=0.6),
    T.SpeedLimits(a_lat_max=3.0, a_drive_max=1.0, a_brake_max=2.0, v_max=25.0),
]


@pytest.mark.parametrize("name", ["Monza", "Norisring", "Spa"])
@pytest.mark.parametrize("lim", LIMITS, ids=["default", "mu0.6", "gentle"])
def test_profile_never_exceeds_a_limit_and_is_maximal(name, lim):
    trk = T.load_track(name)
    prof = T.speed_profile(trk, lim)
    check_limits(prof)
    assert prof.v[0] == prof.v[-1]  # periodic
    # maximal: every node touches an active constraint (within 1e-6): its lateral limit, the top
    # speed, or the friction ellipse of one of its two segments (checked at either end node,
    # since a segment's acceleration is limited by the more loaded of its two nodes)
    v, a, k = prof.v, prof.a, trk.kappa
    lat = np.abs(v**2 * k) / lim.ay
    amax = np.where(a > 0, lim.ax_drive, lim.ax_brake)
    seg = np.maximum((a / amax) ** 2 + lat[:-1] ** 2, (a / amax) ** 2 + lat[1:] ** 2)
    seg_prev = np.r_[seg[-1], seg]  # closed track: node 0 follows the last segment
    seg_next = np.r_[seg, seg[0]]
    active = (lat > 1 - 1e-6) | (v > lim.v_max * (1 - 1e-6)) | (seg_prev > 1 - 1e-6) \
        | (seg_next > 1 - 1e-6)
    assert active.all()
    # and it is not trivially so: a sizeable share of nodes is limited by the ellipse alone
    assert ((lat < 0.99) & (v < lim.v_max * 0.99)).mean() > 0.2


def test_default_limits_load_the_car_like_the_paper():
    lim = T.SpeedLimits()
    assert (lim.a_lat_max, lim.a_drive_max, lim.a_brake_max) == (6.0, 3.0, 6.0)
    prof = T.speed_profile(T.load_track("Catalunya"))
    assert np.abs(prof.a_lat).max() == pytest.approx(6.0, rel=1e-9)
    assert prof.a.max() == pytest.approx(3.0, rel=1e-6)
    assert prof.a.min() == pytest.approx(-6.0, rel=1e-6)


def test_mu_caps_every_limit():
    lim = T.SpeedLimits(mu=0.3)
    assert lim.ay == pytest.approx(0.3 * G)
    assert lim.ax_drive == pytest.approx(min(3.0, 0.3 * G))
    assert lim.ax_brake == pytest.approx(0.3 * G)
    prof = T.speed_profile(T.circle_track(50.0), lim)
    # the fitted circle's kappa is 1/R within 1e-10 (test_exact_circle_...), v ~ kappa^-1/2
    np.testing.assert_allclose(prof.v, math.sqrt(0.3 * G * 50.0), rtol=1e-9)


def test_circle_closed_form():
    """Constant curvature: v = sqrt(a_y R) everywhere, lap time 2 pi R / v."""
    prof = T.speed_profile(T.circle_track(80.0))
    v = math.sqrt(6.0 * 80.0)
    np.testing.assert_allclose(prof.v, v, rtol=1e-9)
    assert prof.duration == pytest.approx(2 * math.pi * 80.0 / v, rel=1e-9)


def test_straight_from_standstill_closed_form():
    """v(s) = sqrt(2 a_d s) until v_max, then braking v(s) = sqrt(2 a_b (L - s)) to v_end = 0."""
    lim = T.SpeedLimits(v_max=20.0)
    trk = T.straight_track(500.0)
    prof = T.speed_profile(trk, lim, v_start=0.0, v_end=0.0)
    check_limits(prof)
    s = trk.s
    expect = np.minimum.reduce([np.sqrt(2 * 3.0 * s), np.full_like(s, 20.0),
                                np.sqrt(np.maximum(2 * 6.0 * (trk.length - s), 0.0))])
    np.testing.assert_allclose(prof.v, expect, rtol=1e-12, atol=1e-12)
    # time: 20/3 s accelerating, 20/6 s braking, the rest at 20 m/s. The node profile differs
    # from the continuous one only on the two segments where 20 m/s is reached and left (one
    # constant acceleration over the whole segment): each costs < ds (20 - v_i) / (20 v_i)
    # with v_i >= sqrt(20^2 - 2 a ds), i.e. < 3.8e-4 s (drive) and < 7.6e-4 s (brake).
    cruise = trk.length - 20.0**2 / 6.0 - 20.0**2 / 12.0
    assert prof.duration == pytest.approx(20 / 3 + 20 / 6 + cruise / 20.0, abs=1.2e-3)


def test_profile_is_continuous_on_the_time_grid():
    ref = T.make_reference(T.load_track("Budapest"), dt=0.01)
    dv = np.abs(np.diff(ref["vx"]))
    assert dv.max() <= 6.0 * 0.01 * (1 + 1e-9)  # |dVx| <= max |a_x| dt
    np.testing.assert_allclose(np.diff(ref["s"]), 0.5 * 0.01 * (ref["vx"][1:] + ref["vx"][:-1]),
                               atol=0.5 * 6.0 * 0.01**2)  # trapezoid is exact up to a jump in a


def test_speed_limits_validation():
    with pytest.raises(ValueError, match=r"a_lat_max = -1.0 m/s\^2: must be > 0"):
        T.SpeedLimits(a_lat_max=-1.0)
    with pytest.raises(ValueError, match=r"v_max = nan m/s"):
        T.SpeedLimits(v_max=float("nan"))
    with pytest.raises(ValueError, match="closed track"):
        T.speed_profile(T.circle_track(10.0), v_start=1.0)
    with pytest.raises(ValueError, match="zero speed"):
        T.speed_profile(T.straight_track(10.0), v_start=0.0, v_end=0.0,
                        limits=T.SpeedLimits(v_max=1e-200))


@pytest.mark.parametrize(
    "kw, text",
    [
        (dict(v_start="3"), "v_start = '3' m/s: expected a real number"),
        (dict(v_end=True), "v_end = True m/s: expected a real number"),
        (dict(v_start=np.True_), "v_start = np.True_ m/s: expected a real number"),
        (dict(v_start=[1.0]), "v_start = [1.0] m/s: expected a real number"),
        (dict(v_end=1 + 0j), "v_end = (1+0j) m/s: expected a real number"),
        (dict(v_start=-1.0), "v_start = -1.0 m/s: must be >= 0"),
        (dict(v_end=math.inf), "v_end = inf m/s: must be finite"),
        (dict(v_start=math.nan), "v_start = nan m/s: must be finite"),
    ],
)
def test_bad_end_speeds_are_refused_by_name(kw, text):
    """v_start / v_end on the shared validator: text, booleans and lists used to pass as
    float() took them ("3" as 3.0, True as 1.0) or fail with a bare TypeError."""
    with pytest.raises(ValueError, match=f"^{re.escape(text)}$"):
        T.speed_profile(T.straight_track(50.0), **kw)


def test_end_speeds_none_is_free_and_integers_are_their_floats():
    """None (the default) leaves an end free; an int or a NumPy number is its float, bit for
    bit."""
    trk = T.straight_track(200.0)
    free = T.speed_profile(trk)
    np.testing.assert_array_equal(T.speed_profile(trk, v_start=None, v_end=None).v, free.v)
    a = T.speed_profile(trk, v_start=3, v_end=np.int64(0))
    b = T.speed_profile(trk, v_start=np.float64(3.0), v_end=0.0)
    np.testing.assert_array_equal(a.v, b.v)
    np.testing.assert_array_equal(a.t, b.t)
    assert a.v[0] == 3.0 and a.v[-1] == 0.0
