"""Numbers in messages: short, exact where short, never hundreds of digits.

A value a user typed (``feed_mm_s`` 1e-300) can make a computed one enormous (1.08e+304
samples); Python prints such an ``int`` with every digit. :func:`number_text` is how every
``error:`` and warning line writes a number it computed or was given: up to ``digits``
significant digits, exponent form when needed, ``inf``/``nan`` as such. Belongs to no room:
``imaging``, ``model``, ``haptics`` and ``app`` all use it.
"""

from __future__ import annotations

import math

#: Integers up to this many digits are written whole (a sample count, a file size).
MAX_WHOLE_DIGITS = 15


def number_text(value: float | int, digits: int = 6) -> str:
    """``value`` for a message: ``0.4``, ``1e-300``, ``1.08e+304``, ``50000000``, ``inf``.

    Parameters
    ----------
    value : a float or an int (a bool is written ``True``/``False``).
    digits : significant digits kept for floats and for integers too long to write whole.
    """
    if isinstance(value, bool):
        return str(value)
    if isinstance(value, int):
        if abs(value) < 10**MAX_WHOLE_DIGITS:
            return str(value)
        try:
            whole = str(abs(value))
        except ValueError:  # beyond the interpreter's digit limit: its size is what matters
            return f"{'-' if value < 0 else ''}about 1e+{int(value.bit_length() * math.log10(2))}"
        lead = whole[:digits].rstrip("0")
        mantissa = lead[0] + ("." + lead[1:] if len(lead) > 1 else "")
        return f"{'-' if value < 0 else ''}{mantissa}e+{len(whole) - 1:02d}"
    x = float(value)
    if math.isnan(x):
        return "nan"
    if math.isinf(x):
        return "inf" if x > 0 else "-inf"
    return f"{x:.{digits}g}"


def ascii_whole(text: str, *, max_digits: int = 18) -> int | None:
    """The whole number ``text`` spells in ASCII digits (``0`` .. ``9``, at most
    ``max_digits``), else None.

    ``str.isdigit`` is true for ``²`` and ``٣`` as well; ``int`` refuses the first (a
    traceback where a message was due) and reads the second: what a user typed is read as
    ASCII or refused, the same way everywhere.
    """
    t = text.strip()
    if not t or len(t) > max_digits or not (t.isascii() and t.isdigit()):
        return None
    return int(t)


def ascii_number(text: str) -> float | None:
    """The float ``text`` spells in ASCII (``1.5``, ``-2e-3``, ``inf``), else None (``float``
    also reads ``١.٥`` and full-width digits, which no field of ctdrill means)."""
    t = text.strip()
    if not t.isascii():
        return None
    try:
        return float(t)
    except ValueError:
        return None
