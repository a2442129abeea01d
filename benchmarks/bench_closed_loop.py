"""Speed and memory of the compiled closed loop (issue 7).

Run as a script (``python benchmarks/bench_closed_loop.py [--memory]``; ``--memory``: part 3
alone); it prints the figures recorded in ``benchmarks/README.md`` "Closed loop":

1. a closed-loop 10DoF lap of the default track (``paper-noise-free`` scenario: peugeot406,
   natural-output model-free controller, plant and controller at 1 kHz, log at 100 Hz) after
   JIT warm-up, best of 3: real-time factor of the compiled loop (target >= 1000x on one
   core) and time per plant step, and the real-time factor of ``simulate()`` end to end (the
   preparation included: reference, speed profile, flying-lap start speed, the sensor noise
   (drawn a block at a time as the loop needs it), the errors of the trajectory);
2. the same with the ``paper`` sensors, with the inertial-unit
   estimator (``paper-imu``), for the other two designs, on
   the 3DoF plant (the loop's cost without the 10DoF model) and through the Python door (a
   Python controller returning constants: the cost of one Python call per control step);
3. peak memory of a 10-minute run logged at 100 Hz (target < 300 MB), of ``paper`` (with the
   sensors' noise) and ``paper-noise-free``, each measured
   in a fresh subprocess: the peak resident set size (``VmHWM`` of ``/proc/self/status``; elsewhere
   ``resource.getrusage``, whose ``ru_maxrss`` survives ``execve`` and so starts at the
   *parent's* size: after the timings above it read 214 MB "after the imports" where the
   process had 183 MB) with the baseline after the imports and after a warm-up run beside it,
   and the peak of the run's own allocations (``tracemalloc``, which sees numpy's buffers).

The machine has 2 cores shared with other jobs: timings are noisy; the best of several runs is
reported. Nothing here is a test.
"""

from __future__ import annotations

import platform
import subprocess
import sys
import time

from flatfree.scenario import Timing
from flatfree.scenarios import named_scenario
from flatfree.simulation import simulate

_MEM_SCRIPT = r"""
import resource, sys, tracemalloc
def peak_mb():
    try:  # this process's own high-water mark (reset by execve, unlike ru_maxrss)
        with open("/proc/self/status") as f:
            for line in f:
                if line.startswith("VmHWM:"):
                    return float(line.split()[1]) / 1024.0
    except OSError:
        pass
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
from flatfree.scenarios import named_scenario
from flatfree.scenario import Timing, ReferenceSpec
from flatfree.simulation import simulate
imported = peak_mb()
# warm-up in this process (loads the compiled kernels from numba's cache)
simulate(named_scenario(sys.argv[1], duration_s=0.5))
base = peak_mb()
sc = named_scenario(sys.argv[1])
# 10 minutes: ten laps of the default track, logged at 100 Hz
sc = sc.with_(reference=ReferenceSpec(track=sc.reference.track, laps=10),
              timing=Timing(duration_s=600.0, log_dt_s=0.01))
tracemalloc.start()
tr = simulate(sc)
heap = tracemalloc.get_traced_memory()[1] / 2**20
peak = peak_mb()
print(f"{imported:.1f} {base:.1f} {peak:.1f} {heap:.1f} {tr.duration:.1f} {len(tr)} "
      f"{tr.status.value}")
"""


class _Constant:
    """A Python controller holding a small drive torque and the steer straight."""

    def step(self, t, measurement, reference, applied):
        return 100.0, 0.0


def _best_rtf(name: str, repeats: int = 3) -> tuple[float, float, str]:
    """Best real-time factor of a named scenario; ``name:3dof`` on the 3DoF plant,
    ``name:python`` through the Python door (:class:`_Constant`, 8 s: it stays on the road)."""
    base, _, variant = name.partition(":")
    sc = named_scenario(base)
    controller = None
    if variant == "3dof":
        sc = sc.with_(plant="3dof")
    elif variant == "python":
        sc = sc.with_(timing=Timing(duration_s=8.0))
        controller = _Constant()
    simulate(sc.with_(timing=Timing(duration_s=1.0)), controller)  # JIT warm-up
    best = 0.0
    e2e = 0.0
    status = ""
    for _ in range(repeats):
        t0 = time.perf_counter()
        tr = simulate(sc, controller)
        wall_total = time.perf_counter() - t0
        rtf = tr.meta["real_time_factor"]
        if rtf > best:
            best, status = rtf, f"{tr.status.value} after {tr.duration:.1f} s"
        # end to end: simulate() as a user calls it, preparation included (best of the repeats)
        e2e = max(e2e, tr.duration / wall_total)
    return best, e2e, status


def main() -> None:
    print(f"machine: {platform.processor() or platform.machine()}, python "
          f"{platform.python_version()}, {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}")
    if "--memory" not in sys.argv:
        _speed()
    _memory()


def _speed() -> None:
    print("1-2. closed-loop lap of the default track, plant and controller at 1 kHz "
          "(real-time factor of the compiled loop; and of simulate() end to end: the "
          "reference, the sensor noise and the trajectory's errors included)")
    for name in ("paper-noise-free", "paper", "paper-imu", "paper-mfc-flat-noise-free",
                 "paper-flatness-noise-free", "paper-noise-free:3dof",
                 "paper-noise-free:python"):
        rtf, e2e, status = _best_rtf(name)
        print(f"  {name:28s} {rtf:8.0f}x real time = {1e3 / rtf:5.2f} us per 1 ms step; "
              f"simulate() end to end {e2e:5.0f}x ({status})")


def _memory() -> None:
    print("3. peak memory, 10-minute run logged at 100 Hz (fresh process)")
    for name in ("paper", "paper-noise-free"):
        out = subprocess.run([sys.executable, "-c", _MEM_SCRIPT, name], capture_output=True,
                             text=True, check=True).stdout.split()
        imported, base, peak, heap, dur, rows, status = out
        print(f"  {name}: peak RSS {peak} MB (after the imports: {imported} MB; after a warm-up "
              f"run too, before the run: {base} MB); peak of the run's own allocations "
              f"(tracemalloc: numpy and Python) {heap} MB (simulated {dur} s, {rows} logged "
              f"rows, {status})")


if __name__ == "__main__":
    main()
