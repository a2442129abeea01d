"""Trajectory container, its export, and the metrics computed from it (closed-form references)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from flatfree.metrics import compute_metrics, wrap_angle
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
    m = compute_metrics(_traj(meta={"real_time_factor": 1234.0}), startup_s=1.0)
    # samples t in [1, 2] s: 1001 samples covering exactly 5 periods plus one end point
    assert m.lateral_error_max_m == pytest.approx(0.02, rel=1e-6)
    assert m.lateral_error_rms_m == pytest.approx(0.02 / math.sqrt(2), rel=2e-3)
    assert m.yaw_error_max_deg == pytest.approx(0.5, rel=1e-12)
    assert m.yaw_error_rms_deg == pytest.approx(0.5, rel=1e-12)
    assert m.speed_error_rms_mps == pytest.approx(0.3 / math.sqrt(2), rel=2e-3)
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
    tr = _traj()
    sig = {k: v for k, v in tr.signals.items() if k != "torque"}
    with pytest.raises(ValueError, match="'torque'"):
        compute_metrics(Trajectory(time=tr.time, signals=sig, units=UNITS))
    with pytest.raises(ValueError, match="startup_s = -1.0 s"):
        compute_metrics(tr, startup_s=-1.0)


def test_signals_by_name_are_read_only_copies():
    tr = _traj()
    assert tr["time"] is tr.time
    with pytest.raises(ValueError):
        tr["vx"][0] = 1.0
    with pytest.raises(KeyError, match="available: lateral_error"):
        tr["nope"]
    assert "vx" in tr and "nope" not in tr
    assert tr.names == list(UNITS)


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"time": np.array([0.0, 1.0, 1.0])}, "strictly increasing"),
        ({"signals": {"a": np.zeros(2)}, "units": {"a": "m"}}, "shape"),
        ({"signals": {"a": np.zeros(3)}, "units": {}}, "no unit"),
        ({"status": Status.LEFT_TRACK}, "status_time"),
        ({"status_time": 1.0}, "None for a completed run"),
    ],
)
def test_invalid_trajectories(kwargs, match):
    base = {"time": np.array([0.0, 1.0, 2.0]), "signals": {}, "units": {}}
    with pytest.raises(ValueError, match=match):
        Trajectory(**{**base, **kwargs})


def test_parquet_round_trip_is_exact(tmp_path):
    tr = _traj(n=101, status=Status.LEFT_TRACK, status_time=0.05,
               meta={"controller": "mfc-natural", "seed": 3})
    back = Trajectory.from_parquet(tr.to_parquet(tmp_path / "run.parquet"))
    assert back.status is Status.LEFT_TRACK and back.status_time == 0.05
    assert back.meta["controller"] == "mfc-natural" and back.meta["seed"] == 3
    assert back.units == tr.units
    np.testing.assert_array_equal(back.time, tr.time)
    for k in tr:
        np.testing.assert_array_equal(back[k], tr[k])


def test_csv_export(tmp_path):
    tr = _traj(n=11)
    path = tr.to_csv(tmp_path / "run.csv")
    lines = path.read_text().splitlines()
    assert lines[0] == "# status=completed"
    assert lines[1].split(",")[:3] == ["time [s]", "lateral_error [m]", "yaw_error [rad]"]
    data = np.loadtxt(path, delimiter=",", skiprows=2)
    np.testing.assert_array_equal(data[:, 0], tr.time)
    np.testing.assert_array_equal(data[:, 4], tr["vx_ref"])


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
