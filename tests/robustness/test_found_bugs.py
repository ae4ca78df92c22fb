"""Open bugs found by the robustness tests, each a failing test until fixed (docs/robustness.md).

``KNOWN_BUGS`` lists the signature (exception type and the project function it escapes from) of
each open bug whose trigger the fuzzers keep hitting: the fuzz tests tolerate exactly these and
fail on anything new, while a test here pins each one with its minimal input. ``BUG_CASES`` are
corpus cases whose outcome is wrong; ``test_corpus.py`` leaves them to a test here.

Fixed bugs move to ``test_regressions.py`` with their minimal inputs.
"""

from __future__ import annotations

import traceback
from dataclasses import dataclass
from pathlib import Path

import pytest

from tests.robustness.make_corpus import ROOT


@dataclass(frozen=True)
class KnownBug:
    """A reported bug: ``exc_type`` escaping from ``function`` (``*``: any) in ``module_path``."""

    key: str
    exc_type: type[BaseException]
    module_path: str
    function: str


@dataclass(frozen=True)
class Finding:
    """One bug found by these tests (the record docs/robustness.md lists)."""

    key: str
    component: str
    trigger: str
    symptom: str
    status: str  # "open" or "fixed"
    found_by: str


FINDINGS: tuple[Finding, ...] = (
    Finding("plan-int-overflow", "imaging/plan.py", "an integer 10**400 in entry_mm or margin_mm",
            "OverflowError from math.isfinite", "fixed", "JSON fuzz"),
    Finding("plan-kind-unhashable", "imaging/plan.py", '"kind": ["canal"] on a landmark',
            "TypeError: unhashable type: 'list'", "fixed", "JSON fuzz"),
    Finding("calibration-int-overflow", "model/calibration.py", "an integer 10**400 in any field",
            "OverflowError from float()", "fixed", "JSON fuzz"),
    Finding("calibration-law-unbounded", "model/calibration.py",
            "a0.b0 = 400, a0.n = 500 or a0.ke = 1e308",
            "accepted; then A0 = inf or OverflowError at every HU", "fixed", "JSON fuzz"),
    Finding("dicom-header-unbounded-read", "imaging/discovery.py",
            "a header element declaring 4294967280 bytes",
            "pydicom allocates it: MemoryError under RLIMIT_AS", "fixed", "DICOM fuzz, corpus"),
    Finding("dicom-private-transfer-syntax", "imaging/pixels.py",
            "TransferSyntaxUID 1.2.840.12008.1.2.1 (one bit off)",
            "ValueError: UID is not a transfer syntax", "fixed", "DICOM fuzz, corpus"),
    Finding("dicom-unknown-vr", "imaging/discovery.py", "SliceThickness with VR bytes 'D['",
            "NotImplementedError: Unknown Value Representation", "fixed", "DICOM fuzz, corpus"),
    Finding("dicom-bytes-length", "imaging/discovery.py",
            "4 zero bytes inserted in the TransferSyntaxUID value",
            "pydicom BytesLengthException escapes", "fixed", "DICOM fuzz"),
    Finding("zero-rescale-slope", "imaging loader", "RescaleSlope 0",
            "loaded silently: every voxel = intercept", "fixed", "corpus"),
    Finding("number-of-frames-bomb", "imaging loader", "NumberOfFrames 2147483647, one frame",
            "loaded one slice silently", "fixed", "corpus"),
    Finding("pixel-length-bomb", "imaging loader", "PixelData declaring 4294967280 bytes in 1 kB",
            "loaded silently (an incomplete copy)", "fixed", "corpus"),
    Finding("cli-warnings-on-stderr", "app/cli.py + loader",
            "a junk file beside a series; a non-finite position",
            "pydicom/NumPy warnings before the error: line", "fixed", "corpus (subprocess)"),
    Finding("inf-position-message", "imaging loader", "ImagePositionPatient inf\\0\\0",
            "error names neither file nor tag", "fixed", "corpus"),
    Finding("manifest-nul-path", "model/recordings.py", "a NUL byte in a manifest's file name",
            "ValueError: embedded null byte from open(): calibrate exits 1", "fixed",
            "calibrate fuzz"),
    Finding("calibrate-unloadable-fit", "model/fit.py + app/commands/calibrate.py",
            "the 4 mm/s recordings' force in mN (x1000), the rest in N",
            "fit gives Ke = 102696 per mm/s; calibrate writes OUT.json, then refuses to load it "
            "(exit 2 blaming OUT.json, the unusable file left behind)", "fixed",
            "calibrate fuzz (20000 examples)"),
    Finding("plan-huge-coordinates", "imaging/plan.py + imaging/_geometry.py",
            "a canal point at z = 1e308 mm (entry_mm 1e308: see symptom)",
            "accepted; export then exits 1 with ValueError: math domain error in the clearance "
            "(entry 1e308: refused, but NumPy's overflow warning precedes the error: line)",
            "fixed", "pipeline fuzz"),
    Finding("fifo-hang", "imaging/discovery.py", "a named pipe (mkfifo) pipe.dcm beside a series",
            "ctdrill inspect blocks forever opening it (killed after 15 s)", "fixed", "corpus"),
    Finding("calibration-law-vanishing", "model/calibration.py",
            "a0.n = -400 (or -1e308), or a0.b0 = -400",
            "accepted; A0 = 0 N at every HU (n = -1e308: overflow in n log10 C' on the way)",
            "fixed", "JSON fuzz (20000 examples)"),
    Finding("path-too-long", "imaging loader, imaging/plan.py, model/calibration.py, app export",
            "a path component over 255 bytes: inspect DIR, export --plan / --out, a plan's "
            "calibration name",
            "OSError [Errno 36] File name too long: traceback, exit 1", "fixed",
            "pipeline fuzz (20000 examples)"),
    Finding("dicom-nested-sequences", "imaging/dicom/fastheader.py",
            "1200 nested undefined-length sequences in one slice (43 KB)",
            "RecursionError: traceback in inspect, export, rehearse and the GUI", "fixed",
            "issue 15, corpus nested_undefined_sequences"),
    Finding("rle-lying-lengths", "imaging/dicom/pixels.py",
            "an RLE basic offset table, fragment or segment declaring 0xFFFFFFF0 bytes",
            "struct.error traceback (table); loaded from what was there (fragment, segment "
            "count); a two-line error (segment offset)", "fixed",
            "issue 15, corpus bomb_rle_*"),
    Finding("files-unreadable-silent", "imaging/dicom/discovery.py",
            "files or a subfolder of the series without read permission (not root)",
            "skipped silently: 40 of 80 slices loaded, warnings: none", "fixed",
            "issue 15, tests/imaging/test_load_unreadable.py"),
    Finding("special-file-readers", "haptics/session.py, model/recordings.py, app export",
            "an operator script, manifest or recording that is a FIFO or /dev/zero; a FIFO "
            "beside the series with --include-phi",
            "blocks forever / reads until MemoryError", "fixed",
            "issue 15, test_hostile_inputs.py"),
    Finding("calibration-json-bombs", "model/calibration.py",
            "a calibration set nested 1000 deep or holding a 4301-digit integer",
            "RecursionError / ValueError traceback", "fixed", "issue 15, test_hostile_inputs.py"),
    Finding("non-utf8-plan-name", "app/export_plot.py", "a plan file named b'pl\\xffan.json'",
            "matplotlib fails drawing the force.png title: traceback, exit 1", "fixed",
            "issue 15, test_hostile_inputs.py"),
    Finding("outputs-not-atomic", "app/export.py, app/commands/calibrate.py",
            "kill -9 during export; calibrate --out on a full disk",
            "a folder mixing old and new files, staging folders piling up; a good calibration "
            "overwritten by 8 KB of invalid JSON", "fixed",
            "issue 15, tests/app/test_records.py, test_output_faults.py"),
)  # fmt: skip

#: Open bugs whose trigger the fuzzers hit.
KNOWN_BUGS: tuple[KnownBug, ...] = ()

#: Corpus cases whose outcome is wrong (kept out of test_corpus.py and test_memory_bombs.py).
BUG_CASES: frozenset[str] = frozenset()


def known_bug(exc: BaseException) -> str | None:
    """The key of the reported bug ``exc`` comes from, or None if it is a new one."""
    # Resolved: in a checkout the package runs through the ctdrill/ links to the folders.
    frames = [
        f
        for f in traceback.extract_tb(exc.__traceback__)
        if Path(f.filename).resolve().is_relative_to(ROOT)
        and "/tests/" not in f.filename
        and "/.venv/" not in f.filename
    ]
    while frames and frames[-1].name.startswith("<"):  # <genexpr>, <listcomp>, <lambda>
        frames.pop()
    if not frames:
        return None
    where = frames[-1]
    rel = Path(where.filename).resolve().relative_to(ROOT).as_posix()
    for bug in KNOWN_BUGS:
        if (
            isinstance(exc, bug.exc_type)
            and rel == bug.module_path
            and bug.function in (where.name, "*")
        ):
            return bug.key
    return None


def test_known_bug_matches_module_and_function(
    monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    """The fuzzers' tolerance is exact: the bug's module and function, nothing wider."""
    import tests.robustness.test_found_bugs as registry
    from ctdrill.imaging import ImagingInputError
    from ctdrill.imaging.plan.load import load_plan

    bad = tmp_path / "bad-format.json"
    bad.write_text('{"format": "ctdrill-plan/9"}', encoding="utf-8")
    with pytest.raises(ImagingInputError) as info:
        load_plan(bad)  # raised in imaging/plan/plan_file.py
    assert known_bug(info.value) is None
    here = KnownBug("demo", ImagingInputError, "imaging/plan/plan_file.py", "*")
    monkeypatch.setattr(registry, "KNOWN_BUGS", (here,))
    assert known_bug(info.value) == "demo"
    elsewhere = KnownBug("demo", ImagingInputError, "imaging/series.py", "*")
    monkeypatch.setattr(registry, "KNOWN_BUGS", (elsewhere,))
    assert known_bug(info.value) is None
    wrong_type = KnownBug("demo", TypeError, "imaging/plan/plan_file.py", "*")
    monkeypatch.setattr(registry, "KNOWN_BUGS", (wrong_type,))
    assert known_bug(info.value) is None
