"""The shared validators of flatfree._validate: what counts as a real number or array."""

from __future__ import annotations

import math
import re

import numpy as np
import pytest

from flatfree._validate import as_real, boolean, real_array


def test_real_array_returns_float64_arrays_as_they_are_and_converts_numbers():
    a = np.arange(3.0)
    assert real_array("x", a) is a  # no copy on the common path
    big = np.arange(3.0).astype(">f8")  # float64 in the other byte order: converted, equal
    np.testing.assert_array_equal(real_array("x", big), big)
    for value in ([1, 2, 3], np.arange(3, dtype=np.int32), np.arange(3, dtype=np.uint8), 2.5,
                  np.float32(0.5)):
        out = real_array("x", value)
        assert out.dtype == np.float64
        np.testing.assert_array_equal(out, np.asarray(value, dtype=np.float64))


@pytest.mark.parametrize(("value", "message"), [
    ("1.0", "x = '1.0': expected real numbers, got dtype <U3"),
    ([True, False], "x = [True, False]: expected real numbers, got dtype bool"),
    ([1.0, None], "x = [1.0, None]: expected real numbers, got dtype object"),
    ([1.0, 2j], "x = [1.0, 2j]: expected real numbers, got dtype complex128"),
    (np.zeros(5, dtype=bool), "x (shape (5,)): expected real numbers, got dtype bool"),
    ([[1.0], [1.0, 2.0]], ("x: expected an array of real numbers of one shape, got "
                          "[[1.0], [1.0, 2.0]]")),
])
def test_real_array_refuses_what_is_not_real_numbers_naming_the_field(value, message):
    with pytest.raises(ValueError, match=f"^{re.escape(message)}$"):
        real_array("x", value)


def test_as_real_takes_numbers_only():
    assert as_real(3) == 3.0 and as_real(np.float32(0.5)) == 0.5 and as_real(np.array(2.0)) == 2.0
    for value in ("1", b"1", True, np.bool_(False), np.zeros(1), None, [1.0]):
        assert as_real(value) is None


def test_real_array_names_the_unit_when_given():
    with pytest.raises(ValueError, match=r"^fz = \['1'\] N: expected real numbers, got dtype <U1$"):
        real_array("fz", ["1"], "N")
    with pytest.raises(ValueError, match=r"^fz \[N\]: expected an array of real numbers of one "):
        real_array("fz", [[1.0], [1.0, 2.0]], "N")
    assert as_real(1 + 2j) is None and as_real(np.complex128(1.0)) is None  # not real numbers
    assert as_real(7) == 7.0 and type(as_real(7)) is float


def test_one_of_takes_the_allowed_integers_only():
    from flatfree._validate import one_of

    assert one_of("nu", 2, (1, 2)) == 2 and type(one_of("nu", 2.0, (1, 2))) is int
    assert one_of("nu", np.int64(1), (1, 2)) == 1
    for bad in (True, np.True_, 3, 1.5, "1", math.nan, None, [1]):
        with pytest.raises(ValueError, match=r"^nu = .+: must be 1 or 2 \(hint\)$"):
            one_of("nu", bad, (1, 2), " (hint)")
    with pytest.raises(ValueError, match=r"^mode = 4: must be 1, 2 or 3$"):
        one_of("mode", 4, (1, 2, 3))


def test_whole_keeps_large_integers_exact_and_refuses_what_float_cannot_hold():
    from flatfree._validate import whole

    big = 2**60 + 1  # float(big) == 2**60: a float path would round it
    assert whole("seed", big, 0) == big and whole("n", np.int64(7), 2) == 7
    assert whole("n", 100.0, 2) == 100 and type(whole("n", 100.0, 2)) is int
    for bad in (True, np.True_, 1, -(2**70), 2.5, "3", math.inf, math.nan):
        with pytest.raises(ValueError, match=r"must be an integer >= 2$"):
            whole("n", bad, 2)
    assert as_real(10**400) is None  # beyond float's range: not refused by an OverflowError


def test_whole_strict_takes_integers_only():
    """strict (the estimators' counts and orders): an integral float is refused too, the
    message naming the type (an integral 100.0 >= 2 was told "must be an integer >= 2");
    integers, NumPy's and beyond float's range too, pass as ints."""
    from flatfree._validate import whole

    assert whole("n", 2**60 + 1, 0, strict=True) == 2**60 + 1
    assert type(whole("n", np.int64(7), 2, strict=True)) is int
    with pytest.raises(ValueError, match=r"^n = 1 samples: must be an integer >= 2$"):
        whole("n", 1, 2, "samples", strict=True)
    for bad, kind in ((100.0, "float"), (np.float64(3.0), "float64"), (True, "bool"),
                      (np.True_, "bool"), (2.5, "float"), ("3", "str"), (math.nan, "float"),
                      (None, "NoneType")):
        with pytest.raises(ValueError, match=rf"^n = .+: must be an integer >= 2, given as an "
                                             rf"int \(not {kind}\)$"):
            whole("n", bad, 2, "samples", strict=True)


def test_boolean_takes_bools_only_and_names_the_field():
    assert boolean("noise", True) is True and boolean("noise", False) is False
    for bad in (1, 0, "true", None, np.True_, 1.0):
        with pytest.raises(ValueError, match=rf"^tire_lanes = {re.escape(repr(bad))}: "
                                             "must be true or false$"):
            boolean("tire_lanes", bad)
