"""What ``import flatfree`` costs, and the numba cache check's share of it.

Run as a script (``python benchmarks/bench_import.py``); it prints the figures of
benchmarks/README.md "Import". (1) ``import flatfree`` in a fresh interpreter, timed inside it
(the interpreter's own start-up left out), best and median of 15 processes; (2) the same with
the cache check (:func:`flatfree._jitcache.guard`) skipped by ``NUMBA_CACHE_DIR`` being set,
which is what the check adds; (3) ``guard()`` alone in this process once the stamp is current,
best of 50. Nothing here is a test (tests/test_api.py checks that the import loads no numba).
"""

from __future__ import annotations

import os
import statistics
import subprocess
import sys

CODE = ("import time; t = time.perf_counter(); import flatfree; "
        "print(time.perf_counter() - t)")


def fresh(env: dict[str, str], n: int = 15) -> list[float]:
    return [float(subprocess.run([sys.executable, "-c", CODE], env=env, capture_output=True,
                                 text=True, check=True).stdout) for _ in range(n)]


def main() -> None:
    plain = {k: v for k, v in os.environ.items() if k != "NUMBA_CACHE_DIR"}
    fresh(plain, 1)  # the stamp current, the files in the page cache
    checked = fresh(plain)
    skipped = fresh({**plain, "NUMBA_CACHE_DIR": "/nonexistent-flatfree-bench"})
    for label, ts in (("import flatfree, with the check", checked),
                      ("import flatfree, check skipped (NUMBA_CACHE_DIR set)", skipped)):
        print(f"{label:55s} best {min(ts) * 1e3:5.2f} ms, median "
              f"{statistics.median(ts) * 1e3:5.2f} ms")
    from flatfree import _jitcache
    from flatfree._timing import best_time

    os.environ.pop("NUMBA_CACHE_DIR", None)  # a user's setting would skip the check timed here
    assert _jitcache.guard() == "unchanged"
    best = best_time(_jitcache.guard, repeats=50)
    print(f"{'guard() alone, stamp current':55s} best {best * 1e3:5.2f} ms")


if __name__ == "__main__":
    main()
