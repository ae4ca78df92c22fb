"""ctdrill.safeio: regular files only, bounded size, bounded JSON nesting and numbers."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from ctdrill.safeio import json_nesting_depth, load_json, read_bytes_bounded


class Refused(ValueError):
    pass


def test_nesting_depth_ignores_brackets_in_strings() -> None:
    assert json_nesting_depth('{"a": [1, {"b": "[[[{{{\\"]]]"}]}') == 3
    assert json_nesting_depth("1") == 0


def test_reads_a_plain_document(tmp_path: Path) -> None:
    path = tmp_path / "x.json"
    path.write_text('{"a": [1, 2.5, "s"]}', encoding="utf-8")
    assert load_json(path, what="plan", error=Refused) == {"a": [1, 2.5, "s"]}


@pytest.mark.parametrize(
    ("text", "match"),
    [
        ("[" * 1000 + "]" * 1000, "nests arrays/objects 1000 deep"),
        ('{"n": ' + "9" * 5000 + "}", "cannot be read"),
        ('{"n": NaN}', "cannot be read"),
        ('{"n": ', "not valid JSON"),
    ],
)
def test_hostile_documents_are_refused(tmp_path: Path, text: str, match: str) -> None:
    path = tmp_path / "bad.json"
    path.write_text(text, encoding="utf-8")
    with pytest.raises(Refused, match=match):
        load_json(path, what="plan", error=Refused)


def test_non_regular_files_are_refused_without_opening(tmp_path: Path) -> None:
    fifo = tmp_path / "pipe"
    os.mkfifo(fifo)
    with pytest.raises(Refused, match="named pipe"):
        load_json(fifo, what="plan", error=Refused)
    with pytest.raises(Refused, match="device"):
        read_bytes_bounded("/dev/zero", what="mask", error=Refused, max_bytes=10)
    with pytest.raises(Refused, match="folder"):
        load_json(tmp_path, what="plan", error=Refused)
    with pytest.raises(Refused, match="not found"):
        load_json(tmp_path / "nope.json", what="plan", error=Refused)


def test_size_limit(tmp_path: Path) -> None:
    path = tmp_path / "big.json"
    path.write_bytes(b" " * 101)
    with pytest.raises(Refused, match="101 bytes, more than the 100"):
        read_bytes_bounded(path, what="plan", error=Refused, max_bytes=100)


def test_not_utf8(tmp_path: Path) -> None:
    path = tmp_path / "latin.json"
    path.write_bytes(b'{"a": "\\xe9\xe9"}')
    with pytest.raises(Refused, match="not UTF-8"):
        load_json(path, what="plan", error=Refused)
