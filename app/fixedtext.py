"""Fixed-point text of float columns, vectorised, byte-identical to Python's ``"%.Nf" % v``.

``force.csv`` holds one row per millisecond of drilling (27 000 rows for the demo): formatting
it one float at a time cost about 100 ms (issue 17). Here each column is turned into digits
with integer arithmetic on whole arrays and the rows are assembled as one byte matrix.

Exactness. Python's ``%.Nf`` is the decimal of the exact binary value rounded to N digits,
half to even. With ``p = |v| * 10**N`` computed in float64, the error of ``p`` is at most
half an ulp (``p * 2**-53``), and rounding to the nearest integer depends only on which side
of ``k + 1/2`` the exact value lies; so wherever ``frac(p)`` is further than ``p * 2**-52``
from 1/2 (and ``p < 2**52``, where every step is exact) the rounded integer is known. The
few other values (near ties, huge values, ``inf``, ``nan``) are formatted by Python itself.
The sign is the sign bit, as Python writes it (``-0.000000`` for ``-1e-9`` and ``-0.0``).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ctdrill.app.csv_cells import csv_row

#: Rows formatted at once: every temporary stays small (in cache, below malloc's mmap
#: threshold, so no page faults).
_CHUNK_ROWS = 1 << 12
_MAX_DIGITS = 15
_EXACT_LIMIT = float(2**52)
_POW10 = np.array([10**k for k in range(19)], dtype=np.int64)
#: "00" .. "99" as ASCII pairs.
_PAIRS16 = (
    np.array([[48 + k // 10, 48 + k % 10] for k in range(100)], dtype=np.uint8)
    .view(np.uint16)
    .ravel()
)


def fixed(values: np.ndarray, digits: int) -> list[str]:
    """``["%.{digits}f" % v for v in values]``, the reference this module must equal."""
    return [f"%.{digits}f" % v for v in np.asarray(values, dtype=np.float64).tolist()]


def _field(values: np.ndarray, digits: int) -> tuple[np.ndarray, np.ndarray]:
    """Right-aligned characters (N, W) uint8 of one column and each text's length (N,)."""
    v = np.asarray(values, dtype=np.float64)
    n = v.shape[0]
    with np.errstate(invalid="ignore", over="ignore"):
        p = np.abs(v) * float(10**digits)
        q = np.floor(p)
        frac = p - q
        ok = np.isfinite(p) & (p < _EXACT_LIMIT) & (np.abs(frac - 0.5) > p * 2.0**-52)
    rounded = np.where(ok, q + (frac > 0.5), 0.0).astype(np.int64)
    int_part = rounded // _POW10[digits]
    frac_part = rounded - int_part * _POW10[digits]
    n_int = 1 + np.searchsorted(_POW10[1:], int_part, side="right")
    sign = np.signbit(v) & ok
    length = sign + n_int + (digits + 1 if digits else 0)
    fallback = np.flatnonzero(~ok)
    texts = [(f"%.{digits}f" % x).encode("ascii") for x in v[fallback].tolist()]
    width = max([int(length.max()) if n else 1, *(len(t) for t in texts)])
    wi = int(n_int.max()) if n else 1
    chars = np.full((n, width), ord("0"), dtype=np.uint8)
    end = width
    if digits:
        chars[:, width - digits :] = _digits(frac_part, digits)
        end = width - digits - 1
        chars[:, end] = ord(".")
    chars[:, end - wi : end] = _digits(int_part, wi)
    rows_neg = np.flatnonzero(sign)
    chars[rows_neg, width - length[rows_neg]] = ord("-")
    for row, raw in zip(fallback.tolist(), texts, strict=True):
        chars[row, width - len(raw) :] = np.frombuffer(raw, dtype=np.uint8)
        length[row] = len(raw)
    return chars, length


def _digits(values: np.ndarray, width: int) -> np.ndarray:
    """ASCII decimal digits (N, width) of non-negative int64 integers, zero-padded (the
    leading digits beyond ``width`` dropped): two digits at a time, by division by the
    scalar 100 (which NumPy vectorises) and a 100-entry table of digit pairs."""
    pairs = (width + 1) // 2
    out = np.empty((pairs, values.shape[0]), dtype=np.uint16)
    x = values
    for j in range(pairs - 1, -1, -1):
        high = x // 100
        out[j] = _PAIRS16.take(x - 100 * high)
        x = high
    chars = np.ascontiguousarray(out.T).view(np.uint8)
    return chars[:, 2 * pairs - width :]


def csv_cell(text: str) -> str:
    """One text cell as :mod:`ctdrill.app.csv_cells` writes it (neutralised when it starts
    like a formula; quoted when it holds a comma, quote or newline)."""
    return csv_row([text], text=True)[:-1]


def fixed_csv(
    header: Sequence[str], columns: Sequence[tuple[np.ndarray, int]], tail: str | None = None
) -> str:
    """CSV text: the header, then one row per element of the columns.

    Each column is (values, digits) written as ``"%.{digits}f"``; ``tail`` is one more cell,
    the same on every row (e.g. the calibration's name), omitted when empty. Equal to
    ``csv.writer`` over the Python-formatted strings, byte for byte (the header and ``tail``
    through the one CSV writer, :func:`ctdrill.app.csv_cells.csv_row`).
    """
    if not columns:
        raise ValueError("fixed_csv needs at least one column")
    for _, digits in columns:
        if not 0 <= digits <= _MAX_DIGITS:
            raise ValueError(f"digits must be 0..{_MAX_DIGITS}, got {digits}")
    n = {np.asarray(values).shape[0] for values, _ in columns}
    if len(n) != 1:
        raise ValueError(f"columns differ in length: {sorted(n)}")
    rows = n.pop()
    head = csv_row(header, text=True)
    # a lone empty field is written "" by csv; among others it is written empty
    cell = "" if tail is None else "," + (csv_cell(tail) if tail else "")
    end = np.frombuffer(cell.encode("utf-8") + b"\n", np.uint8)
    parts = [head.encode("utf-8")]
    for start in range(0, rows, _CHUNK_ROWS):
        stop = min(rows, start + _CHUNK_ROWS)
        fields = [_field(np.asarray(values)[start:stop], digits) for values, digits in columns]
        total = sum(chars.shape[1] for chars, _ in fields) + len(fields) - 1 + end.shape[0]
        out = np.empty((stop - start, total), dtype=np.uint8)
        keep = np.ones((stop - start, total), dtype=bool)
        at = 0
        for i, (chars, length) in enumerate(fields):
            if i:
                out[:, at] = ord(",")
                at += 1
            w = chars.shape[1]
            out[:, at : at + w] = chars
            keep[:, at : at + w] = np.arange(w) >= (w - length)[:, None]
            at += w
        out[:, at:] = end
        parts.append(out[keep].tobytes())
    return b"".join(parts).decode("utf-8")
