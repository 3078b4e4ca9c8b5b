"""Tables of floats as CSV text, fast and exact: 17 significant digits, correctly rounded.

``numpy.savetxt`` formats each value with Python's ``%`` (about 3 s for the 15,000 x 237 table
of a TL074 wheelset run). Here numba forms the digits: each value is multiplied by a power
of ten held as a double-double (an exact power split in two floats), the product is formed
exactly (Dekker's two-product) and rounded to a 17-digit integer. That integer is the
correctly rounded one unless the product lies within 1e-7 of a rounding tie, far beyond
what the double-double's ~1e-30 relative error can move; such values, and those outside
1e-270 ... 1e290 in magnitude (where a power of ten would overflow the split), are formatted
by Python's ``repr``. 17 correctly rounded digits read back to the same float.
"""

from __future__ import annotations

import math
import time
import warnings
from collections.abc import Iterator, Sequence

import numpy as np

from circuitsim.solver.jit import library_in_use, njit

LOW_EXPONENT, HIGH_EXPONENT = -270, 290  # decimal exponents formed here; outside: repr
POWER_OFFSET = 16 - HIGH_EXPONENT  # POWERS[k - POWER_OFFSET] is 10**k
COMPILE_KIND = "CSV writer"  # its name in the compile announcement and the timings file
TOKEN = 24  # longest token: "-1.2345678901234567e-270"
SPLITTER = 134217729.0  # 2**27 + 1 (Dekker)


def _power_ratio(k: int) -> tuple[int, int]:
    """10**k as (numerator, denominator), integers."""
    return (10**k, 1) if k >= 0 else (1, 10**-k)


def _powers() -> np.ndarray:
    """10**k for k = 16 - HIGH_EXPONENT ... 16 - LOW_EXPONENT as (hi, lo) double-doubles.

    Integer arithmetic (a tenth of Fraction's time at each import): Python's true division
    of two integers is correctly rounded, so hi is 10**k rounded and lo the exact rest
    (10**k - hi, a ratio of integers) rounded."""
    table = []
    for k in range(16 - HIGH_EXPONENT, 16 - LOW_EXPONENT + 1):
        numerator, denominator = _power_ratio(k)
        hi = numerator / denominator
        p, q = hi.as_integer_ratio()
        table.append((hi, (numerator * q - p * denominator) / (denominator * q)))
    return np.array(table)


POWERS = _powers()
# 10**k for k = LOW_EXPONENT ... HIGH_EXPONENT, rounded (only compared with: see _write_token)
TENS = np.array([n / d for n, d in map(_power_ratio, range(LOW_EXPONENT, HIGH_EXPONENT + 1))])
LOG10_2 = 0.30102999566398120
# "00", "01", ... "99" as ASCII codes: two digits per division
DIGIT_PAIRS = np.frombuffer("".join(f"{k:02d}" for k in range(100)).encode(), dtype=np.uint8)


@njit(cache=True, inline="always")
def _two_product(a, b):
    """a * b as hi + lo, exactly (Dekker)."""
    p = a * b
    t = SPLITTER * a
    a_hi = t - (t - a)
    a_lo = a - a_hi
    t = SPLITTER * b
    b_hi = t - (t - b)
    b_lo = b - b_hi
    return p, ((a_hi * b_hi - p) + a_hi * b_lo + a_lo * b_hi) + a_lo * b_lo


@njit(cache=True, inline="always")
def _digits(value, exponent, powers):
    """(17-digit integer, whether it is certain) of |value| / 10**(exponent - 16)."""
    p_hi, p_lo = powers[16 - exponent - POWER_OFFSET, 0], powers[16 - exponent - POWER_OFFSET, 1]
    hi, lo = _two_product(value, p_hi)
    lo += value * p_lo
    whole = math.floor(hi)
    rest = (hi - whole) + lo
    below = math.floor(rest)
    fraction = rest - below
    number = np.uint64(np.int64(whole) + np.int64(below) + (1 if fraction >= 0.5 else 0))
    return number, abs(fraction - 0.5) > 1e-7


@njit(cache=True, inline="always")
def _write_token(out, at, value, powers):
    """Write ``value``'s token at out[at:]; returns the new end, or -1 when repr must."""
    if value != value:
        out[at], out[at + 1], out[at + 2] = 110, 97, 110  # nan
        return at + 3
    if value == 0.0:
        if math.copysign(1.0, value) < 0:
            out[at] = 45
            at += 1
        out[at] = 48
        return at + 1
    magnitude = abs(value)
    if magnitude == np.inf:
        if value < 0:
            out[at] = 45
            at += 1
        out[at], out[at + 1], out[at + 2] = 105, 110, 102  # inf
        return at + 3
    # the decimal exponent from the binary one (log10(2) = 0.30103...), then one comparison
    # with a power of ten; _digits' count of digits corrects what a rounded power misjudges
    exponent = int(math.floor((math.frexp(magnitude)[1] - 1) * LOG10_2))
    if exponent < LOW_EXPONENT - 1 or exponent > HIGH_EXPONENT - 1:
        return -1
    if magnitude >= TENS[exponent + 1 - LOW_EXPONENT]:
        exponent += 1
    number, certain = _digits(magnitude, exponent, powers)
    if number >= 100_000_000_000_000_000:  # the exponent one too small
        exponent += 1
        number, certain = _digits(magnitude, exponent, powers)
    elif number < 10_000_000_000_000_000:
        exponent -= 1
        number, certain = _digits(magnitude, exponent, powers)
    if not certain or exponent < LOW_EXPONENT or exponent > HIGH_EXPONENT - 1:
        return -1
    if value < 0:
        out[at] = 45
        at += 1
    # 17 digits d.dddddddd dddddddd: the first nine and the last eight formed two at a time,
    # in two independent chains of unsigned divisions by a constant (which compile to
    # multiplications; signed ones do not), then the fraction's trailing zeros dropped
    eight = np.uint64(100_000_000)
    head = np.uint32(number // eight)
    tail = np.uint32(number - np.uint64(head) * eight)
    hundred = np.uint32(100)
    for k in range(4):
        pair = 2 * (tail % hundred)
        tail //= hundred
        out[at + 16 - 2 * k], out[at + 17 - 2 * k] = DIGIT_PAIRS[pair], DIGIT_PAIRS[pair + 1]
        pair = 2 * (head % hundred)
        head //= hundred
        out[at + 8 - 2 * k], out[at + 9 - 2 * k] = DIGIT_PAIRS[pair], DIGIT_PAIRS[pair + 1]
    out[at] = 48 + head
    out[at + 1] = 46
    end = at + 17
    while out[end] == 48:
        end -= 1
    at = end if out[end] == 46 else end + 1
    if exponent != 0:
        out[at] = 101
        out[at + 1] = 45 if exponent < 0 else 43
        at += 2
        e = np.uint32(abs(exponent))
        if e >= 100:
            out[at] = 48 + e // np.uint32(100)
            at += 1
        out[at] = 48 + (e // np.uint32(10)) % np.uint32(10)
        out[at + 1] = 48 + e % np.uint32(10)
        at += 2
    return at


@njit(cache=True)
def _write_rows(table, powers, fallback, fallback_len):
    """The rows of ``table`` as CSV bytes, and the flat indices whose token repr must form
    (those are written from ``fallback``, one row of bytes per such value, in order, once
    known: a first call passes none and learns the indices)."""
    rows, cols = table.shape
    out = np.empty(rows * cols * (TOKEN + 1) + 1, dtype=np.uint8)
    missing = []
    at = 0
    used = 0
    for i in range(rows):
        for j in range(cols):
            end = _write_token(out, at, table[i, j], powers)
            if end < 0:
                missing.append(i * cols + j)
                if used < fallback.shape[0]:
                    n = fallback_len[used]
                    out[at : at + n] = fallback[used, :n]
                    end = at + n
                else:
                    end = at
                used += 1
            out[end] = 44 if j < cols - 1 else 10
            at = end + 1
    return out[:at], np.array(missing, dtype=np.int64)


def table_lines(table: np.ndarray, rows_per_chunk: int = 512) -> Iterator[bytes]:
    """``table`` (rows, columns) of floats as CSV lines (comma-separated, newline-ended),
    17 significant digits correctly rounded (each value reads back exactly), in chunks of
    ``rows_per_chunk`` rows (a small buffer, reused while it is hot in the cache).

    Parameters
    ----------
    table : ndarray, shape (m, k)

    Yields
    ------
    bytes
        ASCII text of consecutive rows.
    """
    table = np.asarray(table, dtype=np.float64)
    if table.ndim != 2 or table.shape[1] == 0:
        raise ValueError(f"table_lines: expected a 2-d table with columns, got {table.shape}")
    rows = range(0, table.shape[0], rows_per_chunk)
    chunks = (np.ascontiguousarray(table[start : start + rows_per_chunk]) for start in rows)
    yield from _compiled_chunks(chunks)


def column_lines(columns: Sequence[np.ndarray], rows_per_chunk: int = 512) -> Iterator[bytes]:
    """:func:`table_lines` of the table whose columns are ``columns`` (each shape (m,)),
    without forming that table: one chunk of rows at a time is gathered from the columns
    (a run's recorded signals are written with the memory of a chunk, not of a copy).

    Raises
    ------
    ValueError
        No columns, or columns of different lengths.
    """
    columns = [np.asarray(c, dtype=np.float64) for c in columns]
    lengths = {c.shape for c in columns}
    if not columns or len(lengths) != 1 or len(next(iter(lengths))) != 1:
        raise ValueError(f"column_lines: expected 1-d columns of one length, got {lengths}")
    rows = columns[0].size
    chunk = np.empty((min(rows, rows_per_chunk), len(columns)))

    def chunks() -> Iterator[np.ndarray]:
        for start in range(0, rows, rows_per_chunk):
            count = min(rows_per_chunk, rows - start)
            for j, column in enumerate(columns):
                chunk[:count, j] = column[start : start + count]
            yield chunk[:count]

    yield from _compiled_chunks(chunks())


def _compile_announced() -> float | None:
    """Warn (a KernelCompileWarning with an estimate) when the writer must compile before it
    runs: its first use after an install or a change (seconds to a minute; then it is kept
    in the user cache directory). Returns when that compile started (None: nothing to
    compile)."""
    from circuitsim.solver.compiled.cache import compile_notice, is_cold
    from circuitsim.solver.errors import KernelCompileWarning

    if not is_cold(_write_rows):
        return None
    warnings.warn(KernelCompileWarning(compile_notice(COMPILE_KIND)), stacklevel=4)
    return time.perf_counter()


def _compiled_chunks(chunks: Iterator[np.ndarray]) -> Iterator[bytes]:
    """The text of each chunk; a compile of the writer is announced first and its time
    kept as the next estimate."""
    from circuitsim.solver.compiled.cache import record_compile_seconds

    compiling = _compile_announced()
    for chunk in chunks:
        text = _chunk_text(chunk)
        if compiling is not None:
            record_compile_seconds(COMPILE_KIND, time.perf_counter() - compiling)
            compiling = None
        yield text
    _build_startup_library()


def _build_startup_library() -> None:
    """After the writer ran from numba: its module of the start-up library, when missing."""
    from circuitsim.solver.compiled.startup_library import build_when_missing

    build_when_missing(COMPILE_KIND)


def _chunk_text(chunk: np.ndarray) -> bytes:
    """The CSV text of the C-contiguous rows ``chunk``; repr forms the few tokens the compiled
    writer leaves (see the module's docstring)."""
    none = np.zeros((0, TOKEN), dtype=np.uint8)
    text, missing = _write_rows(chunk, POWERS, none, np.zeros(0, dtype=np.int64))
    if missing.size:
        tokens = [repr(float(v)).encode() for v in chunk.ravel()[missing]]
        fallback = np.zeros((len(tokens), TOKEN), dtype=np.uint8)
        for k, token in enumerate(tokens):
            fallback[k, : len(token)] = np.frombuffer(token, dtype=np.uint8)
        lengths = np.array([len(t) for t in tokens], dtype=np.int64)
        text, _ = _write_rows(chunk, POWERS, fallback, lengths)
    return text.tobytes()


def table_text(table: np.ndarray) -> bytes:
    """All of :func:`table_lines` as one bytes object."""
    return b"".join(table_lines(table))


def _use_user_cache() -> None:
    from circuitsim.solver.compiled.cache import relocate_caches

    relocate_caches([__name__])


_on_numba = _use_user_cache  # run by jit.use_numba when the library was in use
if not library_in_use():
    _use_user_cache()
