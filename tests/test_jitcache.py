"""The numba cache guard (flatfree._jitcache): a changed callee in another file is not served
stale from numba's on-disk cache."""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from flatfree import _jitcache

_CALLEE = textwrap.dedent("""\
    from numba import njit

    @njit(cache=True)
    def g():
        return {value}
""")
_CALLER = textwrap.dedent("""\
    from numba import njit
    from {pkg}.callee import g

    @njit(cache=True)
    def f():
        return g()
""")


def _package(tmp: Path, name: str, guarded: bool) -> Path:
    """A package whose cached ``caller.f`` inlines ``callee.g`` from another file."""
    root = tmp / name
    root.mkdir()
    init = ("from flatfree._jitcache import guard\nSTATE = guard(__path__[0])\n"
            if guarded else "")
    (root / "__init__.py").write_text(init)
    (root / "callee.py").write_text(_CALLEE.format(value=1))
    (root / "caller.py").write_text(_CALLER.format(pkg=name))
    return root


def _run(tmp: Path, name: str) -> str:
    env = {k: v for k, v in os.environ.items() if k != "NUMBA_CACHE_DIR"}
    env["PYTHONPATH"] = os.pathsep.join([str(tmp), env.get("PYTHONPATH", "")])
    code = f"import {name}.caller as c; print(c.f())"
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          env=env, cwd=tmp, check=True).stdout.strip()


def _edit_callee(root: Path) -> None:
    path = root / "callee.py"
    st = path.stat()
    path.write_text(_CALLEE.format(value=2))  # the same size: only the contents differ
    os.utime(path, ns=(st.st_atime_ns, st.st_mtime_ns + 10**9))


def test_a_changed_callee_in_another_file_is_compiled_again(tmp_path):
    """Without the guard numba serves the caller's cached code with the old callee inlined
    (the trap, shown first so that the test can fail); with it, the new callee runs."""
    plain = _package(tmp_path, "plainpkg", guarded=False)
    assert _run(tmp_path, "plainpkg") == "1"
    _edit_callee(plain)
    if _run(tmp_path, "plainpkg") != "1":
        pytest.skip("this numba notices a changed callee by itself: nothing to guard against")

    guarded = _package(tmp_path, "guardedpkg", guarded=True)
    assert _run(tmp_path, "guardedpkg") == "1"
    assert list((guarded / "__pycache__").glob("*.nbi"))  # the caller was cached
    _edit_callee(guarded)
    assert _run(tmp_path, "guardedpkg") == "2"


def _fake_cache(root: Path) -> Path:
    d = root / "__pycache__"
    d.mkdir(exist_ok=True)
    f = d / "mod.f-3.py311.nbi"
    f.write_bytes(b"index")
    return f


def test_the_stamp_keeps_the_cache_while_the_sources_are_the_same(tmp_path, monkeypatch):
    monkeypatch.delenv("NUMBA_CACHE_DIR", raising=False)
    (tmp_path / "mod.py").write_text("x = 1\n")
    cached = _fake_cache(tmp_path)
    assert _jitcache.guard(tmp_path) == "cleared"  # no stamp yet: an unknown state
    assert not cached.exists()
    assert (tmp_path / "__pycache__" / _jitcache.STAMP_NAME).exists()
    cached = _fake_cache(tmp_path)
    assert _jitcache.guard(tmp_path) == "unchanged"
    # a new time stamp, the same contents (a checkout there and back): kept
    os.utime(tmp_path / "mod.py", ns=(0, 10**18))
    assert _jitcache.guard(tmp_path) == "unchanged"
    assert cached.exists()
    # a new file is a change of the sources
    (tmp_path / "sub").mkdir()
    (tmp_path / "sub" / "other.py").write_text("y = 2\n")
    assert _jitcache.guard(tmp_path) == "cleared"
    assert not cached.exists()


def test_a_cache_folder_of_the_user_s_choice_is_left_alone(tmp_path, monkeypatch):
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path / "mine"))
    (tmp_path / "mod.py").write_text("x = 1\n")
    cached = _fake_cache(tmp_path)
    assert _jitcache.guard(tmp_path) == "user-dir"
    assert cached.exists()
    assert not (tmp_path / "__pycache__" / _jitcache.STAMP_NAME).exists()


def test_a_folder_that_cannot_be_written_is_reported_not_raised(tmp_path, monkeypatch):
    monkeypatch.delenv("NUMBA_CACHE_DIR", raising=False)
    (tmp_path / "mod.py").write_text("x = 1\n")

    def refuse(*args, **kwargs):
        raise PermissionError("read-only file system")

    monkeypatch.setattr(_jitcache.os, "replace", refuse)
    assert _jitcache.guard(tmp_path) == "not-checked"


def test_an_editor_s_lock_file_does_not_break_the_check(tmp_path, monkeypatch):
    """A dangling symlink named like a module (Emacs's ``.#mod.py`` lock) is not a source;
    a file that cannot be read gives "not-checked", never an exception (it runs on import)."""
    monkeypatch.delenv("NUMBA_CACHE_DIR", raising=False)
    (tmp_path / "mod.py").write_text("x = 1\n")
    (tmp_path / ".#mod.py").symlink_to(tmp_path / "user@host.123:1")
    assert _jitcache.guard(tmp_path) == "cleared"
    assert _jitcache.guard(tmp_path) == "unchanged"

    def vanish(*args, **kwargs):
        raise FileNotFoundError("gone while read")

    monkeypatch.setattr(_jitcache.os, "stat", vanish)
    assert _jitcache.guard(tmp_path) == "not-checked"


def test_importing_flatfree_runs_the_check(tmp_path):
    """``import flatfree`` (of a copy of the package, without its stamp) writes the stamp of
    the copy's sources: the check runs on import, without importing numba."""
    import shutil

    import flatfree

    root = Path(flatfree.__file__).resolve().parent
    shutil.copytree(root, tmp_path / "flatfree", ignore=shutil.ignore_patterns("__pycache__"))
    env = {k: v for k, v in os.environ.items() if k != "NUMBA_CACHE_DIR"}
    env["PYTHONPATH"] = str(tmp_path)
    code = "import sys, flatfree; print(flatfree.__file__, 'numba' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         env=env, cwd=tmp_path, check=True).stdout.split()
    assert out == [str(tmp_path / "flatfree" / "__init__.py"), "False"]
    assert (tmp_path / "flatfree" / "__pycache__" / _jitcache.STAMP_NAME).exists()
    assert _jitcache.guard(tmp_path / "flatfree") in ("unchanged", "user-dir")
