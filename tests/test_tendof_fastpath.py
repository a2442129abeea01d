"""The SIMD fast path of the tyres and the 10DoF model changes no physics.

``flatfree.tires.mf_combined4`` (four tyres in SIMD lanes, polynomial elementary functions) is
checked against the scalar reference kernel ``mf_combined`` (libm), and the 10DoF model with
its default ``tire_lanes=True`` against the same model with ``tire_lanes=False`` (the scalar
reference path: ``math.atan`` and ``mf_combined`` wheel by wheel, bit-identical to the model
before the lanes existed). Reference values: the scalar kernels; criteria from the brief of
the change: forces within 1e-12 mu F_z (round-off), trajectories within 1e-9 of each state's
range.
"""

from __future__ import annotations

import dataclasses
import platform
import re

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numba import njit

from flatfree import _vecmath as vm
from flatfree import load_tire, tires
from flatfree.models.tendof import (
    NDIAG,
    TenDoF,
    TenDoFOptions,
    TenDoFState,
    rhs_kernel,
)
from flatfree.tires import MF4_COLUMNS, combined, mf_combined4
from flatfree.vehicles import load_vehicle

S = TenDoFState
PRESETS = ("peugeot406", "bmw320i", "dallara_av21")
_CR = load_tire("commonroad")
_PJ = load_tire("pacejka2006_205_60R15")
#: every term that the bundled sets switch off (shifts, S_Vykappa, p_Ky4 != 2): exercises the
#: ``general`` variant of the lanes (values of the order of published MF 5.2 sets)
_GENERAL = dataclasses.replace(_PJ, name="general", rhx1=0.02, rhy1=0.01, rhy2=0.005,
                               rvy1=0.05, rvy2=0.01, pky4=1.8, phx1=0.002, phy1=0.003,
                               pvx1=0.01, pvy1=0.02, pex4=0.1, pey3=0.2)
TIRE_PAIRS = [(_CR, _CR), (_PJ, _PJ), (_CR, _PJ), (_PJ, _CR), (_GENERAL, _CR), (_PJ, _GENERAL)]

# Force tolerance: 1e-12 mu F_z (the change's criterion: round-off level). mf_combined4 runs the
# scalar formulas in the same order; only atan, sin, cos, exp differ, by <= 2 ulp, which moves
# the forces by ~1e-15 relative (measured max 7e-16 mu F_z): 1e-12 leaves a 1000x margin and
# still catches any wrong coefficient, lane or branch (those are >= 1e-6 relative).
FORCE_RTOL = 1e-12
_NTP = tires._NTP  # a module global: numba sees a compile-time constant


@njit
def _mf4_many(kappa, alpha, fz, mu, tpf, tpr, outx, outy):
    """mf_combined4 over groups of 4 lanes: element i goes to lane i % 4."""
    lanes = np.zeros((4, NDIAG))
    for g in range(kappa.size // 4):
        for i in range(4):
            k = 4 * g + i
            lanes[i, 0] = fz[k]
            lanes[i, 3] = alpha[k]
            lanes[i, 4] = kappa[k]
            lanes[i, 5] = mu[k]
        mf_combined4(lanes, tpf, tpr)
        for i in range(4):
            outx[4 * g + i] = lanes[i, 1]
            outy[4 * g + i] = lanes[i, 2]


def _compare(kappa, alpha, fz, mu, tire_f, tire_r):
    """Max |lanes - scalar| / (mu F_z) over all points (exact zeros required for F_z <= 0)."""
    n = kappa.size
    fx4, fy4 = np.empty(n), np.empty(n)
    _mf4_many(kappa, alpha, fz, mu, tire_f.to_array(), tire_r.to_array(), fx4, fy4)
    front = (np.arange(n) % 4) < 2
    fx, fy = np.empty(n), np.empty(n)
    for mask, tire in ((front, tire_f), (~front, tire_r)):
        fx[mask], fy[mask] = combined(kappa[mask], alpha[mask], fz[mask], tire, mu[mask])
    off = ~(fz > 0.0)
    assert np.all(fx4[off] == 0.0) and np.all(fy4[off] == 0.0)
    on = ~off
    if not np.any(on):
        return 0.0
    scale = mu[on] * fz[on]
    return max(np.max(np.abs(fx4[on] - fx[on]) / scale), np.max(np.abs(fy4[on] - fy[on]) / scale))


def test_lane_layout_is_the_diagnostics_layout():
    from flatfree.models.tendof import DIAG_FIELDS

    assert MF4_COLUMNS[:5] == DIAG_FIELDS[:5]


@pytest.mark.parametrize("tire_f, tire_r", TIRE_PAIRS, ids=lambda t: t.name)
def test_mf_combined4_equals_mf_combined_on_grid(tire_f, tire_r):
    """Slips through the peak to full sliding, loads from lift-off and 1 uN to 3.75 F_z0,
    friction scales from 0.1 to 1.3, for both bundled sets, mixed front/rear and the
    ``general`` variant."""
    k = np.concatenate([np.linspace(-1.0, 1.0, 21), [0.0, 1e-12, -1e-12, 3.0, -5.0]])
    a = np.concatenate([np.linspace(-0.6, 0.6, 13), [0.0, 1e-12, -1.4]])
    f = np.array([-500.0, 0.0, 1e-6, 1.0, 500.0, 4000.0, 9000.0, 15000.0])
    m = np.array([0.1, 0.5, 1.0, 1.3])
    kk, aa, ff, mm = (np.ascontiguousarray(v.ravel()) for v in np.meshgrid(k, a, f, m))
    pad = (-kk.size) % 4
    kk, aa, ff, mm = (np.concatenate([v, v[:pad]]) for v in (kk, aa, ff, mm))
    for shift in range(4):  # every point in every lane
        err = _compare(*(np.roll(v, shift) for v in (kk, aa, ff, mm)), tire_f, tire_r)
        assert err <= FORCE_RTOL, err


@settings(max_examples=300, deadline=None, derandomize=True)
@given(
    st.lists(st.tuples(st.floats(-2.0, 2.0), st.floats(-1.5, 1.5), st.floats(-1e3, 2e4),
                       st.floats(0.05, 1.5)), min_size=4, max_size=4),
    st.sampled_from(range(len(TIRE_PAIRS))),
)
def test_mf_combined4_equals_mf_combined_hypothesis(points, pair):
    kappa, alpha, fz, mu = (np.array(v, dtype=np.float64) for v in zip(*points, strict=True))
    assert _compare(kappa, alpha, fz, mu, *TIRE_PAIRS[pair]) <= FORCE_RTOL


def test_mf_combined4_rejects_a_wrong_shape():
    with pytest.raises(ValueError):
        mf_combined4(np.zeros((3, 6)), _CR.to_array(), _CR.to_array())
    with pytest.raises(ValueError):
        mf_combined4(np.zeros((4, 5)), _CR.to_array(), _CR.to_array())


@pytest.mark.skipif(platform.machine() not in ("x86_64", "AMD64"), reason="x86 assembly")
def test_tyre_lanes_vectorise():
    """The 4-lane loop compiles to packed-double code without libm calls (fast variant)."""

    @njit(error_model="numpy")
    def lanes(d, tpf, tpr):
        tires._mf_lanes_loop(d, vm.as_tuple(tpf, _NTP), vm.as_tuple(tpr, _NTP))

    d = np.zeros((4, NDIAG))
    d[:, 0] = 3000.0
    d[:, 5] = 1.0
    lanes(d, _PJ.to_array(), _CR.to_array())
    asm = lanes.inspect_asm(lanes.signatures[0])
    assert not re.search(r"call\w*\s+.*\b(atan|sin|cos|exp)\b", asm)
    packed = len(re.findall(r"\bv(?:mul|add|sub|div|fmadd\d+|fnmadd\d+)pd\s+%[yz]mm", asm))
    scalar = len(re.findall(r"\bv(?:mul|add|sub|div|fmadd\d+|fnmadd\d+)sd\b", asm))
    assert packed > 200 and scalar < packed / 10, (packed, scalar)


# --------------------------------------------------------------------------------------------
# The 10DoF model: lanes against the scalar reference path
# --------------------------------------------------------------------------------------------
def _maneuver_60s(model: TenDoF, dt: float = 1e-3):
    """The 60 s maneuver of benchmarks/bench_tendof.py (accelerate, slalom, steady turn, brake
    in the turn, coast), from 10 m/s."""
    vp = model.vehicle
    t = np.arange(int(round(60.0 / dt))) * dt
    mr = vp.mass * vp.wheel_radius
    tw = np.select([t < 10.0, t < 30.0, t < 40.0, t < 45.0],
                   [1.5 * mr, 0.3 * mr, 0.4 * mr, -3.0 * mr], default=0.0)
    delta = np.select([t < 10.0, t < 30.0, t < 45.0],
                      [0.0, 0.03 * np.sin(2.0 * np.pi * 0.5 * (t - 10.0)), 0.02],
                      default=0.01 * np.sin(2.0 * np.pi * 0.2 * t))
    return model.initial_state(10.0), model.inputs(tw, delta)


# Trajectory tolerance: 1e-9 of each state's range over the run (the change's criterion). The
# two paths differ by round-off in the tyre forces (~1e-16 relative), which the stable closed
# dynamics carry without growth: measured max 1.5e-14 over 60 s (all presets).
TRAJ_RTOL = 1e-9


def _max_range_relative(xa, xb):
    rng = np.ptp(xb, axis=0)
    rng[rng == 0.0] = 1.0
    return float(np.max(np.abs(xa - xb) / rng))


@pytest.mark.parametrize("name", PRESETS)
def test_trajectory_unchanged_on_the_benchmark_maneuver(name):
    vp = load_vehicle(name)
    fast = TenDoF(vp)
    ref = TenDoF(vp, TenDoFOptions(tire_lanes=False))
    x0, u = _maneuver_60s(fast)
    xf = fast.simulate(x0, u)
    xr = ref.simulate(x0, u)
    assert np.ptp(xr[:, S.vx]) > 5.0 and np.ptp(xr[:, S.r]) > 0.1  # the maneuver does things
    assert _max_range_relative(xf, xr) <= TRAJ_RTOL


@pytest.mark.parametrize("rear", [_CR, _GENERAL], ids=lambda t: t.name)
def test_trajectory_unchanged_launch_split_mu_mixed_tyres(rear):
    """From standstill to ~15 m/s and back to rest with hard braking, on a split-mu road
    changing in time, with different front and rear tyres and Ackermann steering: every lane
    sees its own load, slip, friction and tyre (with ``_GENERAL`` at the rear: the lanes'
    general variant)."""
    vp = dataclasses.replace(load_vehicle("peugeot406"), tire_rear=rear)
    dt = 1e-3
    t = np.arange(20_000) * dt
    mr = vp.mass * vp.wheel_radius
    tw = np.where(t < 8.0, 2.0 * mr, np.where(t < 12.0, 0.0, -4.0 * mr))
    delta = 0.05 * np.sin(2.0 * np.pi * 0.25 * t)
    mu = np.column_stack([np.where((t > 3.0) & (t < 6.0), 0.4, 1.0), np.ones_like(t),
                          np.where(t > 13.0, 0.6, 1.0), 0.9 * np.ones_like(t)])
    runs = []
    for lanes in (True, False):
        m = TenDoF(vp, TenDoFOptions(tire_lanes=lanes, ackermann=True))
        runs.append(m.simulate(m.initial_state(0.0), m.inputs(tw, delta, mu_wheels=mu), dt))
    xf, xr = runs
    assert xr[:, S.vx].max() > 10.0 and xr[-1, S.vx] < 0.5  # launched, then nearly stopped
    assert _max_range_relative(xf, xr) <= TRAJ_RTOL


def test_diagnostics_agree_at_random_states():
    """Per-wheel forces within 1e-12 mu F_z, slip angles within 2 ulp (the atan), loads and
    slips identical (the same scalar code), at random states around a 20 m/s cornering state."""
    rng = np.random.default_rng(7)
    vp = dataclasses.replace(load_vehicle("bmw320i"), tire_front=_PJ)
    fast, ref = TenDoF(vp), TenDoF(vp, TenDoFOptions(tire_lanes=False))
    n = 400
    x = np.tile(fast.initial_state(20.0, r=0.2, vy=0.3), (n, 1))
    x += rng.normal(0.0, 1.0, (n, len(S))) * np.array(
        [1, 1, 0.1, 5, 1, 0.3, 0.02, 0.1, 0.03, 0.2, 0.02, 0.2, 10, 10, 10, 10,
         0.05, 0.05, 0.05, 0.05, 2, 2])
    u = fast.inputs(rng.uniform(-2000, 1000, n), rng.uniform(-0.1, 0.1, n))
    u[:, 2:6] = rng.uniform(0.3, 1.2, (n, 4))
    df, dr = fast.diagnostics(x, u), ref.diagnostics(x, u)
    for key in ("fz", "kappa", "kappa_plain"):
        np.testing.assert_array_equal(df[key], dr[key])
    assert np.all(np.abs(df["alpha"] - dr["alpha"]) <= 2.0 * np.spacing(np.abs(dr["alpha"])))
    scale = np.where(dr["fz"] > 0.0, u[:, 2:6] * dr["fz"], 1.0)
    for key in ("fx", "fy"):
        assert np.all(np.abs(df[key] - dr[key]) <= FORCE_RTOL * scale)


def test_rhs_kernel_checks_the_diagnostics_shape():
    m = TenDoF(load_vehicle("bmw320i"))
    x, u = m.initial_state(10.0), m.inputs(0.0, 0.01)
    with pytest.raises(ValueError):
        rhs_kernel(x, u, m.params, m.tire_front, m.tire_rear, np.empty(len(S)), np.empty((4, 5)))


def test_tire_lanes_option_is_validated():
    with pytest.raises(ValueError, match="tire_lanes"):
        TenDoFOptions(tire_lanes="yes")
