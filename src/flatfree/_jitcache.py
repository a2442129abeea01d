"""numba's on-disk cache of flatfree's compiled functions, kept in step with the sources.

numba's cache (``cache=True``) checks only the file of the function it loads: when a compiled
function that another module calls changes (a kernel of ``tires.py`` inlined into the closed
loop of ``simulation.py``), the caller's cached machine code still holds the old callee, and a
run silently computes with code that no longer exists. numba lists this among its cache's known
limitations ("cache invalidation fails to recognize changes in symbols defined in a different
file", Notes on Caching, numba.readthedocs.io/en/stable/developer/caching.html; an upstream fix,
numba PR #8396, is not merged). It happens to whoever edits the sources or moves an editable
install to another commit.

:func:`guard` runs when ``flatfree`` is imported, before any compiled function is loaded: it
keeps a stamp of the package's sources beside numba's in-tree cache (the ``__pycache__``
folders next to the sources, numba's default), and when the sources differ from the stamped
ones it deletes every cached function of the package (``*.nbi`` index and ``*.nbc`` code files),
so each is compiled again from the current sources on first use. Checking costs a ``stat`` of
each source file (~1 ms); the contents are hashed only when a file's size or time stamp moved
(a ``git checkout`` there and back keeps the cache).

Not covered: a cache folder of the user's choice (``NUMBA_CACHE_DIR``), which numba then uses
instead of the in-tree one and which its owner keeps in step (``make`` keeps one folder per
state of the sources there); and a process started before an edit that compiles something new
after it (it writes code of the old sources under the stamp of the new ones: restart
long-running processes after editing compiled code, or clear the cache with ``make
clean-cache``). An installed (non-editable) package's files all change on reinstall, which
numba's own check catches.
"""

from __future__ import annotations

import hashlib
import json
import os
from pathlib import Path

#: The stamp's file name, in the package's top ``__pycache__`` folder.
STAMP_NAME = "flatfree-numba-sources.json"
_CACHE_SUFFIXES = (".nbi", ".nbc")


def _sources(root: Path) -> list[Path]:
    """The package's Python sources, in a fixed order."""
    out = []
    for dirpath, dirnames, filenames in os.walk(root):
        dirnames[:] = sorted(d for d in dirnames if d != "__pycache__")
        out.extend(Path(dirpath) / f for f in sorted(filenames) if f.endswith(".py"))
    return out


def _stat_key(root: Path, files: list[Path]) -> str:
    h = hashlib.sha1()
    for f in files:
        st = f.stat()
        h.update(f"{f.relative_to(root)}\0{st.st_size}\0{st.st_mtime_ns}\n".encode())
    return h.hexdigest()


def _content_key(root: Path, files: list[Path]) -> str:
    h = hashlib.sha1()
    for f in files:
        data = f.read_bytes()
        h.update(f"{f.relative_to(root)}\0{len(data)}\n".encode())
        h.update(data)
    return h.hexdigest()


def _purge(root: Path) -> int:
    """Delete the package's cached compiled functions; return how many files went."""
    n = 0
    for dirpath, _, filenames in os.walk(root):
        if os.path.basename(dirpath) != "__pycache__":
            continue
        for f in filenames:
            if f.endswith(_CACHE_SUFFIXES):
                try:
                    os.unlink(os.path.join(dirpath, f))
                    n += 1
                except FileNotFoundError:  # another process cleared it first
                    pass
    return n


def guard(root: str | os.PathLike | None = None) -> str:
    """Clear the package's numba cache if its sources changed since the stamp; keep the stamp.

    ``root`` is the package folder (default: flatfree's). Returns what it did: ``"user-dir"``
    (``NUMBA_CACHE_DIR`` is set: nothing done), ``"unchanged"``, ``"cleared"`` (the sources
    changed, or there was no stamp: the cache was cleared and the stamp written) or
    ``"read-only"`` (the package folder cannot be written: numba cannot cache there either).
    """
    if os.environ.get("NUMBA_CACHE_DIR"):
        return "user-dir"
    root = Path(root) if root is not None else Path(__file__).resolve().parent
    files = _sources(root)
    stamp_dir = root / "__pycache__"
    stamp = stamp_dir / STAMP_NAME
    stat_key = _stat_key(root, files)
    try:
        old = json.loads(stamp.read_text())
    except (OSError, ValueError):
        old = {}
    if old.get("stat") == stat_key:
        return "unchanged"
    content_key = _content_key(root, files)
    new = {"stat": stat_key, "content": content_key}
    try:
        if old.get("content") != content_key:
            _purge(root)
        stamp_dir.mkdir(exist_ok=True)
        tmp = stamp.with_name(f"{STAMP_NAME}.{os.getpid()}.tmp")
        tmp.write_text(json.dumps(new))
        os.replace(tmp, stamp)  # atomic: a concurrent reader sees the old stamp or the new
    except OSError:
        return "read-only"
    return "unchanged" if old.get("content") == content_key else "cleared"
