"""Starting off the path with the natural-output controller in a user's loop:
MfcNaturalSettings.correction_max (benchmarks/initial_offset.py, whose loop these tests run)."""

from __future__ import annotations

import math

import pytest
from conftest import load_script

from flatfree import MfcNaturalSettings


@pytest.fixture(scope="module")
def offset_bench():
    return load_script("benchmarks/initial_offset.py")


def test_a_start_off_the_path_is_recovered_with_a_bounded_correction(offset_bench):
    """peugeot406, 10DoF, noise-free, a straight path at 20 m/s, the car 0.3 m to its left:
    the paper's law (correction_max inf) leaves the path (measured: 43.1 m max after the first
    second, over 12 s); with the correction bounded at 2 m/s^2 the car comes back (measured:
    0.151 m max after the first second, 0.000 m at 6 s).
    The bounds are the run's own outcome, far from both figures: > 2 m (off any lane) and
    < 0.3 m (within the start's offset) then < 1 cm at the end."""
    left, _, _ = offset_bench.run(MfcNaturalSettings(), 20.0, 0.3)
    assert left > 2.0
    worst, end, _ = offset_bench.run(MfcNaturalSettings(correction_max=2.0), 20.0, 0.3)
    assert worst < 0.3 and end < 0.01


def test_a_merging_reference_needs_no_bound(offset_bench):
    """The same start with the paper's law and a reference that starts at the car and merges
    into the path in 3 s (benchmarks/initial_offset.py, merge: a quintic, checked here at its
    ends and middle): tracked within 1 cm after the first second (measured 1 mm) and on the
    path at 6 s."""
    phi = [offset_bench.merge(t, 3.0) for t in (0.0, 1.5, 3.0)]
    assert phi[0] == (1.0, 0.0, 0.0) and phi[1][0] == pytest.approx(0.5, abs=1e-15)
    assert phi[2] == (0.0, 0.0, 0.0) and math.isclose(phi[1][1], -15.0 / 8.0 / 3.0)
    worst, end, _ = offset_bench.run(MfcNaturalSettings(), 20.0, 0.3, merge_s=3.0)
    assert worst < 0.01 and end < 0.01


def test_correction_max_is_a_positive_bound_in_m_per_s2():
    """MfcNaturalSettings.correction_max: > 0 or inf (the default: the paper's law), carried
    into the lateral iPD's parameters; refused otherwise, naming the field and the unit."""
    from flatfree.actuators import ActuatorParams
    from flatfree.controllers.intelligent import IPAR
    from flatfree.controllers.vehicle import build_mfc
    from flatfree.vehicles import load_vehicle

    act = ActuatorParams.from_vehicle(load_vehicle("peugeot406"))
    for value in (math.inf, 2.5):
        arrays = build_mfc("mfc-natural", MfcNaturalSettings(correction_max=value), dt=1e-3,
                           actuators=act)
        assert arrays.p_lat[IPAR.CORR_MAX] == value
        assert arrays.p_lon[IPAR.CORR_MAX] == math.inf  # the speed loop is not bounded
    for bad in (0.0, -1.0, math.nan, "2"):
        with pytest.raises(ValueError, match=r"^correction_max = .* m/s\^2: "
                                             r"(must be|expected a real number) > 0"):
            MfcNaturalSettings(correction_max=bad)
