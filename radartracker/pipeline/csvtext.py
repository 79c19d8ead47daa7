"""CSV rows of numbers and short texts written by one compiled loop, with the bytes Python's ``%``
formatting gives: ``'%.<d>f' % x`` is x rounded to d decimals, correctly (half to even, on the exact
binary value).

A column of floats with ``d`` decimals becomes integers n = rint(p), p = x·10^d, in one compiled pass:
10^d is exact, so p is within half an ulp of the exact product and rint(p) is its correct rounding unless
p lies within an ulp of a half-integer; for those few values the product's exact error (Dekker's
two-product) says on which side of the half the exact product lies (times in steps of 0.5 ms are, at 3
decimals, 1 in 20). The values beyond 2^50 and the non-finite ones ('nan', 'inf', '-inf', or an empty
field for an optional column) are formatted by Python itself and copied as text. The compiled loop
writes, row after row, the sign, the digits of n with the decimal point d places from the right, the
texts and the separators; a second table made of some of the rows and columns (``tracks.csv`` of
``events.csv``) is copied from those rows' fields in the same pass.
The number columns are written into one array as they are added, and only columns with texts have text
positions: a table of 8 192 rows allocates a few MB, and fresh memory costs a page fault per 4 kB.
"""

from __future__ import annotations

import math
import struct
from collections.abc import Callable
from operator import itemgetter

import numpy as np
from numba import njit, uint64

_POW10 = 10 ** np.arange(19, dtype=np.int64)  # the exact powers of ten up to 10^18
_EXACT = 2.0**50  # beyond this |x·10^d| the rounding is left to Python
_TIE = 2.0**-51  # |p|·_TIE bounds twice an ulp of p: nearer a half-integer, the exact product decides
_SPLIT = 2.0**27 + 1  # Veltkamp's splitter: a double into two halves of 26 bits
_DIGITS, _BLANK, _TEXT = 0, 1, 2  # how a number is written
_COLUMNS = 16  # number columns a table makes room for at first (rows of an array never written cost nothing)


class Table:
    """The columns of one CSV table, added in order (:meth:`number`, :meth:`text`), then :meth:`rows`."""

    def __init__(self, n: int) -> None:
        self.n = n
        self._kind: list[int] = []  # 0 number, 1 text, per output column
        # by number column (rows of arrays, filled as added): digits, sign, how written (_DIGITS, ...), decimals
        self._num = np.empty((_COLUMNS, n), np.int64)
        self._neg = np.empty((_COLUMNS, n), np.bool_)
        self._flag = np.empty((_COLUMNS, n), np.int8)
        self._dec: list[int] = []
        self._texts: list[list[str] | None] = []  # each text column; each number column's texts (by row) or None
        self._codes: dict[int, np.ndarray] = {}  # a labels column's row → its distinct text (by column number)
        self._packed: tuple | None = None  # the texts in one buffer (_pack), made by the first rows()

    def _next(self) -> int:
        """The row of the next number column in the number arrays (grown when full)."""
        k = len(self._dec)
        if k == len(self._num):
            self._num, self._neg, self._flag = (np.concatenate([a, np.empty_like(a)]) for a in
                                                (self._num, self._neg, self._flag))
        return k

    def number(self, x, decimals: int, *, optional: bool = False) -> Table:
        """A column of numbers written as ``'%.<decimals>f' % x``; ``optional``: empty where not finite."""
        x = np.ascontiguousarray(x, float).reshape(self.n)
        k = self._next()
        flag = self._flag[k]
        _digits(x, float(_POW10[decimals]), self._num[k], self._neg[k], flag)
        slow = np.flatnonzero(flag).tolist()
        texts = [""] * self.n if slow else None
        for i in slow:
            v = float(x[i])
            if optional and not math.isfinite(v):
                flag[i] = _BLANK
            else:
                texts[i] = "%.*f" % (decimals, v)
        self._kind.append(0)
        self._dec.append(decimals)
        self._texts.append(texts)
        return self

    def integer(self, x) -> Table:
        """A column of integers (``'%d'``), written exactly."""
        x = np.asarray(x, np.int64)
        k = self._next()
        np.abs(x, out=self._num[k])
        np.less(x, 0, out=self._neg[k])
        self._flag[k] = _DIGITS
        self._kind.append(0)
        self._dec.append(0)
        self._texts.append(None)
        return self

    def text(self, values: list[str]) -> Table:
        """A column of texts, written as they are (the caller makes them strings)."""
        self._kind.append(1)
        self._texts.append(values)
        return self

    def labels(self, values: list, text: Callable[[object], str] = str) -> Table:
        """A column of values that repeat (hashable), each written as ``text(value)``: the texts are made
        once per distinct value (equal values are written alike, as the first of them)."""
        index: dict = {v: i for i, v in enumerate(dict.fromkeys(values))}
        # the rows' codes by one itemgetter call and one struct.pack (faster than map and np.fromiter)
        codes = itemgetter(*values)(index) if len(values) > 1 else [index[v] for v in values]
        self._codes[len(self._kind)] = np.frombuffer(struct.pack(f"{len(codes)}q", *codes), np.int64).reshape(self.n)
        return self.text([text(v) for v in index])

    def _arrays(self) -> tuple:
        """What the compiled loop reads: each column's kind, its row in the number arrays and in the text
        positions, the number arrays (digits, sign, how written, decimals) and the texts (start, end,
        UTF-8 buffer)."""
        kinds = np.array(self._kind, np.int64)
        index = np.cumsum(kinds == 0) - 1  # a number column's row in num, neg, flag and dec
        has_text = np.array([t is not None for t in self._texts], np.bool_)
        text_row = np.cumsum(has_text) - 1  # a column's row in start and end (if it has texts)
        if self._packed is None:
            self._packed = _pack([t for t in self._texts if t is not None], self.n,
                                 {int(text_row[c]): rows for c, rows in self._codes.items()})
        k = len(self._dec)
        return (kinds, index, text_row, self._num[:k], self._neg[:k], self._flag[:k], np.array(self._dec, np.int64),
                _POW10, *self._packed)

    def _size(self, select: np.ndarray | slice, columns: np.ndarray) -> int:
        """Bytes enough for the rows ``select`` of the columns ``columns`` (after :meth:`_arrays`): each field
        as often as the most repeated column (a number's at most 24: sign, 19 digits, point; a text's own
        bytes), and the separators."""
        start, end, _ = self._packed
        rows = len(range(self.n)[select]) if isinstance(select, slice) else len(select)
        fields = rows * 24 * len(self._dec) + int((end[:, select] - start[:, select]).sum())
        return _repeats(columns) * fields + rows * len(columns)

    def rows(self, select: np.ndarray | None = None, columns: list[int] | None = None) -> str:
        """The rows ``select`` (all by default; each row ended by a newline) of the columns ``columns``
        (all by default, else their numbers in the order added)."""
        select = np.arange(self.n) if select is None else np.asarray(select, np.int64)
        if not len(select):
            return ""
        cols = np.arange(len(self._kind)) if columns is None else np.asarray(columns, np.int64)
        arrays = self._arrays()
        out = np.empty(self._size(select, cols), np.uint8)
        used, _ = _write(cols, *arrays, select, out, _runs(cols[:0]), np.zeros(self.n, np.bool_), out[:0])
        return out[:used].tobytes().decode("utf-8")

    def rows_and_part(self, mask: np.ndarray, columns: list[int]) -> tuple[memoryview, memoryview]:
        """Every row, and the rows where ``mask`` is true of the columns ``columns`` (as ``rows()`` and
        ``rows(np.flatnonzero(mask), columns)``, UTF-8 encoded: views of the buffers written, not copied),
        in one pass: the part's fields are copied from the rows just written."""
        if not self.n:
            return memoryview(b""), memoryview(b"")
        mask = np.asarray(mask, np.bool_).reshape(self.n)
        cols = np.asarray(columns, np.int64)
        arrays = self._arrays()
        out = np.empty(self._size(slice(None), np.arange(len(self._kind))), np.uint8)
        # a part's row (its fields, each from the row, and fewer separators, each column at most r times) is no
        # longer than r rows: a bound without summing the part's texts (pages never written cost nothing)
        part = np.empty(_repeats(cols) * len(out), np.uint8)
        used, used_part = _write(np.arange(len(self._kind)), *arrays, np.arange(self.n), out, _runs(cols), mask, part)
        return out[:used].data, part[:used_part].data


def _runs(columns: np.ndarray) -> np.ndarray:
    """``columns`` (field numbers) as runs of consecutive ones, each run's first and last ((m, 2)): a run of
    fields is copied, with its commas, as one slice."""
    if not len(columns):
        return np.zeros((0, 2), np.int64)
    cut = np.flatnonzero(np.diff(columns) != 1) + 1
    return np.stack([columns[np.r_[0, cut]], columns[np.r_[cut - 1, len(columns) - 1]]], axis=1)


def _repeats(columns: np.ndarray) -> int:
    """How often the most repeated of ``columns`` (column numbers) is taken (1 if none)."""
    return int(np.bincount(columns).max()) if len(columns) else 1


def _pack(columns: list[list[str]], n: int, codes: dict[int, np.ndarray]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The texts of the columns in one UTF-8 buffer, with each one's start and end by row (a labels
    column: its distinct texts, ``codes`` the row's).

    A column is encoded in one call, its texts joined by newlines (a byte no multi-byte UTF-8 character
    contains), unless one of them holds a newline itself."""
    start = np.zeros((len(columns), n), np.int64)
    end = np.zeros((len(columns), n), np.int64)
    parts, offset = [], 0
    for c, col in enumerate(columns):
        if not n:
            continue
        m = len(col)
        first, last = np.zeros(m, np.int64), np.zeros(m, np.int64)
        data = "\n".join(col).encode("utf-8")
        cuts = np.flatnonzero(np.frombuffer(data, np.uint8) == 10)
        if len(cuts) == m - 1:
            first[1:], last[:-1], last[-1] = cuts + 1, cuts, len(data)
        else:
            lengths = np.array([len(t.encode("utf-8")) for t in col], np.int64)
            last[:] = np.cumsum(lengths)
            first[:] = last - lengths
            data = "".join(col).encode("utf-8")
        rows = codes.get(c)
        start[c], end[c] = (first, last) if rows is None else (first[rows], last[rows])
        start[c] += offset
        end[c] += offset
        offset += len(data)
        parts.append(data)
    return start, end, np.frombuffer(b"".join(parts), np.uint8)


@njit(cache=True)
def _digits(x, scale, num, neg, flag):  # pragma: no cover (compiled)
    """For each x: n = |x|·scale rounded to an integer, half to even, on the exact product, into ``num``, the
    sign bit into ``neg``, and into ``flag`` _DIGITS, or _TEXT where Python formats it instead (0 in ``num``):
    not finite or beyond 2^50. n = rint(p), p = |x|·scale rounded, unless p is within p·2^-51 of a
    half-integer h, which holds every p within 2 ulp of one (an ulp of p is at most p·2^-52): then the side of
    h the exact product lies on is the sign of (p - h) + e, e = |x|·scale - p exactly (:func:`_product_error`),
    p - h exact (p and h are within a factor 2)."""
    for i in range(len(x)):
        v = x[i]
        a = abs(v)
        p = a * scale
        neg[i] = math.copysign(1.0, v) < 0.0
        if p < _EXACT:  # not NaN either
            f = math.floor(p)
            h = f + 0.5
            if abs(p - h) > p * _TIE:
                num[i] = np.int64(np.rint(p))
            else:
                s = (p - h) + _product_error(a, scale, p)
                num[i] = np.int64(f) + np.int64(s > 0.0 or (s == 0.0 and f % 2.0 == 1.0))
            flag[i] = 0  # _DIGITS
        else:
            num[i] = 0
            flag[i] = 2  # _TEXT


@njit(cache=True)
def _product_error(a, b, p):  # pragma: no cover (compiled)
    """a·b - p exactly, p = a·b rounded (Dekker's two-product: a and b split into halves of 26 bits whose
    products are exact; no overflow for a·b < 2^50, no underflow for a·b above 1/2 and b ≤ 10^18)."""
    c = _SPLIT * a
    ah = c - (c - a)
    al = a - ah
    c = _SPLIT * b
    bh = c - (c - b)
    bl = b - bh
    return ((ah * bh - p) + ah * bl + al * bh) + al * bl


@njit(cache=True)
def _write(cols, kinds, index, text_row, num, neg, flag, dec, pow10, start, end, buf, select, out, part_runs,
           in_part, part):  # pragma: no cover (compiled)
    """Write rows ``select`` of columns ``cols`` into ``out`` and, of those rows r with ``in_part[r]``, the
    fields ``part_runs`` (runs of consecutive fields, first and last, numbers in ``cols``: :func:`_runs`) into
    ``part``, copied; returns the bytes written into each."""
    pos = 0
    used = 0
    first = np.empty(len(cols), np.int64)  # where each field of the row starts and ends in out
    last = np.empty(len(cols), np.int64)
    for r in select:
        for i in range(len(cols)):
            c = cols[i]
            if i:
                out[pos] = 44  # ,
                pos += 1
            first[i] = pos
            k = index[c]
            if kinds[c] == 0 and flag[k, r] == 0:  # _DIGITS
                if neg[k, r]:
                    out[pos] = 45  # -
                    pos += 1
                v = uint64(num[k, r])  # unsigned: // 10 without the floor division's sign fix-ups
                d = dec[k]
                m = d + 1  # digits written: at least one before the point
                while m < 19 and v >= uint64(pow10[m]):
                    m += 1
                pos += m
                if d > 0:
                    pos += 1
                j = pos - 1
                for q in range(m):
                    if q == d and d > 0:
                        out[j] = 46  # .
                        j -= 1
                    w = v // uint64(10)
                    out[j] = uint64(48) + v - uint64(10) * w
                    v = w
                    j -= 1
            elif kinds[c] == 1 or flag[k, r] == 2:  # a text, or a number's _TEXT (nothing for _BLANK)
                t = text_row[c]
                for j in range(start[t, r], end[t, r]):
                    out[pos] = buf[j]
                    pos += 1
            last[i] = pos
        out[pos] = 10  # newline
        pos += 1
        if in_part[r]:
            for i in range(len(part_runs)):
                if i:
                    part[used] = 44
                    used += 1
                a, b = first[part_runs[i, 0]], last[part_runs[i, 1]]  # fields a run apart, with their commas
                part[used:used + b - a] = out[a:b]
                used += b - a
            part[used] = 10
            used += 1
    return pos, used

