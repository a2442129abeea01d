"""Figures (issue 8): each function draws the named signals, scaled to the display unit, into
the Axes it is given and returns it; a missing optional signal is skipped and said so.

Reference values are the synthetic signals themselves (a plotted line must carry exactly the
signal times the unit factor), and for the paper's Figure 3 the closed form of the linear
single-track model (cornering stiffness at static load) and the sign of the load transfer.
"""

from __future__ import annotations

import math

import matplotlib
import numpy as np
import pytest
from matplotlib.collections import LineCollection

from flatfree import plotting as pl
from flatfree.trajectory import Trajectory

matplotlib.use("Agg")

UNITS = {"x": "m", "y": "m", "lateral_error": "m", "yaw_error": "rad", "steer": "rad",
         "torque": "N m", "f_lat": "m/s^2", "f_lon": "m/s^2", "vx": "m/s"}


def _traj(seed: int, *, drop: tuple[str, ...] = (), worst_at: float = 6.0) -> Trajectory:
    """A circle of radius 40 m; the lateral error peaks (0.3 m) at ``worst_at`` s."""
    t = np.linspace(0.0, 10.0, 501)
    th = 0.3 * t
    # a small wobble (slope < 0.03 m/s) cannot move the 0.3 m peak off its sample (the peak
    # falls by 3 mm one sample away)
    e = 0.01 * np.sin(3.0 * t + seed) + 0.3 * np.exp(-((t - worst_at) / 0.2) ** 2)
    sig = {"x": 40.0 * np.sin(th), "y": 40.0 * (1 - np.cos(th)), "lateral_error": e,
           "yaw_error": 2.0 * math.pi + 0.01 * np.sin(t), "steer": 0.02 * np.sin(t),
           "torque": 200.0 * np.cos(t), "f_lat": np.sin(2 * t), "f_lon": np.cos(2 * t),
           "vx": np.full_like(t, 12.0)}
    sig = {k: v for k, v in sig.items() if k not in drop}
    return Trajectory(time=t, signals=sig, units={k: UNITS[k] for k in sig})


@pytest.fixture
def ax():
    _fig, axes = pl.new_figure(5.0, 4.0)
    return axes[0, 0]


def _lines(ax, label):
    return [ln for ln in ax.get_lines() if ln.get_label() == label]


def test_errors_are_plotted_in_display_units(ax):
    runs = {"a": _traj(1), "b": _traj(2)}
    assert pl.plot_lateral_error(ax, runs) is ax
    for k, tr in runs.items():
        (ln,) = _lines(ax, k)
        np.testing.assert_array_equal(ln.get_xdata(), tr.time)
        np.testing.assert_allclose(ln.get_ydata(), 100.0 * tr["lateral_error"], rtol=1e-15)
    assert "cm" in ax.get_ylabel()


def test_yaw_error_is_wrapped_before_conversion(ax):
    tr = _traj(1)
    pl.plot_yaw_error(ax, {"a": tr})
    (ln,) = _lines(ax, "a")
    # 2 pi + 0.01 sin t wraps to 0.01 sin t (rounding of 2 pi: ~1e-15 rad)
    np.testing.assert_allclose(ln.get_ydata(), np.degrees(0.01 * np.sin(tr.time)),
                               atol=1e-12)


def test_inputs_with_reference_and_a_missing_signal(ax):
    runs = {"a": _traj(1), "b": _traj(2, drop=("steer",))}
    t = np.linspace(0, 10, 11)
    pl.plot_steer(ax, runs, reference=(t, 0.01 * t), reference_label="recorded")
    (rec,) = _lines(ax, "recorded")
    np.testing.assert_allclose(rec.get_ydata(), np.degrees(0.01 * t))
    (ln,) = _lines(ax, "a")
    np.testing.assert_allclose(ln.get_ydata(), np.degrees(runs["a"]["steer"]))
    assert rec.get_zorder() > ln.get_zorder()  # a noisy run's band must not hide the record
    assert not _lines(ax, "b")
    assert "no steer: b" in [t.get_text() for t in ax.get_legend().get_texts()]
    with pytest.raises(ValueError, match="pair"):
        pl.plot_torque(ax, runs, reference=np.zeros(3))


def test_torque_and_f_estimates(ax):
    runs = {"a": _traj(1)}
    pl.plot_torque(ax, runs)
    np.testing.assert_array_equal(_lines(ax, "a")[0].get_ydata(), runs["a"]["torque"])
    _fig, axes = pl.new_figure(5.0, 4.0)
    assert pl.plot_f_estimate(axes[0, 0], runs, loop="lat") is axes[0, 0]
    (ln,) = _lines(axes[0, 0], "a [m/s^2]")
    np.testing.assert_array_equal(ln.get_ydata(), runs["a"]["f_lat"])
    with pytest.raises(ValueError, match="loop"):
        pl.plot_f_estimate(ax, runs, loop="yaw")


def test_f_estimates_of_different_units_get_their_own_axis(ax):
    """mfc-natural's lateral F is in m/s^2, mfc-flat's in kg m^2/s^2: two y axes."""
    a = _traj(1)
    b = Trajectory(time=a.time, signals={**a.signals, "f_lat": 1e4 * a["f_lat"]},
                   units={**a.units, "f_lat": "kg m^2/s^2"})
    c = _traj(2, drop=("f_lat",))
    pl.plot_f_estimate(ax, {"nat": a, "flat": b, "none": c}, loop="lat")
    twins = [o for o in ax.figure.axes if o is not ax and o.bbox.bounds == ax.bbox.bounds]
    assert len(twins) == 1
    (_la,) = _lines(ax, "nat [m/s^2]")  # exactly one line
    (lb,) = _lines(twins[0], "flat [kg m^2/s^2]")
    np.testing.assert_array_equal(lb.get_ydata(), b["f_lat"])
    assert "kg m^2/s^2" in twins[0].get_ylabel() and "m/s^2" in ax.get_ylabel()
    texts = [t.get_text() for t in ax.get_legend().get_texts()]
    assert texts == ["nat [m/s^2]", "flat [kg m^2/s^2]", "no f_lat: none"]


def test_paths_zoom_on_the_worst_corner(ax):
    runs = {"a": _traj(1, worst_at=6.0), "b": _traj(2, worst_at=3.0)}
    # the peaks: a 0.3 + 0.01 sin(19) = 0.3015 m at sample 300 (t = 6 s), b 0.3 + 0.01 sin(11)
    # = 0.2900 m at sample 150 (the start-up: test_worst_point_ignores_startup_and_missing_signals)
    assert pl.worst_point(runs, startup_s=1.0) == ("a", 300)
    ref = (40.0 * np.sin(np.linspace(0, 3, 50)), 40.0 * (1 - np.cos(np.linspace(0, 3, 50))))
    pl.plot_paths(ax, runs, reference=ref, zoom_half_width_m=10.0)
    assert _lines(ax, "reference") and _lines(ax, "a") and _lines(ax, "b")
    (inset,) = ax.child_axes
    label, i = pl.worst_point(runs)
    cx, cy = runs[label]["x"][i], runs[label]["y"][i]
    assert np.mean(inset.get_xlim()) == pytest.approx(cx)
    assert np.mean(inset.get_ylim()) == pytest.approx(cy)
    assert np.diff(inset.get_xlim())[0] == pytest.approx(20.0)


def test_paths_inset_and_legend_take_the_emptiest_corners(ax):
    # loops in the middle of three quadrants of a 100 m box: only the upper left is empty
    a = np.linspace(0.0, 2.0 * np.pi, 200)
    cx, cy = (25.0, 75.0, 75.0), (25.0, 25.0, 75.0)
    ref = (np.concatenate([[0.0]] + [x + 15.0 * np.cos(a) for x in cx] + [[100.0]]),
           np.concatenate([[0.0]] + [y + 15.0 * np.sin(a) for y in cy] + [[100.0]]))
    tr = _traj(1, worst_at=6.0)
    th = np.linspace(0.0, 2.0 * np.pi, len(tr))
    runs = {"a": Trajectory(time=tr.time, signals={**tr.signals, "x": 75.0 + 15.0 * np.cos(th),
                                                   "y": 25.0 + 15.0 * np.sin(th)},
                            units=tr.units)}
    pl.plot_paths(ax, runs, reference=ref, zoom_half_width_m=5.0)
    (inset,) = ax.child_axes
    box = inset.get_position()  # figure fraction; the axes' own box for comparison
    axbox = ax.get_position()
    assert box.x0 < axbox.x0 + 0.5 * axbox.width and box.y0 > axbox.y0 + 0.5 * axbox.height
    assert ax.get_legend()._loc != 2  # the legend is not under the inset (2: upper left)


def test_worst_point_ignores_startup_and_missing_signals():
    tr = _traj(1)
    e = tr["lateral_error"].copy()
    e[5] = 10.0  # t = 0.1 s, inside the start-up interval
    t2 = Trajectory(time=tr.time, signals={**tr.signals, "lateral_error": e}, units=tr.units)
    assert pl.worst_point({"a": t2}, startup_s=1.0) == ("a", 300)
    assert pl.worst_point({"a": t2}, startup_s=0.0) == ("a", 5)
    assert pl.worst_point({"a": _traj(1, drop=("lateral_error",))}) is None


def test_track_map_colours_are_the_lateral_error(ax):
    tr = _traj(3)
    pl.plot_track_map(ax, tr)
    (lc,) = [c for c in ax.collections if isinstance(c, LineCollection)]
    e = np.abs(tr["lateral_error"]) * 100.0
    np.testing.assert_allclose(lc.get_array(), 0.5 * (e[:-1] + e[1:]))
    with pytest.raises(ValueError, match="lateral_error"):
        pl.plot_track_map(ax, _traj(1, drop=("lateral_error",)))


def test_mismatch_figure(ax):
    runs = {"nominal": _traj(1), "0.3 Cf, 0.3 Cr": _traj(2)}
    pl.plot_mismatch(ax, runs, signal="lateral_error")
    np.testing.assert_allclose(_lines(ax, "nominal")[0].get_ydata(),
                               100.0 * runs["nominal"]["lateral_error"])
    with pytest.raises(ValueError, match="signal"):
        pl.plot_mismatch(ax, runs, signal="steer")


def test_bad_inputs_name_the_problem(ax):
    with pytest.raises(ValueError, match="mapping"):
        pl.plot_lateral_error(ax, [_traj(1)])
    with pytest.raises(ValueError, match="Trajectory"):
        pl.plot_lateral_error(ax, {"a": np.zeros(3)})
    with pytest.raises(ValueError, match="reference"):
        pl.plot_paths(ax, {"a": _traj(1)}, reference=(np.zeros(3), np.zeros(4)))
    with pytest.raises(ValueError, match="figure size"):
        pl.new_figure(0.0, 3.0)


def test_save_figure_writes_png_and_svg(tmp_path, ax):
    pl.plot_lateral_error(ax, {"a": _traj(1)})
    png, svg = pl.save_figure(ax.figure, tmp_path / "f", "lat")
    assert png.read_bytes().startswith(b"\x89PNG\r\n\x1a\n")
    assert "<svg" in svg.read_text(encoding="utf-8")[:2000]


def test_figure3_small_turn_matches_the_static_load_stiffness():
    """At 0.5 m/s^2 the axles' Fy/alpha is the tyres' cornering stiffness at static load.

    Tolerance 1 %: the lateral load transfer at 0.5 m/s^2 moves about 5 % of a wheel's load
    from the inner to the outer wheel, which changes the axle's stiffness only to second order
    (< 0.5 %; measured 0.34 %); the cruise drive torque's combined-slip reduction is smaller
    still.
    """
    d = pl.braking_in_turn(ay_mps2=0.5, duration_s=3.0, t_brake_s=10.0, brake_duration_s=1.0)
    late = d["t"] >= 2.0  # the yaw transient of the step steer has settled
    assert not d["brake"].any()
    assert np.nanmean(d["c_front"][late]) == pytest.approx(d["cf_nominal"], rel=0.01)
    assert np.nanmean(d["c_rear"][late]) == pytest.approx(d["cr_nominal"], rel=0.01)


def test_figure3_braking_moves_stiffness_from_the_rear_to_the_front(ax):
    """Braking transfers load to the front axle: its Fy/alpha rises relative to the rear's.

    The rear axle loses load and carries brake force (combined slip), so its effective
    stiffness drops well below its pre-braking value (> 10 %; the paper's Fig. 3 shows a
    large drop); the front's ratio stays above the rear's.
    """
    d = pl.braking_in_turn(duration_s=4.0, t_brake_s=2.0, brake_duration_s=2.0)
    t = d["t"]
    pre = (t > 1.5) & (t < 2.0)
    dur = (t > 3.0) & (t < 4.0)
    assert np.mean(d["ax"][dur]) == pytest.approx(-5.0, abs=0.5)  # the requested 5 m/s^2
    front = np.mean(d["c_front"][dur]) / np.mean(d["c_front"][pre])
    rear = np.mean(d["c_rear"][dur]) / np.mean(d["c_rear"][pre])
    assert rear < 0.9
    assert front > rear
    assert pl.plot_cornering_stiffness(ax, d) is ax
    (ln,) = _lines(ax, "front axle Fy/alpha")
    np.testing.assert_allclose(ln.get_ydata(), d["c_front"] / 1e3)
    with pytest.raises(ValueError, match="decel_mps2"):
        pl.braking_in_turn(decel_mps2=-1.0)
