"""The curated top-level API resolves, lazily."""

import subprocess
import sys

import pytest

import flatfree


@pytest.mark.parametrize("name", [n for n in flatfree.__all__ if n != "__version__"])
def test_every_public_name_resolves(name):
    obj = getattr(flatfree, name)
    assert obj is not None
    assert name in dir(flatfree)


def test_unknown_name_raises_attribute_error():
    with pytest.raises(AttributeError, match="no attribute 'nope'"):
        flatfree.nope  # noqa: B018


def test_import_is_light():
    """`import flatfree` does not import numba, scipy or matplotlib."""
    code = ("import sys, flatfree; "
            "print(sorted(m for m in ('numba', 'scipy', 'matplotlib') if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout.strip()
    assert out == "[]"
