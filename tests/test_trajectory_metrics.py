"""Trajectory container, its export, and the metrics computed from it (closed-form references)."""

from __future__ import annotations

import dataclasses
import json
import math
import re
import warnings

import numpy as np
import pytest

from flatfree.metrics import Metrics, compute_metrics, no_sample_after_startup, wrap_angle
from flatfree.trajectory import Status, Trajectory

UNITS = {"lateral_error": "m", "yaw_error": "rad", "vx": "m/s", "vx_ref": "m/s",
         "steer": "rad", "torque": "N m"}


def _traj(n=2001, dt=1e-3, **kw):
    t = np.arange(n) * dt
    w = 2 * np.pi * 5.0  # 5 Hz: whole periods in [1 s, 2 s]
    sig = {
        "lateral_error": 0.02 * np.sin(w * t),
        "yaw_error": np.full(n, np.radians(0.5)),
        "vx": 20.0 + 0.3 * np.cos(w * t),
        "vx_ref": np.full(n, 20.0),
        "steer": 0.1 * t,  # a ramp: steer rate exactly 0.1 rad/s
        "torque": np.full(n, -300.0),
    }
    return Trajectory(time=t, signals=sig, units=UNITS, **kw)


def test_metrics_match_closed_forms():
    """Exact sums over the samples t >= startup_s (the sample at t = 1 s included).

    t_k = k ms, and t_1000 == 1.0 exactly: the samples k = 1000..2000, 1001 of them. With
    w t_k = pi k / 100, sin^2 = (1 - cos(2 pi k / 50)) / 2 sums to 500 over k = 1000..1999
    (the cosine over 20 whole periods sums to 0), and sin^2(20 pi) = 0: the lateral error's
    mean square is 0.02^2 * 500 / 1001; likewise cos^2 sums to 500 + cos^2(20 pi) = 501, the
    speed error's mean square 0.3^2 * 501 / 1001. Excluding the sample at 1 s would give
    500 / 1000 for both, 5e-4 away: the 1e-12 check tells them apart. The peak sample
    k = 1050 has sin = 1.
    """
    tr = _traj(meta={"real_time_factor": 1234.0})
    assert tr.time[1000] == 1.0
    m = compute_metrics(tr, startup_s=1.0)
    assert m.lateral_error_max_m == pytest.approx(0.02, rel=1e-12)
    assert m.lateral_error_rms_m == pytest.approx(0.02 * math.sqrt(500 / 1001), rel=1e-12)
    assert m.yaw_error_max_deg == pytest.approx(0.5, rel=1e-12)
    assert m.yaw_error_rms_deg == pytest.approx(0.5, rel=1e-12)
    assert m.speed_error_rms_mps == pytest.approx(0.3 * math.sqrt(501 / 1001), rel=1e-12)
    assert m.steer_rate_rms_radps == pytest.approx(0.1, rel=1e-9)
    assert m.steer_rate_max_radps == pytest.approx(0.1, rel=1e-9)
    assert m.torque_rms_nm == pytest.approx(300.0)
    assert m.real_time_factor == 1234.0
    assert m.status == "completed"
    d = m.to_dict()
    assert d["lateral_error_max_m"] == m.lateral_error_max_m and d["status"] == "completed"


def test_torque_rate_is_the_rms_of_the_logged_differences():
    tr = _traj()
    w, dt = 2 * np.pi * 5.0, 1e-3
    torque = -300.0 + 50.0 * np.sin(w * tr.time)
    tr2 = Trajectory(time=tr.time, signals={**tr.signals, "torque": torque}, units=UNITS)
    m = compute_metrics(tr2, startup_s=1.0)
    # (sin(w (t + dt)) - sin(w t)) / dt = (2 / dt) sin(w dt / 2) cos(w (t + dt / 2)); the 1000
    # differences after 1 s cover exactly 5 periods, where the mean of cos^2 is 1/2
    amp = 50.0 * 2.0 * math.sin(w * dt / 2.0) / dt
    assert m.torque_rate_rms_nmps == pytest.approx(amp / math.sqrt(2.0), rel=1e-9)
    assert compute_metrics(tr, startup_s=1.0).torque_rate_rms_nmps == 0.0  # constant torque
    assert m.to_dict()["torque_rate_rms_nmps"] == m.torque_rate_rms_nmps


def test_startup_interval_is_excluded():
    tr = _traj()
    big = dict(tr.signals)
    e = big["lateral_error"].copy()
    e[tr.time < 0.5] = 5.0  # a start-up transient
    tr2 = Trajectory(time=tr.time, signals={**big, "lateral_error": e}, units=UNITS)
    assert compute_metrics(tr2, startup_s=1.0).lateral_error_max_m == pytest.approx(0.02, rel=1e-6)
    assert compute_metrics(tr2, startup_s=0.0).lateral_error_max_m == 5.0


def test_yaw_error_is_wrapped():
    assert wrap_angle(2 * np.pi + 0.1) == pytest.approx(0.1)
    assert wrap_angle(-np.pi) == pytest.approx(np.pi)
    assert wrap_angle(np.pi) == pytest.approx(np.pi)
    np.testing.assert_allclose(wrap_angle(np.array([-3 * np.pi / 2, 3 * np.pi / 2])),
                               [np.pi / 2, -np.pi / 2])
    tr = _traj()
    sig = dict(tr.signals)
    sig["yaw_error"] = np.full(len(tr), 2 * np.pi + np.radians(0.5))
    m = compute_metrics(Trajectory(time=tr.time, signals=sig, units=UNITS))
    assert m.yaw_error_max_deg == pytest.approx(0.5, rel=1e-9)


def test_missing_signal_and_bad_startup():
    """A missing signal is named; a negative startup_s is named with its value and unit."""
    tr = _traj()
    sig = {k: v for k, v in tr.signals.items() if k != "torque"}
    msg = "trajectory has no signal 'torque' needed by compute_metrics"
    with pytest.raises(ValueError, match=re.escape(msg)):
        compute_metrics(Trajectory(time=tr.time, signals=sig, units=UNITS))
    with pytest.raises(ValueError, match=r"^startup_s = -1\.0 s: must be >= 0$"):
        compute_metrics(tr, startup_s=-1.0)


def test_metrics_are_nan_when_no_sample_follows_the_startup_interval():
    """compute_metrics docstring: NaN where no sample lies after the start-up interval (a
    start-up longer than the run, or an empty trajectory), with a RuntimeWarning; status,
    duration and the real-time factor are still reported, and to_dict gives None for every NaN.
    A start-up ending exactly on the last sample keeps that sample (t >= startup_s)."""
    errors = [f.name for f in dataclasses.fields(Metrics)
              if f.name not in ("status", "duration_s", "real_time_factor")]
    with pytest.warns(RuntimeWarning, match="every metric is NaN"):
        m = compute_metrics(_traj(meta={"real_time_factor": 50.0}), startup_s=2.5)
    assert [name for name in errors if not math.isnan(getattr(m, name))] == []
    assert (m.status, m.duration_s, m.real_time_factor) == ("completed", 2.0, 50.0)
    d = m.to_dict()
    assert all(d[name] is None for name in errors)
    assert (d["status"], d["duration_s"], d["real_time_factor"]) == ("completed", 2.0, 50.0)
    empty = Trajectory(time=np.empty(0), signals={k: np.empty(0) for k in UNITS}, units=UNITS)
    with pytest.warns(RuntimeWarning, match="every metric is NaN"):
        e = compute_metrics(empty, startup_s=0.0)
    assert [name for name in errors if not math.isnan(getattr(e, name))] == []
    assert e.duration_s == 0.0
    # one sample left: the errors of it, the rates NaN, said (they were NaN silently)
    with pytest.warns(RuntimeWarning, match=r"one sample only \(t = 2 s\).*rates.*NaN"):
        last = compute_metrics(_traj(), startup_s=2.0)  # only the sample t = 2 s: cos(20 pi) = 1
    assert last.speed_error_rms_mps == pytest.approx(0.3, rel=1e-12)
    assert last.torque_rms_nm == 300.0
    assert math.isnan(last.steer_rate_rms_radps) and math.isnan(last.torque_rate_rms_nmps)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # two samples: the rates are numbers, no warning
        two = compute_metrics(_traj(), startup_s=1.999)
    assert two.steer_rate_rms_radps == pytest.approx(0.1, rel=1e-9)
    with pytest.raises(ValueError, match=r"^traj = \{'a': 1\}: expected a flatfree.Trajectory"):
        compute_metrics({"a": 1})


def _startup_warning(tr, startup_s):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        m = compute_metrics(tr, startup_s=startup_s)
    assert [w.category for w in caught] == [RuntimeWarning]
    assert caught[0].filename == __file__  # stacklevel: the caller's line
    return m, str(caught[0].message)


def test_a_log_within_the_startup_interval_warns_with_its_numbers():
    """The user's case, ff.compute_metrics(ff.simulate(named_scenario("paper",
    duration_s=2.0)), startup_s=5), built directly: a log ending at 1.99 s (10 ms log) and a
    start-up of 5 s gave every metric NaN, status 'completed', and no word of why. The warning
    names the log's last time, startup_s, where the interval starts when the log does not
    start at 0, how a run that did not complete stopped, and what to change."""
    tr = _traj(n=200, dt=0.01)
    assert tr.time[-1] == pytest.approx(1.99)
    m, msg = _startup_warning(tr, 5)
    assert math.isnan(m.lateral_error_max_m) and m.status == "completed"
    assert msg == ("compute_metrics: every metric is NaN but status, duration and real-time "
                   "factor: the log ends at t = 1.99 s, within the start-up interval of "
                   "startup_s = 5 s that the metrics leave out; simulate longer or pass a "
                   "shorter startup_s")
    late = Trajectory(time=tr.time + 3.0, signals=tr.signals, units=UNITS,
                      status=Status.LEFT_TRACK, status_time=4.995)
    m, msg = _startup_warning(late, 2.5)
    assert m.status == "left_track" and math.isnan(m.yaw_error_rms_deg)
    assert msg == ("compute_metrics: every metric is NaN but status, duration and real-time "
                   "factor: the log ends at t = 4.99 s, within the start-up interval of "
                   "startup_s = 2.5 s from the first sample at t = 3 s that the metrics leave "
                   "out (the run stopped at t = 4.995 s: left_track); simulate longer or pass "
                   "a shorter startup_s")
    empty = Trajectory(time=np.empty(0), signals={k: np.empty(0) for k in UNITS}, units=UNITS)
    _, msg = _startup_warning(empty, 1.0)
    assert msg == ("compute_metrics: every metric is NaN but status, duration and real-time "
                   "factor: the trajectory has no sample (startup_s = 1 s); simulate longer or "
                   "pass a shorter startup_s")


@pytest.mark.parametrize("startup_s", [0.0, 1.0, 1.999])
def test_no_startup_warning_when_a_sample_is_left(startup_s):
    """Warnings as errors: a run with two samples or more after the start-up interval (the
    last one included, t >= startup_s) computes without a warning; no_sample_after_startup
    agrees (one sample left warns about the rates: the test above)."""
    tr = _traj()
    assert not no_sample_after_startup(tr, startup_s)
    assert no_sample_after_startup(tr, 2.0 + 1e-9)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        m = compute_metrics(tr, startup_s=startup_s)
    assert math.isfinite(m.lateral_error_max_m) and math.isfinite(m.torque_rms_nm)


def test_to_dict_turns_every_non_finite_number_into_none():
    """Metrics.to_dict is JSON-ready: NaN and +-inf become None, finite values and the status
    pass unchanged, and the dict serialises with allow_nan=False."""
    m = compute_metrics(_traj(), startup_s=1.0)  # no real_time_factor in meta: NaN
    m = dataclasses.replace(m, torque_rms_nm=math.inf, steer_rate_max_radps=-math.inf)
    d = m.to_dict()
    assert list(d) == [f.name for f in dataclasses.fields(Metrics)]
    assert d["real_time_factor"] is None and d["course_error_max_deg"] is None
    assert d["torque_rms_nm"] is None and d["steer_rate_max_radps"] is None
    assert d["lateral_error_rms_m"] == m.lateral_error_rms_m and d["status"] == "completed"
    json.dumps(d, allow_nan=False)


def test_signals_by_name_are_read_only_copies():
    """Signals and time are copied at construction (changing the caller's arrays afterwards
    leaves the trajectory as it was, and the caller's arrays stay writable) and read-only."""
    t = np.array([0.0, 1.0, 2.0])
    a = np.array([1.0, 2.0, 3.0])
    own = Trajectory(time=t, signals={"a": a}, units={"a": "m"})
    a[0] = 7.0
    t[0] = -1.0
    assert own["a"][0] == 1.0 and own.time[0] == 0.0
    assert a.flags.writeable and t.flags.writeable
    tr = _traj()
    assert tr["time"] is tr.time
    with pytest.raises(ValueError, match="read-only"):
        tr["vx"][0] = 1.0
    with pytest.raises(ValueError, match="read-only"):
        tr.time[0] = 1.0
    msg = "no signal 'nope'; available: lateral_error, steer, torque, vx, vx_ref, yaw_error"
    with pytest.raises(KeyError, match=re.escape(msg)):
        tr["nope"]
    assert "vx" in tr and "nope" not in tr
    assert tr.names == list(UNITS)


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"time": np.array([0.0, 1.0, 1.0])},
         r"^time must be strictly increasing: time\[2\] = 1\.0 s after time\[1\] = 1\.0 s$"),
        ({"time": np.zeros((3, 1))}, r"^time has shape \(3, 1\): expected a 1-D array$"),
        ({"signals": {"a": np.zeros(2)}, "units": {"a": "m"}},
         r"^signal 'a' has shape \(2,\), expected \(3,\) like time$"),
        ({"signals": {"a": np.zeros(3)}, "units": {}}, r"^signal 'a' has no unit in units$"),
        ({"status": "completed"}, r"^status = 'completed': expected a Status$"),
        ({"status": Status.LEFT_TRACK},
         r"^status left_track needs the status_time at which it happened$"),
        ({"status_time": 1.0}, r"^status_time = 1\.0 s: must be None for a completed run$"),
    ],
)
def test_invalid_trajectories(kwargs, match):
    """Each invalid construction raises a ValueError with its full message."""
    base = {"time": np.array([0.0, 1.0, 2.0]), "signals": {}, "units": {}}
    with pytest.raises(ValueError, match=match):
        Trajectory(**{**base, **kwargs})


def test_course_error_metric_when_the_signal_is_there():
    tr = _traj()
    assert math.isnan(compute_metrics(tr).course_error_max_deg)
    n = len(tr)
    course = np.full(n, np.radians(0.2))
    course[tr.time < 0.5] = np.radians(5.0)  # inside the start-up interval: excluded
    course[-1] = np.radians(-0.3) + 2 * np.pi  # wrapped before the max
    tr2 = Trajectory(time=tr.time, signals={**tr.signals, "course_error": course},
                     units={**UNITS, "course_error": "rad"})
    assert compute_metrics(tr2, startup_s=1.0).course_error_max_deg == pytest.approx(0.3)
    assert compute_metrics(tr2, startup_s=0.0).course_error_max_deg == pytest.approx(5.0)


@pytest.mark.parametrize(("angle", "msg"), [
    ("1.0", "angle = '1.0': expected real numbers, got dtype <U3"),
    ([True, False], "angle = [True, False]: expected real numbers, got dtype bool"),
    ([0.0, None], "angle = [0.0, None]: expected real numbers, got dtype object"),
])
def test_wrap_angle_refuses_what_is_not_real_numbers_by_name(angle, msg):
    # float64 reads "1.0" and True as numbers and a None as a silent NaN: refused, by name
    with pytest.raises(ValueError, match=f"^{re.escape(msg)}$"):
        wrap_angle(angle)


def test_a_trajectory_refuses_non_finite_times_and_a_status_time_not_a_number():
    """status_time = "x" was accepted (repr then failed), NaN printed "at t=nan s"; an
    infinite time was accepted and a NaN one called "not increasing"."""
    from flatfree.trajectory import Status

    for bad in ("x", math.nan, math.inf, None):
        with pytest.raises(ValueError, match="status_time"):
            Trajectory(time=[0.0], signals={}, units={}, status=Status.LEFT_TRACK,
                       status_time=bad)
    ok = Trajectory(time=[0.0], signals={}, units={}, status=Status.LEFT_TRACK, status_time=1)
    assert ok.status_time == 1.0 and "at t=1.000 s" in repr(ok)
    for t, i in (([0.0, math.inf], 1), ([math.nan, 1.0], 0)):
        with pytest.raises(ValueError, match=rf"^time\[{i}\] = .*: must be finite"):
            Trajectory(time=t, signals={}, units={})
