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
- **noise**: additive Gaussian, standard deviation ``noise_std``, drawn in advance for the whole
  run: the same seed gives bit-identical runs, different seeds different noise. Noise is drawn
  once per sample (held between samples).
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
from collections.abc import Mapping
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
    """Arrays for :func:`sense_step`: parameters, pre-drawn noise and the state to mutate."""

    names: tuple[str, ...]
    table: np.ndarray  # (n_channels, 4): 1 (noise scale), bias, period_steps, delay_steps
    noise: np.ndarray  # (n_channels, n_steps) error sequences in the signals' units
    history: np.ndarray  # (n_channels, max_delay + 1) ring buffer of true values
    held: np.ndarray  # (n_channels,) last measured value

    def reset(self) -> None:
        """Clear the state (history and held values) for a new run."""
        self.history[:] = np.nan
        self.held[:] = np.nan


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
                seed: int) -> CompiledSensors:
        """Arrays for the compiled loop, channels in the order of ``names``.

        A name without a channel is measured perfectly (no noise, bias, delay; every step).
        Each channel's error comes from its own streams (:func:`channel_streams`), so it does
        not depend on ``n_steps`` beyond its length, on the order of ``names`` or on the other
        channels.
        """
        dt_control = positive("dt_control", dt_control, "s")
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
        # a channel's sequence is a row: drawn in place (a column of a (n_steps, n) table was a
        # strided copy of every draw: ~15 -> 12.2 ms for a Norisring run's noise)
        noise = np.zeros((n, n_steps))
        for i, ch in enumerate(chans):
            if ch.noise_std == 0.0 and ch.markov_std == 0.0:
                continue  # nothing drawn: the other channels' streams are their own anyway
            white, drift = channel_streams(seed, names[i])
            if ch.noise_std > 0.0:
                white.standard_normal(out=noise[i])
                noise[i] *= ch.noise_std
            if ch.markov_std > 0.0:
                make = _gauss_markov if ch.markov_order == 1 else _gauss_markov2
                noise[i] += make(drift, n_steps, ch.markov_std,
                                 math.exp(-dt_control / ch.markov_tau_s))
        max_delay = int(table[:, _DELAY].max()) if n else 0
        history = np.full((n, max_delay + 1), np.nan)
        held = np.full(n, np.nan)
        return CompiledSensors(tuple(names), table, noise, history, held)


def channel_streams(seed: int, name: str) -> tuple[np.random.Generator, np.random.Generator]:
    """The random streams of the channel ``name`` for the run's ``seed``: (white, drift).

    Children of ``numpy.random.SeedSequence(seed)`` at the spawn keys ``(crc32(name), 0)``
    and ``(crc32(name), 1)`` (CRC-32 of the UTF-8 name: the same on every platform and
    Python version, unlike ``hash``), each a PCG64 generator. :meth:`SensorSuite.compile`
    draws a channel's white noise as ``white.standard_normal(n_steps)`` times ``noise_std``
    and its drift's normals from ``drift`` (:func:`_gauss_markov`, :func:`_gauss_markov2`).
    """
    key = zlib.crc32(name.encode())
    return tuple(  # type: ignore[return-value]
        np.random.Generator(np.random.PCG64(np.random.SeedSequence(seed, spawn_key=(key, part))))
        for part in (_WHITE, _DRIFT))


def _gauss_markov(rng: np.random.Generator, n: int, std: float, phi: float) -> np.ndarray:
    """A stationary first-order Gauss-Markov sequence (module docstring), via lfilter."""
    from scipy.signal import lfilter

    # drawn in time order (a shorter run's sequence is the start of a longer one's)
    if n == 0:
        return np.zeros(0)
    w = rng.standard_normal(n)
    w[0] *= std  # b[0] from the stationary distribution
    w[1:] *= std * math.sqrt(1.0 - phi * phi)
    return lfilter([1.0], [1.0, -phi], w)


def _gauss_markov2(rng: np.random.Generator, n: int, std: float, phi: float) -> np.ndarray:
    """A stationary second-order Gauss-Markov sequence (module docstring): two first-order
    stages in cascade, their state before the first sample drawn from its stationary
    distribution, scaled to the standard deviation ``std``."""
    from scipy.signal import lfilter

    q = 1.0 - phi * phi
    var_s, cov_ys, var_y = 1.0 / q, 1.0 / (q * q), (1.0 + phi * phi) / (q * q * q)
    # drawn in time order: first the state (s, y) at k = -1, s from its marginal and y from
    # its law given s, then the driving noise
    z = rng.standard_normal(n + 2)
    s_m = z[0] * math.sqrt(var_s)
    y_m = (cov_ys / var_s) * s_m + z[1] * math.sqrt(var_y - cov_ys * cov_ys / var_s)
    scale = std / math.sqrt(var_y)
    w = z[2:] * scale
    s1, _ = lfilter([1.0], [1.0, -phi], w, zi=[phi * s_m * scale])
    y, _ = lfilter([1.0], [1.0, -phi], s1, zi=[phi * y_m * scale])
    return y


@njit(**no_refcount({"cache": True}))
def sense_step(k, truth, table, noise, history, held, out):
    """Measure the true values ``truth`` at controller step ``k`` into ``out``.

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
            held[i] = delayed + table[i, 1] + table[i, 0] * noise[i, k]
        out[i] = held[i]
