"""The curvature of an open path at its ends after the smoothing low-pass.

Run as a script (``python benchmarks/open_path_ends.py``); it prints the figures of
benchmarks/README.md "Open-path ends". An arc of a circle sampled every metre, built with
:meth:`flatfree.tracks.Track.from_points` (``closed=False``, the default ``ds``), three ways:

- ``mirror``: the code as it is (each end continued by its mirror image across the end's
  normal, the tangent from a parabola over one cut-off length; tracks.geometry._lowpass);
- ``cubic``: the same with the tangent from a cubic over the same points (the comparison that
  chose the parabola);
- ``none``: no continuation (``_END_PAD = 0``: the odd reflection alone, the code before
  session 17, which forces the curvature to 0 at the ends).

Printed: kappa R at the ends and at 5, 10, 20, 40 m from the start, the largest |kappa R - 1|
more than two cut-off lengths inside, how far the first point moved; then, with white noise
on the points (20 draws), the RMS relative curvature error at the two ends and inside; then a
half-turn ending a straight (the end point's move, kappa R at the end). Last, the recorded
scenarios (an open path) with the code as it is: the yaw error's max and where it lies, the
samples above 0.5 deg, its median and 99th percentile after the start-up, the max lateral
error. Nothing here is a test (tests/test_tracks_geometry.py holds the ``mirror`` figures,
tests/paper_scenario_bounds.json the recorded runs').
"""

from __future__ import annotations

import contextlib
import warnings

import numpy as np

from flatfree.metrics import compute_metrics, wrap_angle
from flatfree.scenarios import named_scenario
from flatfree.simulation import simulate
from flatfree.tracks import geometry
from flatfree.tracks.geometry import GC, Track


def _cubic_tangent(y: np.ndarray) -> np.ndarray:
    c = np.polynomial.polynomial.polyfit(np.arange(y.shape[0], dtype=float), y, 3)
    return c[1] / np.linalg.norm(c[1])


@contextlib.contextmanager
def variant(name: str):
    """The module's helpers swapped for the comparison's (restored after)."""
    saved = geometry._end_tangent, geometry._END_PAD
    if name == "cubic":
        geometry._end_tangent = _cubic_tangent
    elif name == "none":
        geometry._END_PAD = 0.0
    try:
        yield
    finally:
        geometry._end_tangent, geometry._END_PAD = saved


def arc(radius: float, length: float, noise: float = 0.0, seed: int = 0):
    th = np.arange(0.0, length + 1e-9, 1.0) / radius
    x, y = radius * np.sin(th), radius * (1.0 - np.cos(th))
    rng = np.random.default_rng(seed)
    return x + noise * rng.standard_normal(x.size), y + noise * rng.standard_normal(x.size)


def clean(radius: float, length: float, cutoff: float) -> str:
    x, y = arc(radius, length)
    trk = Track.from_points(x, y, closed=False, smoothing_length=cutoff)
    g = trk.geometry
    s, k = g[:, GC.S], g[:, GC.KAPPA] * radius
    at = [int(np.argmin(np.abs(s - d))) for d in (0.0, 5.0, 10.0, 20.0, 40.0)]
    inside = np.abs(k[(s > 2 * cutoff) & (s < s[-1] - 2 * cutoff)] - 1.0).max()
    moved = np.hypot(g[0, GC.X] - x[0], g[0, GC.Y] - y[0])
    return (f"kappa R at 0/5/10/20/40 m {' '.join(f'{v:.3f}' for v in k[at])}, end "
            f"{k[-1]:.3f}; inside max |kR - 1| {inside:.1e}; first point moved "
            f"{moved * 1e3:.2f} mm")


def noisy(radius: float, length: float, cutoff: float, noise: float, draws: int) -> str:
    ends, inside = [], []
    for seed in range(draws):
        trk = Track.from_points(*arc(radius, length, noise, seed), closed=False,
                                smoothing_length=cutoff)
        err = trk.kappa * radius - 1.0
        ends += [err[0], err[-1]]
        inside.append(err[(trk.s > 2 * cutoff) & (trk.s < trk.length - 2 * cutoff)])
    e = np.asarray(ends)
    i = np.concatenate(inside)
    return (f"ends RMS {np.sqrt(np.mean(e ** 2)) * 100:.1f} % (max {np.abs(e).max() * 100:.1f}),"
            f" inside RMS {np.sqrt(np.mean(i ** 2)) * 100:.1f} %")


def half_turn(radius: float) -> str:
    """A 100 m straight, then a half-turn of ``radius`` ending the path (points every 0.5 m)."""
    xs = np.arange(-100.0, 0.0, 0.5)
    th = np.arange(0.0, np.pi * radius + 1e-9, 0.5) / radius
    x = np.concatenate([xs, radius * np.sin(th)])
    y = np.concatenate([np.zeros_like(xs), radius * (1.0 - np.cos(th))])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the shrink warning of a tight turn
        g = Track.from_points(x, y, closed=False).geometry
    return (f"end point moved {np.hypot(g[-1, GC.X] - x[-1], g[-1, GC.Y] - y[-1]):.3f} m, "
            f"kappa R at the end {g[-1, GC.KAPPA] * radius:.3f}")


def recorded(name: str) -> str:
    sc = named_scenario(name)
    tr = simulate(sc)
    m = compute_metrics(tr, startup_s=sc.timing.startup_s)
    t = tr.time
    after = t >= t[0] + sc.timing.startup_s
    t, e = t[after], np.degrees(np.abs(wrap_angle(tr["yaw_error"][after])))
    over = t[e > 0.5]
    where = f" at {over.min():.1f}-{over.max():.1f} s" if over.size else ""
    return (f"yaw max {m.yaw_error_max_deg:.3f} deg at t = {t[np.argmax(e)]:.2f} s (run ends "
            f"{t[-1]:.2f} s), {over.size} samples above 0.5 deg{where}, median "
            f"{np.median(e):.2f}, 99th percentile {np.percentile(e, 99):.2f}; max lateral "
            f"{m.lateral_error_max_m * 100:.3f} cm")


def main() -> None:
    for name in ("mirror", "cubic", "none"):
        print(f"[{name}]")
        with variant(name):
            for radius, length, cutoff in ((100.0, 300.0, 20.0), (50.0, 200.0, 20.0),
                                           (300.0, 1000.0, 60.0)):
                print(f"  R = {radius:g} m, {cutoff:g} m cut-off: {clean(radius, length, cutoff)}")
            print(f"  R = 100 m, 20 m cut-off, 2 cm noise, 20 draws: "
                  f"{noisy(100.0, 300.0, 20.0, 0.02, 20)}")
            for radius in (20.0, 3.0):
                print(f"  half-turn R = {radius:g} m ending a straight: {half_turn(radius)}")
    for name in ("recorded", "recorded-imu", "recorded-noise-free", "recorded-imu-noise-free"):
        print(f"{name} (seed 0): {recorded(name)}")


if __name__ == "__main__":
    main()
