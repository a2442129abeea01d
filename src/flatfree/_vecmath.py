"""Vectorisable double-precision ``atan``, ``sin``, ``cos`` and ``exp`` for compiled lane loops.

numba calls the C library for ``math.atan`` & co., one scalar call per value; without a SIMD
math library (numba's SVML support needs an SVML-patched llvmlite, absent here) a loop that
contains such a call is never vectorised. The functions below are straight-line arithmetic:
argument reduction by selects instead of branches, a polynomial, and a few exact operations.
They are compiled with ``forceinline`` so that LLVM inlines them into the caller's loop and can
evaluate 4 lanes at once in AVX2/AVX-512 registers (``flatfree.tires.mf_combined4``, the 10DoF
model's tyres). They are private helpers for hot kernels; everywhere else use ``math``.
:func:`no_refcount` gives the compile options of a kernel that needs no reference counting
(allocation-free kernels of the 10DoF model and the closed loop); :func:`all_finite` is the
models' and the loop's check of a state vector, compiled that way.

Methods (the classic schemes of [Muller] ch. 11 and [C&W]; coefficients computed here)
--------------------------------------------------------------------------------------
``atan(x)``: ``t = |x|`` is reduced with ``atan t = atan c + atan((t - c)/(1 + c t))``: ``c = 0``
for ``t <= tan(pi/8)``, ``c = 1`` up to ``tan(3 pi/8)`` (``z = (t - 1)/(t + 1)``), ``c = inf``
above (``z = -1/t``), so ``|z| <= tan(pi/8)``; then ``atan z = z + z^3 P(z^2)`` with ``P`` of
degree 10, and ``atan c`` is added as a double-double ``c_hi + c_lo``; ``copysign`` restores
the sign (odd, ``atan(+-0) = +-0``, ``atan(+-inf) = +-pi/2``).

``sin(x)``, ``cos(x)``: ``j = round(2 x / pi)`` by adding ``1.5 2^52`` (the sum's low mantissa
bits hold ``j``, whose two lowest bits give the quadrant), ``r = x - j pi/2`` with pi/2 split in
three (Cody and Waite: ``P1``, ``P2`` have 30 significant bits, so ``j P1`` and ``j P2`` are
exact for ``|j| < 2^23``), ``|r| <= pi/4`` up to rounding. One polynomial per lane, its
coefficients selected by the quadrant: ``sin r = r (1 + r^2 S(r^2))`` (``S`` of degree 6) or
``cos r = 1 + r^2 C'(r^2)``, ``C'(w) = -1/2 + w C(w)`` (``C`` of degree 5), then the sign.

``exp(x)``: ``n = round(x / ln 2)`` (the same shift), ``r = x - n ln 2`` (ln 2 split in two, the
high part with 32 bits), ``e^r = 1 + r + r^2 E(r)`` (``E`` of degree 9), times ``2^n`` built from
its bit pattern in two factors ``2^n1 2^n2`` so that results near overflow and in the subnormal
range are rounded once.

The polynomials interpolate the reduced functions ``(atan z - z)/z^3``, ``(sin r - r)/r^3``,
``(cos r - 1 + r^2/2)/r^4`` (in ``w = z^2``, ``r^2``) and ``(e^r - 1 - r)/r^2`` at the ``n + 1``
Chebyshev nodes (first kind) of the reduced interval (``[0, tan(pi/8)^2]``, ``[0, (pi/4)^2]``
twice, ``[-ln2/2, ln2/2]``), computed with mpmath at 60 digits and rounded to double
(near-minimax; ``tests/test_vecmath.py`` recomputes them and checks every literal). Their
interpolation error is below 4e-16 relative, a few hundredths of an ulp of the result. They
are evaluated with Estrin's scheme (shorter dependency chains than Horner's) and fused
multiply-adds where the CPU has them (``fastmath={"contract"}``; the reductions stay exact
with or without fusion).

Accuracy (``tests/test_vecmath.py``; 2026-11-22): at most 2 ulp from libm's result on dense grids
(``atan`` on [-20, 20] and magnitudes 1e-300 to 1e300, ``sin``, ``cos`` on [-10, 10] and at
random points of [-1e5, 1e5], ``exp`` on [-745, 709.7]); against mpmath at 20 000-40 000 random
points of the Magic Formula's range: max 1.76 ulp (``atan``), 1.26 (``sin``), 1.33 (``cos``),
1.03 (``exp``), where libm has 0.51. Domain: ``atan`` and ``exp`` all doubles (``exp``
overflows to ``inf`` above 709.78 and underflows gradually below -708; NaN gives NaN);
``sin``, ``cos`` for ``|x| <= 2^22`` (the exactness range of the reduction; the Magic Formula
needs ``|x| < 4``), NaN outside and for NaN.

References
----------
[C&W] W. J. Cody, W. Waite, Software Manual for the Elementary Functions, Prentice-Hall, 1980
      (additive argument reduction with a split constant).
[Muller] J.-M. Muller, Elementary Functions: Algorithms and Implementation, 3rd ed.,
      Birkhaeuser, 2016, ch. 3 (polynomial approximation, Estrin's scheme) and ch. 11 (range
      reduction).
[Trefethen] L. N. Trefethen, Approximation Theory and Approximation Practice, SIAM, 2013,
      ch. 16 (Chebyshev interpolants are near-best).
"""

from __future__ import annotations

import math

from llvmlite import ir
from numba import njit, types
from numba.core import cgutils
from numba.core.errors import RequireLiteralValue
from numba.extending import intrinsic
from numba.np.arrayobj import load_item, make_array, populate_array

__all__ = ["atan", "sin", "cos", "exp", "as_tuple", "stack_array", "no_refcount", "all_finite"]

# forceinline: LLVM inlines these into the calling loop (a call would stop vectorisation);
# error_model="numpy": divisions have no zero check (a branch), x/0 gives inf as in IEEE 754;
# fastmath "contract" only: a*b + c may become one fused multiply-add (one rounding instead of
# two; the error bounds below hold with and without fusion).
_VJIT = dict(cache=True, nogil=True, error_model="numpy", forceinline=True,
             fastmath={"contract"})

# ---- atan: break points tan(pi/8), tan(3pi/8); pi/4, pi/2 as double-double; P (degree 10) ----
_TAN_PI8, _TAN_3PI8 = 0.41421356237309503, 2.414213562373095
_PI4_HI, _PI4_LO = 0.7853981633974483, 3.061616997868383e-17  # pi/4
_PI2_HI, _PI2_LO = 1.5707963267948966, 6.123233995736766e-17  # pi/2
_AT = (
    -0.3333333333333333, 0.1999999999999552, -0.14285714284666542, 0.11111111015256361,
    -0.09090904578123903, 0.07692183190826087, -0.06664511447381948, 0.0585814891280221,
    -0.0508544973794026, 0.03923165829558719, -0.01917688711906226,
)

# ---- sin/cos: 2/pi, pi/2 = P1 + P2 + P3 (|error| 4.8e-36), S (degree 6), C (degree 5) ----
_TWO_OVER_PI = 0.6366197723675814
_P1, _P2, _P3 = 1.5707963276654482, -8.705515692000731e-10, -3.50343439808993e-19
_SN = (
    -0.16666666666666666, 0.008333333333333331, -0.00019841269841265065,
    2.7557319219339167e-06, -2.5052106232447578e-08, 1.6058531618986147e-10,
    -7.586697117706918e-13,
)
_CS = (
    0.041666666666666664, -0.0013888888888887398, 2.480158729876569e-05,
    -2.7557317271729793e-07, 2.08761462684032e-09, -1.1382632425521717e-11,
)
_SINCOS_MAX = 4194304.0  # 2^22: |j| < 2^23 keeps j P1, j P2 exact
# round to an integer by adding 1.5 2^52: the sum's last bit has weight 1, and its low mantissa
# bits hold the integer in two's complement (for |integer| < 2^51)
_SHIFTER = 6755399441055744.0
_SHIFTER_BITS = 0x4338000000000000  # bit pattern of _SHIFTER

# ---- exp: 1/ln 2, ln 2 = L1 + L2 (|error| 1.3e-27), E (degree 9), clamp range ----
_LOG2E = 1.4426950408889634
_L1, _L2 = 0.6931471806019545, -4.2009150726810846e-11
_EX = (
    0.5000000000000001, 0.16666666666666669, 0.041666666666624164, 0.008333333333330065,
    0.0013888888917196719, 0.00019841269863040545, 2.4801521322368692e-05,
    2.7557268480310024e-06, 2.7620075879983367e-07, 2.5100375832561234e-08,
)
_EXP_HI, _EXP_LO = 710.0, -746.0  # beyond: inf, 0 (exp(709.79) > DBL_MAX, exp(-745.14) < 2^-1075)


@intrinsic
def _int64_bits_as_float64(typingctx, bits):
    """Reinterpret the bits of an int64 as a float64 (an LLVM ``bitcast``, vectorisable)."""
    if not isinstance(bits, types.Integer):
        return None

    def codegen(context, builder, signature, args):
        val = context.cast(builder, args[0], signature.args[0], types.int64)
        return builder.bitcast(val, ir.DoubleType())

    return types.float64(bits), codegen


@intrinsic
def _float64_bits_as_int64(typingctx, x):
    """Reinterpret the bits of a float64 as an int64 (an LLVM ``bitcast``, vectorisable)."""
    if not isinstance(x, types.Float):
        return None

    def codegen(context, builder, signature, args):
        val = context.cast(builder, args[0], signature.args[0], types.float64)
        return builder.bitcast(val, ir.IntType(64))

    return types.int64(x), codegen


def no_refcount(options: dict) -> dict:
    """``options`` plus ``_nrt=False`` when this numba knows the option (else unchanged).

    numba increfs and decrefs every array argument (and every view) of a compiled function on
    every call, with lock-prefixed atomic operations that its pruning pass cannot remove across
    calls that are not inlined; in the 10DoF model they took ~37 % of the run time and in the
    closed loop's controller ~30 % (perf and timings, benchmarks/README.md). A kernel that
    allocates nothing and only indexes arrays owned by its caller for the whole call needs no
    reference counting: ``_nrt=False`` compiles it without numba's runtime (an underscore
    option, which numba's own string and sort kernels use for the same reason). Should a numba
    release drop it, the option is left out (checked without compiling anything): the kernels
    are then slower but identical.
    """
    try:
        from numba.core.cpu import CPUTargetOptions

        known = hasattr(CPUTargetOptions, "_nrt")
    except ImportError:  # pragma: no cover - a numba without this module layout
        known = False
    return dict(options, _nrt=False) if known else dict(options)


@intrinsic
def as_tuple(typingctx, arr, n):
    """The first ``n`` (a compile-time constant) elements of a 1-d array as a tuple.

    A lane loop that reads coefficients from a tuple (values in registers) instead of an array
    touches no memory for them, so LLVM needs no run-time alias checks between them and the
    loop's stores (it allows none in a loop of 4 iterations) and can vectorise the loop.
    No bounds check: ``n <= arr.size`` is the caller's duty.
    """
    if not (isinstance(arr, types.Array) and arr.ndim == 1 and isinstance(n, types.Integer)):
        return None
    if not isinstance(n, types.IntegerLiteral):
        raise RequireLiteralValue("as_tuple: the length must be a compile-time constant")
    count = int(n.literal_value)
    tupty = types.UniTuple(arr.dtype, count)

    def codegen(context, builder, signature, args):
        aryty = signature.args[0]
        ary = context.make_array(aryty)(context, builder, value=args[0])
        out = context.get_constant_undef(tupty)
        for k in range(count):
            ptr = cgutils.get_item_pointer(context, builder, aryty, ary,
                                           [context.get_constant(types.intp, k)])
            out = builder.insert_value(out, load_item(context, builder, aryty, ptr), k)
        return out

    return tupty(arr, n), codegen


@intrinsic
def stack_array(typingctx, rows, cols):
    """An uninitialised C-contiguous float64 array of shape ``(rows, cols)`` (compile-time
    constants) in the stack frame of the compiled function that calls this.

    Scratch for a lane loop's results that the rest of the function reads back: a local array
    no argument can alias, so the loop's stores to it are contiguous vector stores (an array
    argument's rows at a stride would be scattered) and nothing else waits on them. Valid until
    that function returns: never return it or keep a view of it. No reference counting (no
    meminfo); every element read must have been written first.
    """
    if not (isinstance(rows, types.Integer) and isinstance(cols, types.Integer)):
        return None
    if not (isinstance(rows, types.IntegerLiteral) and isinstance(cols, types.IntegerLiteral)):
        raise RequireLiteralValue("stack_array: the shape must be compile-time constants")
    nr = int(rows.literal_value)
    nc = int(cols.literal_value)
    if nr < 1 or nc < 1:
        raise ValueError("stack_array: the shape must be positive")
    arrty = types.Array(types.float64, 2, "C")

    def codegen(context, builder, signature, args):
        dbl = ir.DoubleType()
        with builder.goto_entry_block():  # once per call of the function, not per use
            buf = builder.alloca(ir.ArrayType(dbl, nr * nc))
            buf.align = 32  # a 4-lane vector store within one cache line
        data = builder.bitcast(buf, dbl.as_pointer())
        ary = make_array(arrty)(context, builder)
        intp = context.get_value_type(types.intp)
        populate_array(ary, data=data, shape=(intp(nr), intp(nc)),
                       strides=(intp(8 * nc), intp(8)), itemsize=8, meminfo=None)
        return ary._getvalue()

    return arrty(rows, cols), codegen


@njit(**_VJIT)
def _pow2(k: int) -> float:
    """``2^k`` for an integer ``k`` in [-1022, 1023] [IEEE 754 binary64 layout]."""
    return _int64_bits_as_float64((k + 1023) << 52)


@njit(**_VJIT)
def atan(x: float) -> float:
    """Arc tangent [rad], in ``[-pi/2, pi/2]``; error < 2 ulp (module docstring)."""
    t = abs(x)
    # reduction atan t = atan c + atan((t - c)/(1 + c t)) [Muller] 11, one division, selects
    big = t > _TAN_3PI8
    mid = t > _TAN_PI8
    num = -1.0 if big else (t - 1.0 if mid else t)  # c = inf: atan t = pi/2 - atan(1/t)
    den = t if big else (t + 1.0 if mid else 1.0)  # c = 1: z = (t - 1)/(t + 1)
    khi = _PI2_HI if big else (_PI4_HI if mid else 0.0)
    klo = _PI2_LO if big else (_PI4_LO if mid else 0.0)
    z = num / den  # |z| <= tan(pi/8)
    w = z * z
    # P(w) by Estrin's scheme: 4 dependent multiply-adds instead of 10
    w2 = w * w
    w4 = w2 * w2
    w8 = w4 * w4
    q0 = (_AT[0] + _AT[1] * w) + (_AT[2] + _AT[3] * w) * w2
    q1 = (_AT[4] + _AT[5] * w) + (_AT[6] + _AT[7] * w) * w2
    q2 = (_AT[8] + _AT[9] * w) + _AT[10] * w2
    p = (q0 + q1 * w4) + q2 * w8
    # atan c + z + z^3 P(z^2): the small terms first, the double-double constant last
    y = khi + (z + (z * (w * p) + klo))
    return math.copysign(y, x)


@njit(**_VJIT)
def _sin_cos_quadrant(x: float, shift: int) -> float:
    """``sin(x + shift pi/2)`` for ``shift`` in {0, 1} (module docstring)."""
    # j = round(2 x / pi), as the low bits of t (|2 x / pi| < 2^51): no rounding instruction
    t = x * _TWO_OVER_PI + _SHIFTER
    j = t - _SHIFTER
    r = ((x - j * _P1) - j * _P2) - j * _P3  # [C&W]: j P1, j P2 exact for |j| < 2^23
    q = _float64_bits_as_int64(t) + shift  # quadrant: j + shift mod 4 in the two lowest bits
    use_cos = (q & 1) != 0
    # sin r = r (1 + w S(w)), cos r = 1 (1 + w C'(w)) with C'(w) = -1/2 + w C(w): one
    # polynomial per lane, its coefficients selected by the quadrant
    w = r * r
    c0 = -0.5 if use_cos else _SN[0]
    c1 = _CS[0] if use_cos else _SN[1]
    c2 = _CS[1] if use_cos else _SN[2]
    c3 = _CS[2] if use_cos else _SN[3]
    c4 = _CS[3] if use_cos else _SN[4]
    c5 = _CS[4] if use_cos else _SN[5]
    c6 = _CS[5] if use_cos else _SN[6]
    w2 = w * w
    w4 = w2 * w2
    p = ((c0 + c1 * w) + (c2 + c3 * w) * w2) + ((c4 + c5 * w) + c6 * w2) * w4
    a = 1.0 if use_cos else r
    y = a + (a * w) * p
    y = -y if (q & 2) != 0 else y
    return y if abs(x) <= _SINCOS_MAX else math.nan


@njit(**_VJIT)
def sin(x: float) -> float:
    """Sine; error < 2 ulp for ``|x| <= 2^22``, NaN beyond (module docstring)."""
    return _sin_cos_quadrant(x, 0)


@njit(**_VJIT)
def cos(x: float) -> float:
    """Cosine; error < 2 ulp for ``|x| <= 2^22``, NaN beyond (module docstring)."""
    return _sin_cos_quadrant(x, 1)


@njit(**_VJIT)
def exp(x: float) -> float:
    """Exponential; error < 2 ulp (module docstring)."""
    xc = _EXP_HI if x > _EXP_HI else x
    xc = _EXP_LO if xc < _EXP_LO else xc
    # xc == xc: False only for NaN (the NaN test, kept in this compiled kernel as written)
    xc = xc if xc == xc else 0.0  # noqa: PLR0124  NaN: any finite value, replaced at the end
    t = xc * _LOG2E + _SHIFTER  # n = round(x / ln 2) in the low bits of t
    n = t - _SHIFTER
    r = (xc - n * _L1) - n * _L2  # [C&W]: n L1 exact for |n| < 2^21
    r2 = r * r
    r4 = r2 * r2
    r8 = r4 * r4
    q0 = (_EX[0] + _EX[1] * r) + (_EX[2] + _EX[3] * r) * r2
    q1 = (_EX[4] + _EX[5] * r) + (_EX[6] + _EX[7] * r) * r2
    q2 = _EX[8] + _EX[9] * r
    p = (q0 + q1 * r4) + q2 * r8
    er = 1.0 + (r + r2 * p)
    ni = _float64_bits_as_int64(t) - _SHIFTER_BITS  # n as an integer
    n1 = ni >> 1  # 2^n = 2^n1 2^n2 with both factors normal for n in [-1076, 1024]
    y = (er * _pow2(n1)) * _pow2(ni - n1)
    return y if x == x else x  # noqa: PLR0124  NaN in, NaN out (the NaN test above)


# A kernel that allocates nothing and only reads the array it is given (no_refcount above):
# callable from kernels compiled with and without reference counting; forceinline lets LLVM fold
# the loop into the caller's step loop.
_FJIT = no_refcount(dict(cache=True, nogil=True, forceinline=True))


@njit(**_FJIT)
def all_finite(x) -> bool:
    """Every entry of the 1-d array ``x`` finite (no NaN, no inf); ``True`` for an empty array.

    Stops at the first non-finite entry.
    """
    for i in range(x.shape[0]):  # noqa: SIM110  a loop: compiled, no generator
        if not math.isfinite(x[i]):
            return False
    return True
