"""JSON for frozen dataclasses: each field is written once, as the type declares it.

A record's JSON keys are its field names, in field order; field metadata may rename a key
(:func:`key`), flatten a nested record into its parent (:func:`flat`) or leave a key out when
its value is None or empty (:func:`optional`). :func:`to_json` writes a record, :func:`from_json`
reads one back from the types of its fields (records, tuples of them, ``X | None``, numbers,
strings, booleans, and plain JSON mappings). So the key lists of an output are never written
twice: the record's fields are the list.
"""

from __future__ import annotations

import dataclasses
import types
import typing
from collections.abc import Mapping
from typing import Any, TypeVar, Union, get_args, get_origin

T = TypeVar("T")


def key(name: str) -> dict[str, Any]:
    """Field metadata: the field's JSON key is ``name``."""
    return {"json_key": name}


def flat() -> dict[str, Any]:
    """Field metadata: the nested record's keys are written into its parent's."""
    return {"json_flat": True}


def optional() -> dict[str, Any]:
    """Field metadata: the key is left out when the value is None or empty."""
    return {"json_optional": True}


def added(absent: Any = None) -> dict[str, Any]:
    """Field metadata: a key later versions added (always written); a document written before
    it reads as ``absent`` (a batch resumed over older row folders, an older summary read)."""
    return {"json_absent": absent}


def _encode(value: Any) -> Any:
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return to_json(value)
    if isinstance(value, tuple | list):
        return [_encode(v) for v in value]
    if isinstance(value, Mapping):
        return {str(k): _encode(v) for k, v in value.items()}
    return value


def to_json(record: Any) -> dict[str, Any]:
    """``record`` (a dataclass instance) as a JSON object, keys in field order."""
    out: dict[str, Any] = {}
    for f in dataclasses.fields(record):
        value = getattr(record, f.name)
        if f.metadata.get("json_optional") and (value is None or value == ()):
            continue
        if f.metadata.get("json_flat"):
            out.update(to_json(value))
            continue
        out[f.metadata.get("json_key", f.name)] = _encode(value)
    return out


_HINTS: dict[type, dict[str, Any]] = {}


def _hints(cls: type) -> dict[str, Any]:
    if cls not in _HINTS:
        _HINTS[cls] = typing.get_type_hints(cls)
    return _HINTS[cls]


def _decode(tp: Any, value: Any) -> Any:
    origin = get_origin(tp)
    if origin in (Union, types.UnionType):
        options = get_args(tp)
        if value is None and type(None) in options:
            return None
        for option in options:
            if option is not type(None):
                return _decode(option, value)
    if origin is tuple:
        inner = get_args(tp)[0]
        return tuple(_decode(inner, v) for v in value)
    if isinstance(tp, type) and dataclasses.is_dataclass(tp):
        return from_json(tp, value)
    if tp is float and isinstance(value, int | float):
        return float(value)
    if origin in (dict, Mapping) or tp is Any:
        return value
    return value


def from_json(cls: type[T], doc: Mapping[str, Any]) -> T:
    """The ``cls`` record (a dataclass) written as ``doc`` by :func:`to_json`.

    Raises
    ------
    KeyError
        A key the record needs is missing.
    """
    hints = _hints(cls)
    values: dict[str, Any] = {}
    for f in dataclasses.fields(cls):  # type: ignore[arg-type]
        tp = hints[f.name]
        if f.metadata.get("json_flat"):
            values[f.name] = from_json(tp, doc)
            continue
        name = f.metadata.get("json_key", f.name)
        if name not in doc and "json_absent" in f.metadata:
            values[f.name] = f.metadata["json_absent"]
            continue
        if name not in doc and f.metadata.get("json_optional"):
            origin = get_origin(tp)
            values[f.name] = () if origin is tuple else None
            continue
        values[f.name] = _decode(tp, doc[name])
    return cls(**values)
