"""Plan settings written as ``key=value`` words in a Slicer control point's description.

3D Slicer keeps a control point's ``description`` through load and save, but drops a markup's
own ``name``, ``description`` and ``attributes`` when it writes a ``.mrk.json``. So ctdrill
stores a markup's settings in its first control point's description::

    name="IAN canal" radius_mm=1.5 margin_mm=2.5

A value is either a bare word or a JSON string in double quotes (for names with spaces). Words
without ``=`` are free text and ignored; a ``key=value`` whose key is not a setting of that
markup is refused (a misspelt key must not be silently dropped), and so is a key given twice
in one description (``radius_mm=1.2 radius_mm=0.01``: which one was meant is not known, so
neither is taken).
"""

from __future__ import annotations

import json
import re
from typing import Any

from ctdrill.numtext import ascii_number

#: ``key=value``: key a word, value a JSON string ("...", escapes allowed) or a bare word.
_SETTING = re.compile(r'(?<![\w"=])([A-Za-z_][A-Za-z0-9_]*)=("(?:[^"\\]|\\.)*"|[^\s,;]*)')
#: Settings whose value is text, never a number.
TEXT_KEYS = frozenset(
    {
        "name",
        "calibration",
        "series",
        "series_uid_sha256",
        "drills",
        "implant",
        "implant_apex",
        "implant_drills",
    }
)


class SettingsSyntaxError(ValueError):
    """A ``key=value`` word whose quoted value is not a valid JSON string, or a key given
    twice."""


def parse_settings(text: str) -> dict[str, Any]:
    """The ``key=value`` settings in ``text`` (numbers as float, text keys as str).

    Raises
    ------
    SettingsSyntaxError
        A quoted value that is not a valid JSON string, or a key given twice.
    """
    out: dict[str, Any] = {}
    raws: dict[str, str] = {}
    for match in _SETTING.finditer(text):
        key, raw = match.group(1), match.group(2)
        if key in raws:
            raise SettingsSyntaxError(
                f"{key} is given twice ({key}={raws[key]}, then {key}={raw}); keep the one you mean"
            )
        raws[key] = raw
        value: Any
        if raw.startswith('"'):
            try:
                value = json.loads(raw)
            except json.JSONDecodeError as exc:
                raise SettingsSyntaxError(f"{key}={raw} is not a quoted string") from exc
        elif key in TEXT_KEYS:
            value = raw
        else:  # ASCII digits only (float also reads "١.٢"): the same rule everywhere
            number = ascii_number(raw)
            value = raw if number is None else number
        out[key] = value
    return out


def free_text(text: str) -> str:
    """``text`` without its ``key=value`` settings: the free words (Slicer roles, notes)."""
    return _SETTING.sub(" ", text)


def format_settings(settings: dict[str, Any]) -> str:
    """``key=value`` words, in the given order; text quoted as JSON, numbers exactly (repr)."""
    words = []
    for key, value in settings.items():
        if isinstance(value, str):
            words.append(f"{key}={json.dumps(value, ensure_ascii=False)}")
        elif isinstance(value, bool):
            raise TypeError(f"setting {key}: bool is not a setting value")
        elif isinstance(value, int):
            words.append(f"{key}={value}")
        else:
            words.append(f"{key}={float(value)!r}")
    return " ".join(words)
