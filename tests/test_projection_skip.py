"""The true pose's projection between logged rows (flatfree.simulation._closed_loop,
"Projections"): skipped where it cannot decide anything, it changes nothing.

A run logged at every plant step projects the true pose at every step (the loop as it was
before the skip); the same run logged at 10 ms projects it about once per row. The two must
agree: the trajectory bit for bit (the controller sees the measured pose only), the logged
path coordinates to round-off, and the steps at which the run ends, whether it leaves the road
or reaches the path's end.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from flatfree.scenario import Fault, ReferenceSpec, RoadSpec, Scenario, Timing
from flatfree.scenarios import REALISTIC_SENSORS
from flatfree.simulation import _path_bounds, _safe_move, prepare, simulate
from flatfree.trajectory import Status

# the logged path coordinates of the true pose: formed by the projection, whose local search
# may start from another segment when it was skipped (the same foot point, to Newton's
# convergence); everything else is the loop's state and must be the same bit for bit
_PATH_SIGNALS = ("s", "e_y", "e_psi", "lateral_error", "yaw_error", "course_error")


def _scenario(**kw) -> Scenario:
    base = dict(plant="10dof", controller="mfc-natural",
                reference=ReferenceSpec(track="Norisring"), sensors=REALISTIC_SENSORS, seed=3,
                timing=Timing(duration_s=12.0, log_dt_s=0.01))
    base.update(kw)
    return Scenario(**base)


def _fine(sc: Scenario) -> Scenario:
    """``sc`` logged at every plant step: the true pose projected at every step."""
    t = sc.timing
    return sc.with_(timing=Timing(plant_dt_s=t.plant_dt_s, control_dt_s=t.control_dt_s,
                                  log_dt_s=t.plant_dt_s, duration_s=t.duration_s))


def _assert_rows_agree(coarse, fine, every: int = 10) -> None:
    assert int(round(coarse.time[1] / fine.time[1])) == every
    assert len(fine) >= (len(coarse) - 1) * every + 1
    for k in coarse:
        a = coarse[k]
        b = fine[k][::every][:len(a)]
        if k in _PATH_SIGNALS:
            np.testing.assert_allclose(a, b, rtol=0.0, atol=1e-9, err_msg=k)
        else:
            np.testing.assert_array_equal(a, b, err_msg=k)


@pytest.mark.parametrize("noise", [True, False], ids=["noisy", "noise-free"])
def test_a_run_logged_at_10_ms_is_the_run_logged_at_every_step(noise):
    """The noise-free run also checks the measured pose's projection, which reuses the true
    one's only when that was made this step, from the same segment."""
    sc = _scenario(noise=noise)
    coarse = simulate(sc)
    fine = simulate(_fine(sc))
    assert coarse.status is fine.status is Status.COMPLETED
    _assert_rows_agree(coarse, fine)


def test_leaving_the_road_is_found_at_the_same_step():
    """The steering locked straight through the first corners (tests/test_simulation.py): the
    run logged at 10 ms leaves at the very step of the run projected at every step."""
    lock = Fault(kind="steer_limit", t_start_s=0.0, duration_s=20.0, value=0.0)
    sc = _scenario(faults=(lock,), timing=Timing(duration_s=20.0, log_dt_s=0.01))
    coarse = simulate(sc)
    fine = simulate(_fine(sc))
    assert coarse.status is fine.status is Status.LEFT_TRACK
    assert coarse.status_time == fine.status_time
    _assert_rows_agree(coarse, fine)


def _write_road(path, x, y, w=None) -> None:
    """A track file of points, with their half-widths left and right [m] if given (else the
    loop's default half-width applies)."""
    if w is None:
        path.write_text("x,y\n" + "".join(f"{p:.6f},{q:.6f}\n" for p, q in zip(x, y,
                                                                                 strict=True)))
        return
    path.write_text("# x_m,y_m,w_tr_right_m,w_tr_left_m\n" + "".join(
        f"{p:.6f},{q:.6f},{h:.4f},{h:.4f}\n" for p, q, h in zip(x, y, w, strict=True)))


def test_a_narrow_road_is_left_at_the_same_step(tmp_path):
    """An open road 1.4-3.0 m either side of a gentle S (curvature <= 0.005 1/m: the skip
    goes on until |e_y| is 0.25 m short of the narrowest half-width, 1.4 m) with the steering
    limited to 0.01 rad from 2 s: the car leaves it at the very step of the run projected at
    every step, logged every 10 ms, every 0.1 s (the 2 m allowance binds) and with control
    every 2 ms; through the Python door too."""
    s = np.arange(0.0, 600.0, 2.0)
    _write_road(tmp_path / "narrow.csv", s, 8.0 * np.sin(s / 40.0), 2.2 + 0.8 * np.sin(s / 13.0))
    lock = Fault(kind="steer_limit", t_start_s=2.0, duration_s=50.0, value=0.01)
    base = _scenario(reference=ReferenceSpec(track=str(tmp_path / "narrow.csv"), closed=False,
                                             a_lat_max=4.0),
                     faults=(lock,), seed=0, timing=Timing(duration_s=40.0, log_dt_s=0.01))
    w_min, k_max = _path_bounds(prepare(base).reference.path.geometry, 7.5)
    assert 1.39 < w_min < 1.41 and k_max < 0.01
    for sc, every in ((base, 10), (base.with_(timing=Timing(duration_s=40.0, log_dt_s=0.1)), 100),
                      (base.with_control_period(0.002), 10)):
        coarse = simulate(sc)
        fine = simulate(_fine(sc))
        assert coarse.status is fine.status is Status.LEFT_TRACK
        assert coarse.status_time == fine.status_time
        _assert_rows_agree(coarse, fine, every)
    door = simulate(base, controller=_Counting(base))
    assert door.status is Status.LEFT_TRACK
    assert door.status_time == simulate(base).status_time


def test_two_laps_cross_the_start_line_with_the_same_arc_length():
    """Two laps of Norisring: the unwrapped arc length is s plus the laps, so the logged one is
    the every-step run's bit for bit, and the run ends at the same step (through the door)."""
    sc = _scenario(reference=ReferenceSpec(track="Norisring", laps=2),
                   timing=Timing(duration_s=400.0, log_dt_s=0.01))
    coarse = simulate(sc)
    fine = simulate(_fine(sc))
    assert coarse.status is fine.status is Status.COMPLETED
    assert coarse["s"][-1] > 1.9 * prepare(sc).reference.path.geometry[-1, 0]  # 2 laps
    _assert_rows_agree(coarse, fine)
    np.testing.assert_array_equal(coarse["s"], fine["s"][::10][:len(coarse)])
    steps = []
    for run in (sc, _fine(sc)):
        door = _Counting(run)
        simulate(run, controller=door)
        steps.append(door.calls)
    assert steps[0] == steps[1]


class _Counting:
    """The built-in natural-output kernel through the Python door, counting the control steps
    the loop ran (the step at which it ended)."""

    def __init__(self, sc: Scenario):
        self.c = prepare(sc).controller
        self.calls = 0

    def reset(self):
        self.c.reset()
        self.calls = 0

    def step(self, t, m, r, a):
        from flatfree.controllers.vehicle import vehicle_step

        self.calls += 1
        c = self.c
        return vehicle_step(c.kind, c.p_lon, c.s_lon, c.p_lat, c.s_lat, c.coef, c.f_lon, c.f_lat,
                            c.f_yaw, m, r, a[0], a[1])


def test_the_path_end_is_reached_at_the_same_step(tmp_path):
    """An open road of 400 m (a straight and a 60 m arc): the run ends where the path ends,
    at the same control step whether the true pose was projected at every step or not; the
    Python door runs the same loop as the compiled one."""
    x = np.arange(0.0, 200.0, 5.0)
    a = np.arange(5.0, 200.0, 5.0) / 60.0
    f = tmp_path / "road.csv"
    _write_road(f, np.concatenate([x, 200.0 + 60.0 * np.sin(a)]),
                np.concatenate([0.0 * x, 60.0 - 60.0 * np.cos(a)]))
    sc = _scenario(reference=ReferenceSpec(track=str(f), closed=False, a_lat_max=3.0),
                   timing=Timing(duration_s=60.0, log_dt_s=0.01))
    coarse = simulate(sc)
    fine = simulate(_fine(sc))
    assert coarse.status is fine.status is Status.COMPLETED
    assert coarse.time[-1] < 50.0  # the path's end, not the duration
    _assert_rows_agree(coarse, fine)
    steps = []
    for run in (sc, _fine(sc)):
        door = _Counting(run)
        tr = simulate(run, controller=door)
        np.testing.assert_array_equal(tr["x"], (coarse if run is sc else fine)["x"])
        steps.append(door.calls)
    assert steps[0] == steps[1] > 0.9 * coarse.time[-1] / sc.timing.control_dt_s


def test_what_needs_the_arc_length_at_every_step_keeps_the_projection_there():
    """A friction patch and a bank are looked up at the car's arc length at every step: with
    either, the 10 ms run is still the run projected at every step."""
    from flatfree.scenario import FrictionPatch

    for road in (RoadSpec(patches=(FrictionPatch(s_start_m=200.0, s_end_m=260.0, mu=0.7),)),
                 RoadSpec(bank_deg=((0.0, 0.0), (300.0, -4.0)))):
        sc = _scenario(road=road, timing=Timing(duration_s=8.0, log_dt_s=0.01))
        _assert_rows_agree(simulate(sc), simulate(_fine(sc)))


def test_the_distance_allowed_between_projections():
    """_safe_move: the road's narrowest half-width less the error and a 0.25 m margin, at most
    2 m; none within 5 m of the path's end or where kappa e_y could reach 1/2 on the way (then
    the arc length could move more than twice the distance)."""
    assert _safe_move(0.01, 100.0, math.inf, 5.0, 0.02) == 2.0
    assert _safe_move(-0.01, 100.0, math.inf, 2.0, 0.02) == pytest.approx(2.0 - 0.01 - 0.25)
    assert _safe_move(1.9, 100.0, math.inf, 2.0, 0.02) == 0.0  # within the margin
    assert _safe_move(0.01, 100.0, 104.9, 5.0, 0.02) == 0.0  # near the end
    assert _safe_move(0.01, 100.0, 105.1, 5.0, 0.02) == 2.0
    assert _safe_move(3.1, 100.0, math.inf, 9.0, 0.1) == 0.0  # 0.1 x 5.1 m > 0.5
    assert _safe_move(2.9, 100.0, math.inf, 9.0, 0.1) == 2.0  # 0.1 x 4.9 m
    assert _safe_move(math.nan, 100.0, math.inf, 5.0, 0.02) == 0.0


def test_path_bounds_take_the_narrowest_width_and_the_interpolations_curvature():
    sc = _scenario()
    g = prepare(sc).reference.path.geometry.copy()
    from flatfree.tracks.geometry import GC

    w, k = _path_bounds(g, 7.5)
    widths = g[:, [GC.W_LEFT, GC.W_RIGHT]]
    assert np.all(np.isfinite(widths)) and w == widths.min()
    h = g[1, GC.S] - g[0, GC.S]
    assert k == np.abs(g[:, GC.KAPPA]).max() + h * np.abs(g[:, GC.DKAPPA]).max()
    g[5, GC.W_LEFT] = np.nan  # unknown: the default half-width there
    assert _path_bounds(g, 0.5)[0] == 0.5
    assert _path_bounds(g, 50.0)[0] == widths.min()
