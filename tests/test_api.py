"""The curated top-level API resolves, lazily."""

import importlib
import subprocess
import sys

import pytest

import flatfree


@pytest.mark.parametrize("name", [n for n in flatfree.__all__ if n != "__version__"])
def test_every_public_name_resolves(name):
    """Each top-level name is the very object its home module (as listed in ``_API``) defines:
    not a copy, a stub or a same-named object from elsewhere. (``name in dir(flatfree)`` was
    true by construction, both sides coming from ``_API``, so it is no longer checked.)"""
    obj = getattr(flatfree, name)
    assert obj is getattr(importlib.import_module(flatfree._API[name]), name)


def test_dir_lists_the_public_names_not_the_module_s_own_imports():
    """Tab completion shows the API (and subpackages once imported), not ``importlib``."""
    import flatfree.tracks  # a subpackage, imported: listed

    names = dir(flatfree)
    assert set(flatfree.__all__) <= set(names)
    assert "tracks" in names
    assert not {"importlib", "Any", "annotations", "_API", "_jitcache"} & set(names)


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


def test_the_public_doors_refuse_bad_input_with_a_valueerror_naming_it():
    """The calls of a user review, through the top-level names: each used to end in numba's
    TypeError/TypingError or an AttributeError from deep inside."""
    ip = flatfree.IP(alpha=2.0, kp=5.0, dt=0.01, window=10)
    for bad in ("a", None, [1.0, 2.0]):
        with pytest.raises(ValueError, match=r"^y = .*: expected a real number"):
            ip.step(y=bad, y_ref=1.0)
    with pytest.raises(ValueError, match=r"^ki = 3\.0 1/s\^2: must be 0 for an IP"):
        flatfree.IP(alpha=2.0, kp=5.0, dt=0.01, window=10, ki=3.0)
    act = flatfree.ActuatorParams.from_vehicle(flatfree.load_vehicle("peugeot406"))
    noc = flatfree.NaturalOutputController(dt=0.001, actuators=act)
    with pytest.raises(ValueError, match=r"^vx = '20' m/s: expected a real number"):
        noc.step(vx="20", r=0.0, e_y=0.0, kappa=0.0, vx_ref=20.0)
    ref = flatfree.make_reference("Norisring", {"a_lat_max": 3.0}, dt=0.1)
    assert ref.path.name == "Norisring"
    with pytest.raises(ValueError, match=r"^sc = 'papr': expected a Scenario"):
        flatfree.simulate("papr")


def test_the_public_modules_are_reached_from_the_package():
    """``flatfree.scenarios.SCENARIO_NAMES`` after a bare ``import flatfree`` raised
    AttributeError (suggesting 'Scenario'): the public subpackages and modules are imported on
    first use, as the API's names are; the list is every public module of the package."""
    import pathlib

    root = pathlib.Path(flatfree.__file__).parent
    public = {p.stem for p in root.glob("*.py") if not p.stem.startswith("_")} | {
        p.parent.name for p in root.glob("*/__init__.py")}
    assert flatfree._MODULES == public
    code = ("import flatfree, sys; assert 'flatfree.scenarios' not in sys.modules; "
            "print(len(flatfree.scenarios.SCENARIO_NAMES), flatfree.scenario.Fault.__name__)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True)
    assert out.stdout.split() == [str(len(flatfree.scenarios.SCENARIO_NAMES)), "Fault"]
    with pytest.raises(AttributeError, match="no attribute 'nope'"):
        flatfree.nope  # noqa: B018
