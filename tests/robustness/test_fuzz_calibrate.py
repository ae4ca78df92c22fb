"""Fuzz ``ctdrill calibrate``'s inputs: a manifest and six slave-robot recordings (CSV).

The seed recordings follow the pine-wood law exactly (A0 with Ke, 30 and 60 Hz harmonics at
900 rpm, 2 blades) at three HU and two feeds. One file is damaged (a cell replaced by a hostile
value, a row duplicated or dropped, bytes flipped, inserted, deleted or cut off); the fit must
give a finite calibration set that loads back, or raise the package's ``ModelInputError``.
"""

from __future__ import annotations

import functools
import json
import math
import tempfile
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from tests.robustness.fuzz import (
    EXAMPLE_LIMIT_S,
    FUZZ_TIMEOUT_S,
    byte_mutations,
    fuzz_settings,
    timed,
)
from tests.robustness.mutate import ByteMutation, apply_bytes, bounded_memory, finite_numbers
from tests.robustness.test_found_bugs import known_bug

pytestmark = [pytest.mark.fuzz, pytest.mark.timeout(FUZZ_TIMEOUT_S)]

RPM, BLADES = 900.0, 2
HOSTILE_CELLS = ("", "nan", "inf", "-inf", "1e400", "-0", "abc", "1,5", "0x10", " ", "1e-320")


@functools.cache
def seed_files() -> dict[str, str]:
    """File name -> CSV text: ``manifest.csv`` and six recordings (1 kHz, depth 0..9 mm)."""
    from ctdrill.model import load_calibration
    from ctdrill.model.force import a0_n, bk_n

    cal = load_calibration("pine-wood-paper")
    freqs = [h.order * BLADES * RPM / 60.0 for h in cal.harmonics]
    files = {}
    manifest = ["file,hu,feed_mm_s"]
    for hu in (-700.0, -600.0, -500.0):
        for feed in (2.0, 4.0):
            name = f"rec_{int(-hu)}_{int(feed)}.csv"
            t = np.arange(0.0, 9.0 / feed, 1e-3)
            a0 = float(a0_n(np.array(hu), feed, cal))
            bk = bk_n(np.array(hu), cal)
            force = np.full(t.shape, a0)
            for b, f in zip(bk, freqs, strict=True):
                force += float(b) * np.sin(2 * math.pi * f * t)
            rows = ["time_s,position_mm,force_n"]
            rows += [f"{ti:.4f},{feed * ti:.5f},{fi:.6f}" for ti, fi in zip(t, force, strict=True)]
            files[name] = "\n".join(rows) + "\n"
            manifest.append(f"{name},{hu:g},{feed:g}")
    files["manifest.csv"] = "\n".join(manifest) + "\n"
    return files


def fit(files: dict[str, str]) -> str:
    """Run the calibration on ``files``; "ok", "refuse" or a known bug's key."""
    from ctdrill.model import ModelInputError, load_calibration
    from ctdrill.model.fit import calibrate_from_manifest, fit_document

    with tempfile.TemporaryDirectory() as tmp:
        for name, text in files.items():
            (Path(tmp) / name).write_bytes(text.encode("utf-8", "surrogateescape"))
        try:
            with bounded_memory():
                result = timed(
                    EXAMPLE_LIMIT_S,
                    lambda: calibrate_from_manifest(
                        Path(tmp) / "manifest.csv", rpm=RPM, blades=BLADES
                    ),
                )
        except ModelInputError as exc:
            assert str(exc).strip() and "\n" not in str(exc).strip(), repr(str(exc))
            return "refuse"
        except Exception as exc:
            key = known_bug(exc)
            if key is None:
                raise
            return key
        doc = fit_document(result)
        assert finite_numbers(doc), doc
        out = Path(tmp) / "fitted.json"
        out.write_text(json.dumps(doc, allow_nan=False))
        try:
            load_calibration(out)  # what calibrate writes must load back
        except ModelInputError as exc:
            key = known_bug(exc)
            if key is None:
                raise
            return key
    return "ok"


def test_seed_recordings_recover_the_law() -> None:
    """Unmutated, the fit recovers the pine-wood exponent (the fuzzing starts from valid data)."""
    from ctdrill.model.fit import calibrate_from_manifest

    with tempfile.TemporaryDirectory() as tmp:
        for name, text in seed_files().items():
            (Path(tmp) / name).write_text(text)
        result = calibrate_from_manifest(Path(tmp) / "manifest.csv", rpm=RPM, blades=BLADES)
    assert result.calibration.a0.n == pytest.approx(0.77, abs=0.02)
    assert result.calibration.ke_per_mm_s == pytest.approx(0.25, abs=0.02)


@st.composite
def damaged(draw: st.DrawFn) -> dict[str, str]:
    files = dict(seed_files())
    name = draw(st.sampled_from(sorted(files)))
    lines = files[name].split("\n")
    kind = draw(st.sampled_from(["cell", "row", "bytes"]))
    if kind == "cell":
        r = draw(st.integers(0, len(lines) - 2))
        cells = lines[r].split(",")
        c = draw(st.integers(0, len(cells) - 1))
        cells[c] = draw(st.sampled_from(HOSTILE_CELLS) | st.text(max_size=6))
        lines[r] = ",".join(cells)
        files[name] = "\n".join(lines)
    elif kind == "row":
        r = draw(st.integers(1, len(lines) - 2))
        if draw(st.booleans()):
            lines.insert(r, lines[r])  # a repeated sample: time not strictly increasing
        else:
            del lines[r]
        files[name] = "\n".join(lines)
    else:
        mutations: list[ByteMutation] = draw(byte_mutations())
        data = files[name].encode()
        for m in mutations:
            data = apply_bytes(data, m, [])
        files[name] = data.decode("utf-8", "surrogateescape")
    return files


@fuzz_settings
@given(files=damaged())
def test_fuzz_calibrate_inputs(files: dict[str, str]) -> None:
    fit(files)
