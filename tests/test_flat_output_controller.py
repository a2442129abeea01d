"""The flat-output model-free controller in a user's own loop (FlatOutputController)."""

from __future__ import annotations

import copy
import math

import numpy as np
import pytest

from flatfree import (
    ActuatorParams,
    Bicycle3DoFParams,
    FlatOutputController,
    MfcFlatSettings,
    load_vehicle,
)
from flatfree.controllers.vehicle import CREF, MEAS, settings_from_mapping, y2_per_r
from flatfree.scenario import ReferenceSpec, Scenario, Timing
from flatfree.scenarios import REALISTIC_SENSORS
from flatfree.simulation import Status, prepare, simulate

CAR = load_vehicle("peugeot406")
ACT = ActuatorParams.from_vehicle(CAR)
MODEL = Bicycle3DoFParams.from_vehicle(CAR)


def _scenario(**kw) -> Scenario:
    base = dict(plant="10dof", controller="mfc-flat",
                reference=ReferenceSpec(track="Norisring", a_lat_max=3.0),
                timing=Timing(duration_s=1.5, log_dt_s=0.01), sensors=REALISTIC_SENSORS, seed=1)
    base.update(kw)
    return Scenario(**base)


class _FlatDoor:
    """The engine's built-in mfc-flat through FlatOutputController (the same kernel)."""

    schedule = "path"

    def __init__(self, sc, *, own_ratio: bool = False):
        self.steer0 = prepare(sc).steer0
        self.own_ratio = own_ratio
        self.calls = 0
        self.c = FlatOutputController(
            dt=sc.timing.control_dt_s, actuators=ACT, model=MODEL,
            settings=settings_from_mapping(sc.controller, sc.controller_settings))

    def reset(self):
        self.c.reset(steer0=self.steer0)

    def step(self, t, measurement, reference, applied):
        self.calls += 1
        m, r = measurement, reference
        return self.c.step(
            vx=m[MEAS.VX], vy=m[MEAS.VY], r=m[MEAS.R], vx_ref=r[CREF.VX], ax_ref=r[CREF.AX],
            y2_ref=r[CREF.Y2], y2_ref_dot=r[CREF.Y2_DOT], y2_ref_ddot=r[CREF.Y2_DDOT],
            e_y=m[MEAS.E_Y],
            e_psi=m[MEAS.E_PSI], e_y_ref=r[CREF.EY], e_y_ref_dot=r[CREF.EY_DOT],
            r_kin=r[CREF.R_KIN], y2_per_r=None if self.own_ratio else r[CREF.Y2_PER_R],
            applied_torque=applied[0], applied_steer=applied[1])


@pytest.mark.parametrize("controller, settings", [
    ("mfc-flat", {}), ("mfc-flat", {"path_correction": False, "ki_lat": 3.0}),
    ("flatness", {}), ("flatness", {"path_correction": False, "derivative": "algebraic"})],
    ids=["mfc-flat", "mfc-flat-paper-exact", "flatness", "flatness-paper-exact"])
def test_door_gives_the_compiled_controller_bit_for_bit(controller, settings):
    """Through the engine's Python door, the class gives the built-in mfc-flat's and
    flatness' trajectories bit for bit (same kernel; the engine's sensors, actuators, logging
    are shared): every measurement and reference column reaches the kernel as the compiled
    loop hands it, and the actuators' model stands for the applied input only where the
    engine does not give it (its first step). (Not the mismatched flatness law: the engine
    hands a Python controller the nominal model's y2 reference and d y2 / d r, where its
    built-in one plans with the scaled model; test_mismatch_plans_with_the_scaled_model.)"""
    sc = _scenario(controller=controller, controller_settings=settings)
    ref_run = simulate(sc)
    door = _FlatDoor(sc)
    py_run = simulate(sc, controller=door)
    assert door.calls == 1500
    assert ref_run.status is Status.COMPLETED
    for k in ref_run:
        if k in ("f_lon", "f_lat"):  # controller internals: only the built-in door logs them
            continue
        np.testing.assert_array_equal(py_run[k], ref_run[k], err_msg=k)
    st = door.c.status
    assert not st.steer_held
    if controller == "mfc-flat":
        assert st.speed.window_full and st.lateral.window_full and st.flatness is None
    else:
        assert st.flatness.code == 0 and st.speed is None and st.lateral is None


def test_the_ratio_of_the_design_model_is_y2_per_r():
    """Left out, d y2 / d r is the design model's steady ratio at vx_ref (the engine's
    column is that ratio at the reference's rows, interpolated: close, not identical)."""
    c = FlatOutputController(dt=0.001, actuators=ACT, model=MODEL)
    for v in (5.0, 20.0, 47.5):
        g = c._lfm * v
        assert c._g0 - g * g / c._crl == float(y2_per_r(MODEL, v))
    sc = _scenario()
    a = simulate(sc, controller=_FlatDoor(sc))
    b = simulate(sc, controller=_FlatDoor(sc, own_ratio=True))
    assert b.status is Status.COMPLETED
    # the two differ only by the interpolation of a quadratic over the reference's rows:
    # measured 3.6e-8 m over these 1.5 s (8.6e-7 m over 10 s)
    assert 0.0 < np.max(np.abs(a["e_y"] - b["e_y"])) < 1e-6


def test_mismatch_plans_with_the_scaled_model():
    """With cf_scale, cr_scale the flatness law's design model is scaled (its parameter
    array) and so is the path correction's d y2 / d r (the steady ratio of the scaled model,
    as the engine's paper-mismatch), while the model-free design never reads Cf, Cr."""
    import dataclasses

    from flatfree.controllers.vehicle import FlatnessSettings

    law = FlatOutputController(dt=0.001, actuators=ACT, model=MODEL,
                               settings=FlatnessSettings(cf_scale=0.3, cr_scale=0.5))
    scaled = dataclasses.replace(MODEL, cf=0.3 * MODEL.cf, cr=0.5 * MODEL.cr)
    # the parameter array starts with the design model (flatness_control.FPAR)
    np.testing.assert_array_equal(law._arrays.p_lon[:9], scaled.to_array())
    for v in (5.0, 30.0):
        g = law._lfm * v
        assert law._g0 - g * g / law._crl == float(y2_per_r(scaled, v))
    free = FlatOutputController(dt=0.001, actuators=ACT,
                                model=dataclasses.replace(MODEL, cf=1.0, cr=1.0),
                                settings=MfcFlatSettings(path_correction=False))
    ref = FlatOutputController(dt=0.001, actuators=ACT, model=MODEL,
                               settings=MfcFlatSettings(path_correction=False))
    args = dict(vx=20.0, vy=0.1, r=0.05, vx_ref=21.0, y2_ref=-100.0, y2_ref_dot=5.0)
    for _ in range(80):
        assert free.step(**args) == ref.step(**args)


def test_warm_up_holds_the_start_then_the_law_runs():
    s = MfcFlatSettings()
    c = FlatOutputController(dt=0.001, actuators=ACT, model=MODEL)
    c.reset(steer0=0.02, torque0=100.0)
    args = dict(vx=20.0, vy=0.0, r=0.0, vx_ref=21.0, y2_ref=0.0, y2_ref_dot=0.0, e_y=0.0,
                e_psi=0.0)
    for _ in range(s.window_lat - 1):
        tw, de = c.step(**args)
        assert (tw, de) == (100.0, 0.02)
        assert c.status.steer_held
    for _ in range(20):
        tw, de = c.step(**args)
    assert not c.status.steer_held and c.status.lateral.window_full
    assert tw > 100.0  # below its reference the speed loop drives


def test_path_correction_steers_back_to_the_path():
    """A car 0.5 m left of its path (e_y > 0), on a straight at the reference's states:
    the correction asks for a right turn, which the y2 loop makes with a right steer; the
    paper's design (no correction) does not see the deviation."""
    def steer_after(settings, e_y):
        c = FlatOutputController(dt=0.001, actuators=ACT, model=MODEL, settings=settings)
        for _ in range(200):
            _, de = c.step(vx=20.0, vy=0.0, r=0.0, vx_ref=20.0, y2_ref=0.0, y2_ref_dot=0.0,
                           e_y=e_y, e_psi=0.0)
        return de

    assert steer_after(MfcFlatSettings(), 0.5) < -1e-4
    assert steer_after(MfcFlatSettings(), -0.5) > 1e-4
    paper = MfcFlatSettings(path_correction=False)
    assert steer_after(paper, 0.5) == steer_after(paper, 0.0) == 0.0


def test_nonfinite_measurement_holds_and_a_lost_pose_holds_the_correction():
    c = FlatOutputController(dt=0.001, actuators=ACT, model=MODEL)
    args = dict(vx=20.0, vy=0.1, r=0.05, vx_ref=20.0, y2_ref=0.0, y2_ref_dot=0.0, e_y=0.1,
                e_psi=0.0)
    for _ in range(100):
        out = c.step(**args)
    held = c.step(**{**args, "r": math.nan})  # y2 lost: the steer held; the speed loop runs
    assert held[1] == out[1] and held[0] != out[0]
    assert c.status.steer_held and c.status.lateral.nonfinite and not c.status.speed.nonfinite
    tw, de = c.step(**{**args, "e_y": math.nan, "e_psi": math.nan})
    assert math.isfinite(tw) and math.isfinite(de) and not c.status.steer_held


@pytest.mark.parametrize("lost", ["e_y", "e_psi", "vx_ref", "r_kin", "y2_per_r"])
@pytest.mark.parametrize("design", ["mfc-flat", "flatness"])
def test_a_lost_sample_of_the_correction_holds_its_shift(design, lost):
    """One non-finite input of the path correction holds its last y2 shift: it was left out
    for that period and the y2 reference jumped back to the uncorrected one (the flatness
    law's steer 0.080 -> 0.015 -> 0.080 rad at a 0.3 m deviation, one sample of e_y lost).
    """
    from flatfree.controllers.vehicle import FlatnessSettings

    settings = FlatnessSettings() if design == "flatness" else MfcFlatSettings()

    args = dict(vx=20.0, vy=0.0, r=0.0, vx_ref=20.0, y2_ref=0.0, y2_ref_dot=0.0,
                y2_ref_ddot=0.0, e_y=-0.3, e_psi=0.0, r_kin=0.0,
                # vx_ref reaches the correction through the model's d y2 / d r
                y2_per_r=None if lost == "vx_ref" else -5000.0)
    c = FlatOutputController(dt=0.001, actuators=ACT, model=MODEL, settings=settings)
    for _ in range(300):
        before = c.step(**args)
    shift = c.status.y2_shift
    assert shift != 0.0 and not c.status.correction_held
    lost_step = c.step(**{**args, lost: math.nan})
    assert c.status.correction_held and c.status.y2_shift == shift
    assert abs(lost_step[1] - before[1]) < 2e-3, (before, lost_step)  # no spike
    after = c.step(**args)
    assert not c.status.correction_held and math.isfinite(after[1])


def test_at_a_standstill_the_steer_is_held_and_the_flatness_law_pulls_away():
    """The audit's standstill: the model-free iPI wound the wheels to their lock at 0 m/s with
    a 0.5 m deviation (0.6 rad after 60 s), the flatness law kept 0 torque at 0 m/s (a bad
    measurement) and never pulled away."""
    from flatfree.controllers.vehicle import FlatnessSettings

    c = FlatOutputController(dt=0.001, actuators=ACT, model=MODEL)
    c.reset(steer0=0.01)
    k = dict(vy=0.0, r=0.0, y2_ref=0.0, y2_ref_dot=0.0, e_psi=0.0)
    for _ in range(5000):
        tw, de = c.step(vx=0.0, vx_ref=0.0, e_y=0.5, **k)
    assert de == 0.01 and c.status.steer_held
    free = FlatOutputController(dt=0.001, actuators=ACT, model=MODEL,
                                settings=MfcFlatSettings(steer_min_speed=0.0))
    with pytest.warns(UserWarning, match="singular speed 0.578 m/s"):  # (0 m/s is within it)
        for _ in range(5000):
            _, de_free = free.step(vx=0.0, vx_ref=0.0, e_y=0.5, **k)
    assert abs(de_free) > 0.01  # without the hold it winds up: 0.0145 rad in 5 s, measured
    law = FlatOutputController(dt=0.001, actuators=ACT, model=MODEL,
                               settings=FlatnessSettings())
    for vx in (0.0, -3.0):  # reversing too (it raised AttributeError: steer_min_speed)
        tw, _ = law.step(vx=vx, vx_ref=5.0, e_y=0.0, y2_ref_ddot=0.0, **k)
        assert tw > 0.0 and law.status.flatness.handed_over and law.status.steer_held


def test_the_flatness_laws_torque_is_within_the_actuators_range():
    from flatfree.controllers.vehicle import FlatnessSettings

    law = FlatOutputController(dt=0.001, actuators=ACT, model=MODEL,
                               settings=FlatnessSettings())
    k = dict(vy=0.0, r=0.0, y2_ref=0.0, y2_ref_dot=0.0, y2_ref_ddot=0.0, e_y=0.0, e_psi=0.0)
    assert law.step(vx=20.0, vx_ref=0.0, **k)[0] == -ACT.max_brake_torque  # -47.7 kN m asked
    assert law.step(vx=20.0, vx_ref=1e300, **k)[0] == ACT.max_drive_torque
    assert law.status.flatness.tw > ACT.max_drive_torque  # the law's own, unclipped


def test_status_before_a_step_and_for_period():
    from flatfree.controllers.vehicle import FlatnessSettings

    for settings in (MfcFlatSettings(), FlatnessSettings()):
        c = FlatOutputController(dt=0.001, actuators=ACT, model=MODEL, settings=settings)
        st = c.status
        assert st.steer_held and st.y2_shift == 0.0 and not st.correction_held
        assert settings.for_period(0.001) == settings  # the tuned period: unchanged
    assert FlatnessSettings().for_period(0.01) == FlatnessSettings()  # no sample counts
    assert MfcFlatSettings().for_period(0.01).window_lat == 5


def test_bad_inputs_are_named():
    c = FlatOutputController(dt=0.001, actuators=ACT, model=MODEL)
    args = dict(vx=20.0, vy=0.0, r=0.0, vx_ref=20.0, y2_ref=0.0, y2_ref_dot=0.0)
    with pytest.raises(ValueError, match="e_y and e_psi = None: required"):
        c.step(**args)
    with pytest.raises(ValueError, match="e_psi = None"):
        c.step(**args, e_y=0.0)
    with pytest.raises(ValueError, match="vy"):
        c.step(**{**args, "vy": "0"}, e_y=0.0, e_psi=0.0)
    with pytest.raises(ValueError, match="y2_per_r"):
        c.step(**args, e_y=0.0, e_psi=0.0, y2_per_r=[1.0])
    with pytest.raises(ValueError, match="applied_steer"):
        c.step(**args, e_y=0.0, e_psi=0.0, applied_steer="x")
    # without the correction the pose is not needed, but checked when given
    paper = FlatOutputController(dt=0.001, actuators=ACT, model=MODEL,
                                 settings=MfcFlatSettings(path_correction=False))
    assert paper.step(**args) == (0.0, 0.0)
    for name, bad in (("e_y", "abc"), ("e_psi", [0.0]), ("e_y", 1 + 0j), ("e_psi", True)):
        with pytest.raises(ValueError, match=rf"^{name} = "):
            paper.step(**args, **{name: bad})
    with pytest.raises(ValueError, match="model"):
        FlatOutputController(dt=0.001, actuators=ACT, model=CAR)
    with pytest.raises(ValueError, match="actuators"):
        FlatOutputController(dt=0.001, actuators=CAR, model=MODEL)
    with pytest.raises(ValueError, match="settings"):
        FlatOutputController(dt=0.001, actuators=ACT, model=MODEL,
                             settings=settings_from_mapping("mfc-natural", {}))
    with pytest.raises(ValueError, match="steer0"):
        c.reset(steer0=5.0)
    from flatfree.controllers.vehicle import FlatnessSettings

    law = FlatOutputController(dt=0.001, actuators=ACT, model=MODEL,
                               settings=FlatnessSettings())
    with pytest.raises(ValueError, match="y2_ref_ddot = None: required with FlatnessSettings"):
        law.step(**args, e_y=0.0, e_psi=0.0)
    with pytest.raises(ValueError, match="y2_ref_ddot"):
        law.step(**args, e_y=0.0, e_psi=0.0, y2_ref_ddot="1")
    law.step(**args, e_y=0.0, e_psi=0.0, y2_ref_ddot=0.0)
    assert law.status.flatness.code == 0 and not law.status.steer_held


def test_overflow_resets_and_raises():
    """Two speeds of 1e308 m/s in the speed loop's window make its F estimate inf - inf: the
    step raises naming the inputs and resets at the last finite commands (as the natural-output
    controller's shell)."""
    c = FlatOutputController(dt=0.001, actuators=ACT, model=MODEL)
    args = dict(vx=20.0, vy=0.0, r=0.0, vx_ref=20.0, y2_ref=0.0, y2_ref_dot=0.0, e_y=0.0,
                e_psi=0.0)
    for _ in range(60):
        c.step(**args)
    last = c.step(**{**args, "vx": 1e308})
    assert last[0] == -ACT.max_brake_torque
    with pytest.raises(ValueError, match=r"FlatOutputController\.step\(vx = 1e\+308, vy = 0\.0"
                                         r".*torque = nan is not finite.*reset\(steer0="):
        c.step(**{**args, "vx": 1e308})
    fresh = FlatOutputController(dt=0.001, actuators=ACT, model=MODEL)
    fresh.reset(torque0=last[0], steer0=last[1])
    for _ in range(80):
        assert c.step(**args) == fresh.step(**args)


def test_copy_steps_on_its_own():
    c = FlatOutputController(dt=0.001, actuators=ACT, model=MODEL)
    args = dict(vx=20.0, vy=0.0, r=0.0, vx_ref=21.0, y2_ref=0.0, y2_ref_dot=0.0, e_y=0.2,
                e_psi=0.0)
    for _ in range(80):
        c.step(**args)
    d = copy.copy(c)
    before = c._arrays.s_lat.copy(), c._arrays.coef.copy()
    out = [d.step(**args) for _ in range(5)]
    np.testing.assert_array_equal(c._arrays.s_lat, before[0])  # the original did not move
    np.testing.assert_array_equal(c._arrays.coef, before[1])  # (the correction's integral)
    assert [c.step(**args) for _ in range(5)] == out  # and steps as the copy did


def test_own_loop_flat_example_runs_and_the_correction_holds_the_path():
    """examples/own_loop_flat.py, the documented reset()/step() use of both flat-output
    designs with their y2 reference from the 3DoF model along the path
    (reference_states_3dof), over 20 s of Norisring. Measured: the model-free design 0.72 m
    max with the path correction (the engine's paper-mfc-flat, whole laps, seeds 0-19:
    0.97-1.02 m; the bound is that band's top), 3.55 m without (the paper's design exactly
    drifts: the engine's leaves the track at 22-29 s); the flatness law 12.8 cm (the engine's
    paper-flatness laps 13.2-13.8 cm; bound that band's top)."""
    from conftest import load_script

    from flatfree.controllers.vehicle import FlatnessSettings

    mod = load_script("examples/own_loop_flat.py")
    corrected = mod.run(MfcFlatSettings(), 20.0)
    exact = mod.run(MfcFlatSettings(path_correction=False), 20.0)
    flatness = mod.run(FlatnessSettings(), 20.0)
    assert corrected["max_lateral_m"] < 1.02
    assert exact["max_lateral_m"] > 2.0 * corrected["max_lateral_m"]
    assert flatness["max_lateral_m"] < 0.138


def test_near_the_singular_speed_the_model_free_design_warns_once():
    """The dallara_av21's design model is singular at 10.8 m/s (yaw index < 1): the steer
    loses its effect on y2 there. The model-free design warns once, at the first measured
    speed within 50 % of it; the peugeot406's (0.58 m/s) is under the standstill hold."""
    import warnings

    from flatfree.controllers.vehicle import FlatnessSettings

    car = load_vehicle("dallara_av21")
    model = Bicycle3DoFParams.from_vehicle(car)
    act = ActuatorParams.from_vehicle(car)
    k = dict(vy=0.0, r=0.0, vx_ref=20.0, y2_ref=0.0, y2_ref_dot=0.0, y2_ref_ddot=0.0,
             e_y=0.0, e_psi=0.0)
    c = FlatOutputController(dt=0.001, actuators=act, model=model,
                             settings=MfcFlatSettings(alpha_lat=-1e5))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        c.step(vx=17.0, **k)  # 1.57 x 10.8 m/s: not yet
    with pytest.warns(UserWarning, match=r"vx = 15 m/s is within 50% of the design model's "
                                         r"singular speed 10.8 m/s") as rec:
        c.step(vx=15.0, **k)
        c.step(vx=12.0, **k)
    assert len(rec) == 1
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        law = FlatOutputController(dt=0.001, actuators=act, model=model,
                                   settings=FlatnessSettings())
        law.step(vx=12.0, **k)  # the flatness law hands over there: no warning
        p406 = FlatOutputController(dt=0.001, actuators=ACT, model=MODEL)
        for v in (5.0, 0.8, 0.5, 0.0):
            p406.step(vx=v, **k)
