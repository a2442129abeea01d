"""Causal FIR filtering, batch and streaming, with one set of weights.

The streaming core is a pair of ``numba.njit`` functions over ONE float64 array, the *kernel
state*, which holds the configuration, the weights, the start-up table and the ring buffer. A
compiled simulation loop carries one such array per estimator and calls :func:`fir_update`
once per sample; the Python classes of :mod:`flatfree.estimators` are thin shells over the same
array, and the batch path (``scipy.signal.lfilter``) applies the very same weights with the very
same start-up and non-finite policies.

Why one array: numba reference-counts every array passed to a function it cannot prune the
counts of; four arrays per call cost ~40 ns (measured), one costs a quarter of that.

Layout of a kernel state ``ks`` (all entries float64; integers are stored exactly):

====================  ========================================================================
``ks[0]``             ``ntaps``
``ks[1]``             ``full``: samples seen from which the weights apply (``ntaps``, or
                      ``ntaps + 1`` for the input channel of an F estimator)
``ks[2]``             start-up policy: 0 "prefill", 1 "shrink"
``ks[3]``             non-finite policy: 0 "raise", 1 "hold"
``ks[4]``             ring position ``p`` (state)
``ks[5]``             samples seen, saturated at ``full`` (state)
``ks[6]``             last finite sample, NaN before the first (state)
``ks[7]``             offset of the start-up table
``ks[8]``             offset of the ring buffer
``ks[9]``             layout tag ``_TAG``
``ks[10:10+ntaps]``   weights reversed (oldest sample first)
table                 for ``c`` samples seen (``1 <= c < full``, "shrink" only) ``c`` weights,
                      oldest first, at ``ks[7] + c (c - 1) / 2``
buffer                ``2 ntaps`` slots: each sample is written at ``p`` and ``p + ntaps`` so the
                      window is the contiguous slice ``buf[p+1 .. p+ntaps]`` (after the write)
====================  ========================================================================

Start-up policies. "prefill": the first sample is taken as the whole past (the signal was at
rest before the first sample; a derivative estimate starts at 0, an F estimate at the at-rest
value). "shrink": with ``c < full`` samples the exact design of the shorter window in the table
is used (no assumption on the past, but a larger noise gain).

Non-finite policies. "raise": ``ValueError``; "hold": the sample is replaced by the last finite
one (zero-order hold of the measurement); a non-finite first sample always raises.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from flatfree._validate import real_array, whole
from flatfree._vecmath import no_refcount

__all__ = ["STARTUP", "NONFINITE", "fir_new", "fir_reset", "fir_update", "fir_add", "fir_batch"]

STARTUP = {"prefill": 0, "shrink": 1}
NONFINITE = {"raise": 0, "hold": 1}

_NTAPS, _FULL, _START, _NONF, _P, _COUNT, _HELD, _OTAB, _OBUF, _TAGI = range(10)
_W = 10
_TAG = 20240311.0  # arbitrary constant identifying the layout
# The streaming kernels allocate nothing and only index the kernel state they are given:
# compiled without numba's reference counting (flatfree._vecmath.no_refcount).
_JIT = no_refcount({"cache": True})


def _policy(name: str, value: str, table: dict) -> int:
    if not isinstance(value, str) or value not in table:
        raise ValueError(f"{name} = {value!r}: expected one of {sorted(table)}")
    return table[value]


def fir_new(weights, startup_weights=None, *, full: int | None = None,
            startup: str = "prefill", nonfinite: str = "raise") -> np.ndarray:
    """A fresh kernel state for the compiled core (see the module docstring for the layout).

    Parameters
    ----------
    weights : array, shape (ntaps,)
        ``weights[i]`` multiplies the sample ``i`` steps back.
    startup_weights : callable ``c -> array of length <= c``, optional
        Weights (newest first) to use with ``c`` samples seen, ``1 <= c < full``; required when
        ``startup = "shrink"``.
    full : int, optional
        Samples needed before ``weights`` apply; default ``ntaps``.
    startup, nonfinite : str
        Policies, see the module docstring.
    """
    w = real_array("weights", weights)
    if w.ndim != 1 or w.size == 0 or not np.all(np.isfinite(w)):
        raise ValueError(f"weights: expected a non-empty finite 1-D array, got shape {w.shape}")
    ntaps = w.size
    full = ntaps if full is None else whole("full", full, 1, strict=True)
    if not ntaps <= full <= ntaps + 1:
        raise ValueError(f"full = {full}: must be ntaps ({ntaps}) or ntaps + 1")
    s = _policy("startup", startup, STARTUP)
    nf = _policy("nonfinite", nonfinite, NONFINITE)
    ntab = full * (full - 1) // 2 if s == 1 else 0
    otab = _W + ntaps
    obuf = otab + ntab
    ks = np.zeros(obuf + 2 * ntaps)
    ks[[_NTAPS, _FULL, _START, _NONF, _OTAB, _OBUF, _TAGI]] = (ntaps, full, s, nf, otab, obuf,
                                                               _TAG)
    ks[_HELD] = np.nan
    ks[_W: _W + ntaps] = w[::-1]
    if s == 1:
        if startup_weights is None:
            raise ValueError('startup = "shrink" needs startup weights')
        for c in range(1, full):
            wc = np.asarray(startup_weights(c), dtype=np.float64)
            if wc.size > c:
                raise ValueError(f"startup weights for {c} samples have {wc.size} taps")
            off = otab + c * (c - 1) // 2
            # oldest first within the entry of length c; missing (older) taps stay zero
            ks[off + c - wc.size: off + c] = wc[::-1]
    return ks


def check_kernel(ks) -> np.ndarray:
    """Validate that ``ks`` is a kernel state made by :func:`fir_new`."""
    if not (isinstance(ks, np.ndarray) and ks.dtype == np.float64 and ks.ndim == 1
            and ks.size > _W and ks[_TAGI] == _TAG):
        raise ValueError("ks: expected a kernel state made by fir_new()")
    return ks


@njit(**_JIT)
def fir_reset(ks: np.ndarray) -> None:
    """Reset a kernel state in place to "no sample seen" (weights and table are kept)."""
    ks[_P] = 0.0
    ks[_COUNT] = 0.0
    ks[_HELD] = np.nan
    for i in range(int(ks[_OBUF]), ks.size):
        ks[i] = 0.0


@njit(**_JIT)
def _nonfinite(ks):
    """Cold path of the non-finite policy: the held sample, or ValueError."""
    if ks[_NONF] == 1.0 and np.isfinite(ks[_HELD]):
        return ks[_HELD]
    raise ValueError("non-finite sample (policy 'raise', or 'hold' with no finite sample yet)")


@njit(**_JIT)
def _startup(ks, ntaps, p, count, x):
    """Cold path: fewer samples than ``full``. Returns (estimate, new count)."""
    obuf = int(ks[_OBUF])
    if ks[_START] == 0.0:
        # prefill: the first sample is the whole past (all slots equal: position irrelevant)
        for i in range(2 * ntaps):
            ks[obuf + i] = x
        return _dot(ks, _W, ks, obuf + p + 1, ntaps), int(ks[_FULL])
    off = int(ks[_OTAB]) + count * (count - 1) // 2
    return _dot(ks, off, ks, obuf + p + 1 + ntaps - count, count), count


# The dot product may be reassociated (fastmath "reassoc"): LLVM then sums in SIMD registers
# with several vector accumulators (a 50-tap window: 22 -> ~10 ns per sample in the closed
# loop); the order is fixed by the compiled code (the same for every call with the same
# length), so results are reproducible, and differ from the sequential sum by round-off only
# (tests/test_speed_equivalence.py bounds it). "contract" lets a*b + s be one fused multiply-add.
_JIT_DOT = dict(_JIT, fastmath={"reassoc", "contract"})


@njit(**_JIT_DOT)
def _dot(a, ia, b, ib, m):
    """sum_{j<m} a[ia+j] b[ib+j], vectorised (reassociated; round-off differences only)."""
    # contiguous views indexed by j alone: ia + j would cost a negative-index fix-up per load
    av = a[ia: ia + m]
    bv = b[ib: ib + m]
    acc = 0.0
    for j in range(m):
        acc += av[j] * bv[j]
    return acc


@njit(**dict(_JIT, forceinline=True))  # inlined into the controllers' steps (~1 % of the loop)
def fir_update(ks: np.ndarray, x: float) -> float:
    """Push one sample into a kernel state; return the estimate at this sample.

    Compiled, O(ntaps). Raises ``ValueError`` on a non-finite sample under the "raise" policy
    (or under "hold" before any finite sample).
    """
    if not np.isfinite(x):
        x = _nonfinite(ks)
    ks[_HELD] = x
    ntaps = int(ks[_NTAPS])
    p = int(ks[_P])
    count = int(ks[_COUNT]) + 1
    obuf = int(ks[_OBUF])
    ks[obuf + p] = x
    ks[obuf + p + ntaps] = x
    if count >= ks[_FULL]:
        acc = _dot(ks, _W, ks, obuf + p + 1, ntaps)
        count = int(ks[_FULL])
    else:
        acc, count = _startup(ks, ntaps, p, count, x)
    p += 1
    if p == ntaps:
        p = 0
    ks[_P] = p
    ks[_COUNT] = count
    return acc


@njit(**_JIT)
def fir_add(ks: np.ndarray, lag: int, c: float) -> bool:
    """Add ``c`` to the sample pushed ``lag`` steps ago (0: the newest) in a kernel state's
    buffer; the next :func:`fir_update` sees it so. Returns False, changing nothing, when the
    buffer no longer holds that sample (``lag >= ntaps``) or has not received it."""
    ntaps = int(ks[_NTAPS])
    if lag < 0 or lag >= ntaps or lag >= int(ks[_COUNT]):
        return False
    pos = int(ks[_P]) - 1 - lag
    if pos < 0:
        pos += ntaps
    obuf = int(ks[_OBUF])
    ks[obuf + pos] += c
    ks[obuf + pos + ntaps] += c
    return True


@njit(cache=True)
def _stream_many(ks, x, out):
    for k in range(x.size):
        out[k] = fir_update(ks, x[k])


def nonfinite_message(name: str, k: int, value: float, raise_policy: bool | None) -> str:
    """The error of a sample ``name[k] = value`` that the non-finite policy refuses ("raise",
    or "hold" with no earlier finite sample): one text for the batch and the streaming paths;
    ``raise_policy`` None: a function without a policy (nothing said about one)."""
    if raise_policy is None:
        return f"{name}[{k}] = {value!r}: non-finite sample"
    why = "nonfinite = 'raise'" if raise_policy else (
        "nonfinite = 'hold', and no earlier finite sample to hold")
    return f"{name}[{k}] = {value!r}: non-finite sample ({why})"


def check_finite(y: np.ndarray, nonfinite: str | None, name: str = "y") -> np.ndarray:
    """Apply a non-finite policy to a whole array (the batch twin of the streaming policy);
    ``nonfinite`` None: a caller without a policy, which refuses any non-finite sample."""
    code = 0 if nonfinite is None else _policy("nonfinite", nonfinite, NONFINITE)
    bad = ~np.isfinite(y)
    if not bad.any():
        return y
    k = int(np.flatnonzero(bad)[0])
    if code == 0 or k == 0:
        raise ValueError(nonfinite_message(name, k, float(y[k]),
                                           None if nonfinite is None else code == 0))
    idx = np.where(bad, 0, np.arange(y.size))  # hold: forward fill with the last finite sample
    np.maximum.accumulate(idx, out=idx)
    return y[idx]


def fir_batch(ks: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Batch twin of :func:`fir_update` applied to ``y`` from a fresh state (``lfilter``).

    ``y`` must already be finite (see :func:`check_finite`); ``ks`` is not modified.
    """
    from scipy.signal import lfilter

    check_kernel(ks)
    ntaps, full, startup = int(ks[_NTAPS]), int(ks[_FULL]), int(ks[_START])
    b = ks[_W: _W + ntaps][::-1]
    y = real_array("y", y)
    if y.size == 0:
        return np.zeros(0)
    if startup == 0:
        # prefill: the first sample repeated over the past, exactly as the stream does
        pad = np.full(ntaps - 1, y[0])
        return lfilter(b, [1.0], np.concatenate((pad, y)))[ntaps - 1:]
    out = lfilter(b, [1.0], y)
    otab = int(ks[_OTAB])
    for c in range(1, min(full, y.size + 1)):
        off = otab + c * (c - 1) // 2
        out[c - 1] = float(np.dot(ks[off: off + c], y[:c]))
    return out
