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
each source file (0.4 ms once warm, ~1-3 ms in a fresh process: benchmarks/bench_import.py);
the contents are read and hashed only when a file's size or time stamp moved, so a ``git
checkout`` there and back does not clear everything (numba's own check still compiles again
the files whose time stamps moved).

Not covered:

- a cache folder of the user's choice (``NUMBA_CACHE_DIR``), which numba then uses instead of
  the in-tree one: its owner keeps it in step (one folder per state of the sources, say);
- numba's user-wide fallback (``~/.cache/numba``), used when the package folder cannot be
  written: an installed (non-editable) package's files all change on reinstall, which numba's
  own check catches;
- compiled functions outside the package that inline flatfree's (a script's own
  ``@njit(cache=True)``): the benchmarks therefore do not cache theirs;
- a process started before an edit that compiles something new after it (it writes code of
  the old sources under the stamp of the new ones): restart long-running processes after
  editing compiled code, or clear the cache with ``make clean-cache``.
"""

from __future__ import annotations

import os

#: The stamp's file name, in the package's top ``__pycache__`` folder: the hash of the sources'
#: contents on its first line, then a line per source (path, size, time stamp).
STAMP_NAME = "flatfree-numba-sources.txt"
_CACHE_SUFFIXES = (".nbi", ".nbc")
# (os.path and a text stamp, no pathlib or json, and hashlib only when the stats moved: an
# import of flatfree stays a few milliseconds)


def _sources(root: str) -> list[str]:
    """The package's Python modules (regular files named ``<identifier>.py``: not an editor's
    lock or backup file such as ``.#simulation.py``), relative to ``root``, in a fixed order."""
    out = []
    for dirpath, dirnames, filenames in os.walk(root):
        dirnames[:] = sorted(d for d in dirnames if d != "__pycache__")
        for f in sorted(filenames):
            path = os.path.join(dirpath, f)
            if f.endswith(".py") and f[:-3].isidentifier() and os.path.isfile(path):
                out.append(os.path.relpath(path, root))
    return out


def _stats(root: str, files: list[str]) -> str:
    lines = []
    for f in files:
        st = os.stat(os.path.join(root, f))
        lines.append(f"{f}\t{st.st_size}\t{st.st_mtime_ns}")
    return "\n".join(lines)


def _content_key(root: str, files: list[str]) -> str:
    import hashlib

    h = hashlib.sha1()
    for f in files:
        with open(os.path.join(root, f), "rb") as fh:
            data = fh.read()
        h.update(f"{f}\0{len(data)}\n".encode())
        h.update(data)
    return h.hexdigest()


def _purge(root: str) -> int:
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
    ``"not-checked"`` (the folder could not be read or written, e.g. a read-only install, or a
    file vanished while it was read: nothing is raised, so ``import flatfree`` never fails
    here).
    """
    if os.environ.get("NUMBA_CACHE_DIR"):
        return "user-dir"
    root = os.fspath(root) if root is not None else os.path.dirname(os.path.abspath(__file__))
    try:
        return _guard(root)
    except OSError:
        return "not-checked"


def _guard(root: str) -> str:
    files = _sources(root)
    stamp_dir = os.path.join(root, "__pycache__")
    stamp = os.path.join(stamp_dir, STAMP_NAME)
    stats = _stats(root, files)
    try:
        with open(stamp, encoding="utf-8") as fh:
            old_content, _, old_stats = fh.read().partition("\n")
    except (OSError, ValueError):
        old_content = old_stats = ""
    if old_content and old_stats == stats:
        return "unchanged"
    content = _content_key(root, files)
    if content != old_content:
        _purge(root)
    os.makedirs(stamp_dir, exist_ok=True)
    tmp = f"{stamp}.{os.getpid()}.tmp"
    with open(tmp, "w", encoding="utf-8") as fh:
        fh.write(f"{content}\n{stats}")
    os.replace(tmp, stamp)  # atomic: a concurrent reader sees the old stamp or the new
    return "unchanged" if content == old_content else "cleared"
