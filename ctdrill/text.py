"""Text as every output writes it."""

from __future__ import annotations


def printable(text: str) -> str:
    """``text`` as valid Unicode for a record or a plot: undecodable bytes of a file name
    (``\\udcff`` from Python's surrogateescape) and lone surrogates become U+FFFD.

    A plan file named with bytes that are not UTF-8 made matplotlib fail on the plot title
    and UTF-8 writers fail on the name; the replacement character says "a byte was here".
    """
    try:
        raw = text.encode("utf-8", "surrogateescape")
    except UnicodeEncodeError:  # a lone surrogate from a JSON escape such as "\\ud800"
        return "".join("\ufffd" if "\ud800" <= c <= "\udfff" else c for c in text)
    return raw.decode("utf-8", "replace")
