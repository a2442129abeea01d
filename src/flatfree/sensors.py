"""Sensors of the sampled-data loop: per-channel noise, bias, sample rate and delay, seeded.

A :class:`SensorChannel` describes one measured signal; a :class:`SensorSuite` maps channel
names to channels. The simulation evaluates them at the controller's rate through the compiled
:func:`sense_step`, over arrays built by :meth:`SensorSuite.compile`:

- **delay**: rounded to the nearest whole number of controller periods (``delay_steps``; an
  exact half to the even number, as Python's ``round``); the channel
  returns the true value of ``delay_steps`` periods earlier (the first value before enough
  history exists).
- **sample rate**: a channel slower than the controller holds its last sample between updates
  (``period_steps`` controller periods apart, rounded as the delay, at least 1: 400 Hz at a 1 kHz
  controller samples every 2 steps); a rate of ``None`` means every controller step. A sample
  that is not finite is not held (:func:`sense_step`).
- **noise**: additive Gaussian, standard deviation ``noise_std``, drawn ahead of the loop, for
  the whole run or block after block (:meth:`SensorSuite.compile`, ``block``; the same
  sequences bit for bit): the same seed gives bit-identical runs, different seeds different
  noise. Noise is drawn once per sample (held between samples).
- **streams** (:func:`channel_streams`): each channel draws from streams of its own, keyed by
  the seed and the channel's name (children of ``numpy.random.SeedSequence(seed)``), one for
  its white noise and one for its drift, each drawn in time order. So for a given seed a
  channel's error sequence does not depend on the run's length (a 10 s run's is the first
  10 s of a 20 s run's), on the other channels' settings, or on its own other component's:
  doubling a ``noise_std`` doubles the same white sequence (common random numbers for
  sensitivity studies).
- **drift** (optional): a first-order Gauss-Markov error of stationary standard deviation
  ``markov_std`` and correlation time ``markov_tau_s``, ``b[k+1] = phi b[k] + markov_std
  sqrt(1 - phi^2) w[k]``, ``phi = exp(-dt / markov_tau_s)``, started from its stationary
  distribution: the slow error of, e.g., a GNSS/INS position (a datasheet's "1 cm" accuracy is
  mostly such a slow error, the sample-to-sample jitter being much smaller).
  ``markov_order = 2``: a second-order Gauss-Markov error instead, two such first-order stages
  in cascade (the same ``phi``) scaled to the stationary standard deviation ``markov_std``,
  also started stationary. Its autocorrelation at a lag of ``m`` samples is exactly
  ``phi^m (1 + m tanh(dt / markov_tau_s))``, which tends to ``exp(-t / tau) (1 + t / tau)`` as
  dt -> 0 (the second-order Gauss-Markov model of GNSS error analysis); its sample-to-sample
  increments have the variance ``2 markov_std^2 (1 - phi (1 + tanh(dt / tau)))``, of order
  dt^2 where the first-order drift's is of order dt: a smooth error, like the position an
  inertial unit blends from a receiver's, where the first-order one is a random walk at short
  time scales. (Derivation: with ``s[k] = phi s[k-1] + w[k]`` and ``y[k] = phi y[k-1] + s[k]``,
  ``y[k] = sum_j (j + 1) phi^j w[k-j]``; var y = (1 + phi^2) / (1 - phi^2)^3,
  cov(y, s) = 1 / (1 - phi^2)^2, var s = 1 / (1 - phi^2), the lag-m covariance
  phi^m (var y + m cov(y, s)).)
- **bias**: a constant offset added to every sample.

Units of ``noise_std`` and ``bias`` are those of the channel's signal (SI).
"""

from __future__ import annotations

import math
import zlib
from collections.abc import Collection, Mapping
from dataclasses import dataclass, field
from types import MappingProxyType

import numpy as np
from numba import njit

from flatfree._validate import finite, nonnegative, one_of, positive, whole_steps
from flatfree._vecmath import no_refcount
from flatfree._warn import warn

__all__ = ["SENSOR_CHANNELS", "SensorChannel", "SensorSuite", "CompiledSensors", "sense_step",
           "channel_streams"]

#: The measured signals of the closed loop, in the order the sensors see them
#: (:mod:`flatfree.simulation`): the names a scenario's sensor tables and measurement faults
#: may use.
SENSOR_CHANNELS = ("x", "y", "psi", "vx", "vy", "r", "ax", "ay")

# columns of the compiled parameter table
_NOISE, _BIAS, _PERIOD, _DELAY = 0, 1, 2, 3
# the streams of a channel (channel_streams): the last entry of their spawn key
_WHITE, _DRIFT = 0, 1


@dataclass(frozen=True, slots=True, kw_only=True)
class SensorChannel:
    """One measured signal.

    Parameters
    ----------
    noise_std
        Standard deviation of the additive Gaussian noise, in the signal's unit (>= 0).
    bias
        Constant offset, in the signal's unit.
    rate_hz
        Sample rate [Hz]; ``None`` samples at every controller step.
    delay_s
        Transport delay [s] (>= 0), rounded to whole controller periods.
    markov_std, markov_tau_s
        Stationary standard deviation (signal's unit) and correlation time [s] of a
        Gauss-Markov drift (module docstring); 0 / None: no drift.
    markov_order
        1 (default): a first-order Gauss-Markov drift; 2: a second-order one (smooth at short
        time scales; module docstring).
    """

    noise_std: float = 0.0
    bias: float = 0.0
    rate_hz: float | None = None
    delay_s: float = 0.0
    markov_std: float = 0.0
    markov_tau_s: float | None = None
    markov_order: int = 1

    def __post_init__(self) -> None:
        nonnegative("noise_std", self.noise_std)
        finite("bias", self.bias)
        if self.rate_hz is not None:
            positive("rate_hz", self.rate_hz, "Hz")
        nonnegative("delay_s", self.delay_s, "s")
        nonnegative("markov_std", self.markov_std)
        if self.markov_tau_s is not None:
            positive("markov_tau_s", self.markov_tau_s, "s")
        elif self.markov_std > 0.0:
            raise ValueError(
                f"markov_std = {self.markov_std!r}: a drift needs its correlation time "
                "markov_tau_s [s]"
            )
        object.__setattr__(self, "markov_order", one_of("markov_order", self.markov_order, (1, 2)))


@dataclass(frozen=True, slots=True)
class CompiledSensors:
    """Arrays for :func:`sense_step`: parameters, drawn noise and the state to mutate.

    ``noise[:, j]`` is the error of control step ``first_step + j``. Compiled whole
    (:meth:`SensorSuite.compile` without ``block``) it holds the run's every step and
    ``first_step`` stays 0; compiled in blocks it holds one block, and :meth:`next_block`
    draws the next one in its place, continuing each channel's streams: the same sequences as
    drawn whole, bit for bit (tests/test_sensors_actuators.py).
    """

    names: tuple[str, ...]
    table: np.ndarray  # (n_channels, 4): 1 (noise scale), bias, period_steps, delay_steps
    noise: np.ndarray  # (n_channels, n_columns) error sequences in the signals' units
    history: np.ndarray  # (n_channels, max_delay + 1) ring buffer of true values
    held: np.ndarray  # (n_channels,) last measured value
    _draw: _NoiseDraw | None = field(default=None, repr=False, compare=False)

    @property
    def first_step(self) -> int:
        """The control step of ``noise[:, 0]``."""
        return 0 if self._draw is None else self._draw.first_step

    def next_block(self) -> int:
        """Draw the next block of the error sequences into ``noise``; return its first
        control step. Only for sensors compiled in blocks (``block`` given)."""
        if self._draw is None:
            raise ValueError("next_block: these sensors were compiled whole (block = None)")
        return self._draw.next(self.noise)

    def reset(self) -> None:
        """Clear the state (history and held values) for a new run, which then measures with
        the same noise: compiled whole, the noise stays; in blocks, the streams start again
        and the first block is drawn again."""
        self.history[:] = np.nan
        self.held[:] = np.nan
        if self._draw is not None and self._draw.first_step != 0:
            self._draw.restart(self.noise)


@njit(**no_refcount({"cache": True}))
def _drift1(w, start, c0, c, phi, z, out):
    """Add a first-order Gauss-Markov sequence to ``out`` (module docstring, "drift"):
    ``y[j] = a_j w[j] + z_j``, ``z_(j+1) = phi y[j]``, the scale ``a_j`` ``c0`` at the
    sequence's first sample (``start``) and ``c`` after it; returns the last ``z``.
    ``scipy.signal.lfilter([1], [1, -phi], a w)`` bit for bit, block after block."""
    for j in range(w.shape[0]):
        y = w[j] * (c0 if start and j == 0 else c) + z
        z = phi * y
        out[j] = out[j] + y
    return z


@njit(**no_refcount({"cache": True}))
def _drift2(w, scale, phi, zs, zy, out):
    """Add a second-order Gauss-Markov sequence to ``out``: two first-order stages in cascade
    (:func:`_drift1` with ``c0 = c = scale``, then its output through the same stage) from
    their states ``zs``, ``zy``; returns the last states."""
    for j in range(w.shape[0]):
        s = w[j] * scale + zs
        zs = phi * s
        y = s + zy
        zy = phi * y
        out[j] = out[j] + y
    return zs, zy


class _NoiseDraw:
    """The channels' error sequences, drawn block after block in time order
    (:class:`CompiledSensors`): each channel's streams (:func:`channel_streams`) and the
    drifts' filter states, carried from a block to the next."""

    def __init__(self, chans: list[SensorChannel], names: tuple[str, ...], seed: int,
                 dt_control: float, unread: frozenset[str] = frozenset()) -> None:
        self._chans = [(i, ch, names[i], math.exp(-dt_control / ch.markov_tau_s)
                        if ch.markov_std > 0.0 else 0.0)
                       for i, ch in enumerate(chans)
                       # nothing drawn: the other channels' streams are their own anyway
                       if (ch.noise_std > 0.0 or ch.markov_std > 0.0)
                       and names[i] not in unread]
        self._seed = seed
        self._start()

    def _start(self) -> None:
        """Each channel's streams at their start, no drift state yet (None), step 0."""
        self.first_step = 0
        self._drawn = 0  # control steps drawn so far
        self._rows = [[i, ch, *channel_streams(self._seed, name), phi, None]
                      for i, ch, name, phi in self._chans]

    def restart(self, noise: np.ndarray) -> None:
        """The streams from their start again, and the first block drawn into ``noise``."""
        self._start()
        self.next(noise)

    def next(self, noise: np.ndarray) -> int:
        """Draw the next ``noise.shape[1]`` steps into ``noise``; return their first step."""
        m = noise.shape[1]
        self.first_step = self._drawn
        for row in self._rows:
            i, ch, white, drift, phi, state = row
            out = noise[i]
            if ch.noise_std > 0.0:
                white.standard_normal(out=out)
                out *= ch.noise_std
            else:
                out[:] = 0.0
            if ch.markov_std > 0.0:
                row[5] = self._drift(ch, drift, phi, state, m, out)
        self._drawn += m
        return self.first_step

    @staticmethod
    def _drift(ch: SensorChannel, rng: np.random.Generator, phi: float, state, m: int,
               out: np.ndarray):
        """Add the drift's next ``m`` samples to ``out``; return its state after them."""
        std = ch.markov_std
        if ch.markov_order == 1:
            # b[0] from the stationary distribution, then the recursion's driving noise
            z = _drift1(rng.standard_normal(m), state is None, std,
                        std * math.sqrt(1.0 - phi * phi), phi,
                        0.0 if state is None else state, out)
            return z
        q = 1.0 - phi * phi
        var_s, cov_ys, var_y = 1.0 / q, 1.0 / (q * q), (1.0 + phi * phi) / (q * q * q)
        scale = std / math.sqrt(var_y)
        if state is None:
            # first the state (s, y) at k = -1, s from its marginal and y from its law given
            # s, then the driving noise
            z0, z1 = rng.standard_normal(2)
            s_m = z0 * math.sqrt(var_s)
            y_m = (cov_ys / var_s) * s_m + z1 * math.sqrt(var_y - cov_ys * cov_ys / var_s)
            state = (phi * s_m * scale, phi * y_m * scale)
        return _drift2(rng.standard_normal(m), scale, phi, state[0], state[1], out)


@dataclass(frozen=True, slots=True)
class SensorSuite:
    """Named sensor channels.

    ``SensorSuite({"vx": SensorChannel(noise_std=0.05), "r": SensorChannel(noise_std=0.002)})``
    """

    channels: Mapping[str, SensorChannel] = field(default_factory=dict)

    def __post_init__(self) -> None:
        for name, ch in self.channels.items():
            if not isinstance(ch, SensorChannel):
                raise ValueError(f"sensor {name!r}: expected a SensorChannel, got {ch!r}")
        object.__setattr__(self, "channels", MappingProxyType(dict(self.channels)))

    @property
    def random(self) -> bool:
        """Whether any channel draws random numbers (a ``noise_std`` or a ``markov_std``): if
        not, the run's seed changes nothing (a bias is a constant)."""
        return any(c.noise_std > 0.0 or c.markov_std > 0.0 for c in self.channels.values())

    def noise_free(self) -> SensorSuite:
        """The same channels with zero noise and zero bias (rates and delays kept)."""
        return SensorSuite({
            k: SensorChannel(rate_hz=c.rate_hz, delay_s=c.delay_s)
            for k, c in self.channels.items()
        })

    def compile(self, names: tuple[str, ...], dt_control: float, n_steps: int,
                seed: int, *, block: int | None = None,
                unread: Collection[str] = ()) -> CompiledSensors:
        """Arrays for the compiled loop, channels in the order of ``names``.

        ``block`` None: the noise of all ``n_steps`` control steps, drawn now. A block of
        control steps: the noise of the first ``min(block, n_steps)`` steps, and
        :meth:`CompiledSensors.next_block` draws the next ones in their place (the same
        sequences; a long run's noise then takes a block's memory, not the run's).

        A name without a channel is measured perfectly (no noise, bias, delay; every step).
        Each channel's error comes from its own streams (:func:`channel_streams`), so it does
        not depend on ``n_steps`` beyond its length, on the order of ``names`` or on the other
        channels.

        ``unread``: names that nobody reads in this run (the closed loop's built-in controller
        does not use them): no noise is drawn for them and they measure NaN, so that a reader
        shows up as a held (NaN) input instead of a silent value; the other channels' errors
        are those of a run that measures every name (their streams are their own).
        """
        dt_control = positive("dt_control", dt_control, "s")
        unread = frozenset(unread)
        if not unread <= set(names):
            raise ValueError(f"unread = {sorted(unread - set(names))}: not among the measured "
                             f"signals {', '.join(names)}")
        unknown = set(self.channels) - set(names)
        if unknown:
            raise ValueError(
                f"sensor channel(s) {sorted(unknown)} are not measured signals; "
                f"valid: {', '.join(names)}"
            )
        n = len(names)
        table = np.zeros((n, 4))
        chans = [self.channels.get(name, SensorChannel()) for name in names]
        rounded = []
        for i, ch in enumerate(chans):
            table[i, _NOISE] = 1.0
            table[i, _BIAS] = ch.bias
            # the controller's clock is all a channel has: say where it moves a setting
            delay, moved = whole_steps(ch.delay_s, dt_control)
            table[i, _DELAY] = delay
            if moved:
                rounded.append(f"{names[i]}.delay_s = {ch.delay_s:g} s -> "
                               f"{delay * dt_control:g} s")
            table[i, _PERIOD] = 1
            if ch.rate_hz is not None:
                period, moved = whole_steps(1.0 / ch.rate_hz, dt_control)
                table[i, _PERIOD] = max(1, period)
                if moved or period < 1:
                    rounded.append(f"{names[i]}.rate_hz = {ch.rate_hz:g} Hz -> "
                                   f"{1.0 / (table[i, _PERIOD] * dt_control):g} Hz")
        if rounded:
            warn(f"sensors at a control period of {dt_control:g} s: {'; '.join(rounded)} "
                 "(rounded to whole control periods)")
        n_steps = int(n_steps)
        if block is not None:
            if isinstance(block, bool) or not isinstance(block, (int, np.integer)) or block < 1:
                raise ValueError(f"block = {block!r}: expected a whole number of control "
                                 "steps >= 1 (or None)")
            n_steps = min(n_steps, int(block))
        # a channel's sequence is a row: drawn in place (a column of a (n_steps, n) table was a
        # strided copy of every draw: ~15 -> 12.2 ms for a Norisring run's noise)
        noise = np.zeros((n, n_steps))
        for i, name in enumerate(names):
            if name in unread:
                noise[i] = np.nan  # (never drawn into: the blocks rewrite the drawn rows only)
        draw = _NoiseDraw(chans, tuple(names), seed, dt_control, unread)
        draw.next(noise)
        max_delay = int(table[:, _DELAY].max()) if n else 0
        history = np.full((n, max_delay + 1), np.nan)
        held = np.full(n, np.nan)
        return CompiledSensors(tuple(names), table, noise, history, held,
                               None if block is None else draw)


def channel_streams(seed: int, name: str) -> tuple[np.random.Generator, np.random.Generator]:
    """The random streams of the channel ``name`` for the run's ``seed``: (white, drift).

    Children of ``numpy.random.SeedSequence(seed)`` at the spawn keys ``(crc32(name), 0)``
    and ``(crc32(name), 1)`` (CRC-32 of the UTF-8 name: the same on every platform and
    Python version, unlike ``hash``), each a PCG64 generator. :meth:`SensorSuite.compile`
    draws a channel's white noise as ``white.standard_normal(n_steps)`` times ``noise_std``
    and its drift's normals from ``drift`` (:func:`_drift1`, :func:`_drift2`), block after
    block in time order.
    """
    key = zlib.crc32(name.encode())
    return tuple(  # type: ignore[return-value]
        np.random.Generator(np.random.PCG64(np.random.SeedSequence(seed, spawn_key=(key, part))))
        for part in (_WHITE, _DRIFT))


@njit(**no_refcount({"cache": True}))
def sense_step(k, truth, table, noise, kn, history, held, out):
    """Measure the true values ``truth`` at controller step ``k`` into ``out``.

    ``noise[:, kn]`` is the error of step ``k`` (``kn = k - first_step`` of
    :class:`CompiledSensors`: ``k`` itself for sensors compiled whole).

    Mutates ``history`` (ring buffer of true values) and ``held`` (sample-and-hold).
    A non-finite true value propagates to its measurement (a fault the controller must handle);
    a channel whose held sample is not finite (none yet, or a non-finite true value at its
    last sample instant) is not held: it samples again at the next step, off its sample
    instants.
    Allocation-free, compiled without reference counting (``flatfree._vecmath.no_refcount``).
    """
    n = truth.shape[0]
    depth = history.shape[1]
    # the common case (no delay, a sample every step) skips the integer divisions: a modulo is
    # a division, ~15 cycles, and this runs at the control rate for every channel
    slot = k % depth if depth > 1 else 0
    for i in range(n):
        history[i, slot] = truth[i]
        delay = int(table[i, 3])
        if delay == 0:
            delayed = truth[i]  # = history[i, k % depth], just written
        elif k >= delay:
            delayed = history[i, (k - delay) % depth]
        else:
            delayed = history[i, 0]  # not enough history yet: the first value
        period = int(table[i, 2])
        if period == 1 or k % period == 0 or not math.isfinite(held[i]):
            held[i] = delayed + table[i, 1] + table[i, 0] * noise[i, kn]
        out[i] = held[i]
