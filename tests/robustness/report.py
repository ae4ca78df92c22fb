"""Write docs/robustness.md: every corpus case and a seeded fault-injection campaign, with counts.

Usage: ``python -m tests.robustness.report [--examples N] [--out docs/robustness.md]``
(N mutations per target and seed; default 300). The campaign draws its faults from
``random.Random(seed)`` with the same mutation functions the hypothesis fuzz tests use.
"""

from __future__ import annotations

import argparse
import functools
import json
import logging
import platform
import random
import subprocess
import tempfile
import time
import warnings
from collections import Counter, defaultdict
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pydicom

from tests.robustness.fuzz import SEED_MARKUPS, SEED_PLAN, seed_calibration
from tests.robustness.make_corpus import ROOT, Case, build_corpus
from tests.robustness.mutate import (
    apply_bytes,
    bounded_memory,
    random_byte_mutation,
    random_json_mutation,
)
from tests.robustness.outcomes import (
    Observed,
    error_line_problems,
    inspect_args,
    observe_load,
    run_cli_in_process,
    run_cli_subprocess,
)
from tests.robustness.test_found_bugs import FINDINGS, known_bug
from tests.robustness.test_memory_bombs import BOMB_ADDRESS_SPACE, HANG_S

SLOW_S = 5.0


def corpus_rows(out_dir: Path) -> list[dict[str, str]]:
    """Run every corpus case through load_series and the CLI; one row per case."""
    rows = []
    for case in build_corpus(out_dir):
        if case.isolate:
            try:
                run = run_cli_subprocess(
                    inspect_args(case), address_space_bytes=BOMB_ADDRESS_SPACE, timeout_s=HANG_S
                )
            except subprocess.TimeoutExpired:
                rows.append(_row(case, f"hang (no exit within {HANG_S:.0f} s)", "killed", False))
                continue
            seen = _from_cli(run.code, run.stdout, run.stderr)
            cli_ok = run.code == 0 or not error_line_problems(run)
        else:
            seen = observe_load(case)
            run = run_cli_in_process(inspect_args(case))
            cli_ok = (run.code == 0) == (seen.outcome == "load") and (
                run.code == 0 or not error_line_problems(run)
            )
        rows.append(
            _row(case, _describe(seen), f"exit {run.code}", _matches(case, seen) and cli_ok)
        )
    return rows


def _row(case: Case, observed: str, cli: str, ok: bool) -> dict[str, str]:
    return {
        "case": case.name,
        "fault": case.fault,
        "expected": " or ".join(e.describe() for e in case.expected),
        "observed": observed,
        "cli": cli,
        "verdict": "ok" if ok else "**bug**",
    }


def _from_cli(code: int, stdout: str, stderr: str) -> Observed:
    if code == 0:
        doc = json.loads(stdout)
        codes = tuple(sorted(w["code"] for w in doc["warnings"]))
        return Observed("load", codes, tuple(doc["dims"]))
    if code == 2:
        return Observed("refuse", message=stderr.strip())
    return Observed("bug", message=stderr.strip().splitlines()[-1] if stderr.strip() else "")


def _matches(case: Case, seen: Observed) -> bool:
    if seen.outcome == "refuse":
        return any(e.outcome == "refuse" for e in case.expected)
    if seen.outcome == "load":
        return any(e.accepts_load(seen.codes, seen.dims) for e in case.expected)
    return False


def _describe(seen: Observed) -> str:
    if seen.outcome == "load":
        codes = ", ".join(seen.codes) if seen.codes else "no warning"
        return f"load {'x'.join(str(d) for d in seen.dims)} [{codes}]"
    if seen.outcome == "refuse":
        return "refuse"
    return f"exception: {seen.message[:80]}"


def classify(call: Callable[[], Any], project_error: type[BaseException]) -> str:
    """Run ``call`` under a 1 GiB address-space headroom: load, refuse, slow (more than
    :data:`SLOW_S` of CPU time: a loaded host does not make a case slow), known bug or new."""
    start = time.process_time()
    try:
        with bounded_memory():
            call()
    except project_error:
        outcome = "refuse"
    except Exception as exc:
        key = known_bug(exc)
        outcome = f"known bug: {key}" if key else f"NEW BUG: {type(exc).__name__}"
    else:
        outcome = "load"
    if time.process_time() - start > SLOW_S:
        outcome = "slow (> 5 s)"
    return outcome


def dicom_campaign(n: int, rng: random.Random) -> dict[str, Counter[str]]:
    """``n`` single mutations per seed series, one random file each; outcome counts per op."""
    from ctdrill.imaging import ImagingInputError, load_series
    from tests.robustness.test_fuzz_dicom import SEEDS, seed_offsets, seed_series

    counts: dict[str, Counter[str]] = defaultdict(Counter)
    for seed in SEEDS:
        files = seed_series(seed)
        for _ in range(n):
            mutation = random_byte_mutation(rng)
            victim = rng.randrange(len(files))
            data = apply_bytes(files[victim], mutation, seed_offsets(seed, victim))
            with tempfile.TemporaryDirectory() as tmp:
                for k, content in enumerate(files):
                    (Path(tmp) / f"{k}.dcm").write_bytes(data if k == victim else content)
                outcome = classify(functools.partial(load_series, tmp), ImagingInputError)
            counts[f"{seed}: {mutation.op}"][outcome] += 1
    return counts


def json_campaign(n: int, rng: random.Random) -> dict[str, Counter[str]]:
    """``n`` mutated documents per JSON reader; outcome counts per reader."""
    from ctdrill.imaging import ImagingInputError
    from ctdrill.imaging.plan.load import load_plans
    from ctdrill.model import ModelInputError, load_calibration

    targets: list[tuple[str, Any, str, Callable[[Path], object], type[BaseException]]] = [
        ("plan (ctdrill-plan/1)", SEED_PLAN, ".json", load_plans, ImagingInputError),
        ("plan (Slicer .mrk.json)", SEED_MARKUPS, ".mrk.json", load_plans, ImagingInputError),
        ("calibration set", seed_calibration(), ".json", load_calibration, ModelInputError),
    ]
    counts: dict[str, Counter[str]] = defaultdict(Counter)
    for name, doc, suffix, reader, error in targets:
        for _ in range(n):
            text = random_json_mutation(doc, rng)
            with tempfile.TemporaryDirectory() as tmp:
                path = Path(tmp) / f"doc{suffix}"
                path.write_text(text, encoding="utf-8", errors="surrogatepass")
                counts[name][classify(functools.partial(reader, path), error)] += 1
    return counts


def protocol_campaign(n: int, rng: random.Random) -> dict[str, Counter[str]]:
    """``n`` mutated frames fed to a FrameReader followed by a valid heartbeat."""
    from ctdrill.haptics.protocol import FrameReader, Packet, ProtocolError, decode
    from tests.robustness.test_fuzz_protocol import FRAMES, HEARTBEAT

    counts: dict[str, Counter[str]] = defaultdict(Counter)
    for _ in range(n):
        mutation = random_byte_mutation(rng)
        while mutation.op == "length":  # frames have no DICOM elements
            mutation = random_byte_mutation(rng)
        original = rng.choice(FRAMES)
        frame = apply_bytes(original, mutation, [])
        reader = FrameReader()
        try:
            out = reader.feed(rng.randbytes(rng.randrange(64)) + frame + b"\x00" + HEARTBEAT)
        except Exception as exc:
            counts[mutation.op][f"NEW BUG: {type(exc).__name__}"] += 1
            continue
        recovered = bool(out) and isinstance(out[-1], Packet)
        packets = [item for item in out[:-1] if isinstance(item, Packet)]
        if any(p != decode(original[:-1]) for p in packets):
            outcome = "decoded, altered (CRC collision)"
        elif packets:
            outcome = "decoded intact (fault missed the frame)"
        elif any(isinstance(item, ProtocolError) for item in out):
            outcome = "refused"
        else:
            outcome = "dropped"
        counts[mutation.op][outcome] += 1
        if not recovered:
            counts[mutation.op]["NEW BUG: next frame lost"] += 1
    return counts


def _counts_table(title: str, counts: dict[str, Counter[str]]) -> list[str]:
    columns = sorted({k for c in counts.values() for k in c})
    lines = [f"| {title} | " + " | ".join(columns) + " | total |"]
    lines.append("|---" * (len(columns) + 2) + "|")
    for key in sorted(counts):
        c = counts[key]
        cells = " | ".join(str(c.get(col, 0)) for col in columns)
        lines.append(f"| {key} | {cells} | {sum(c.values())} |")
    return lines


def render(
    rows: list[dict[str, str]],
    campaigns: dict[str, dict[str, Counter[str]]],
    n: int,
    seconds: float,
) -> str:
    """The Markdown page."""
    ok = sum(r["verdict"] == "ok" for r in rows)
    out = [
        "# Robustness: hard inputs, fault injection, privacy",
        "",
        "Generated by `python -m tests.robustness.report` (do not edit by hand). The same inputs",
        "are asserted by `tests/robustness/` in `make test` (short fuzz runs) and `make fuzz`",
        "(`CTDRILL_FUZZ_EXAMPLES=20000`).",
        "",
        f"Last run: {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}, Python "
        f"{platform.python_version()}, pydicom {pydicom.__version__}, {n} mutations per target "
        f"and seed, {seconds:.0f} s in all.",
        "",
        "## Hard-input corpus",
        "",
        "Written with pydicom by `tests/robustness/make_corpus.py` (synthetic 10x12x8 series with",
        "known HU and geometry, one fault each) plus the real series of `../shared/data`.",
        "Expected outcomes list every acceptable one; a refusal is `ImagingInputError`, i.e.",
        "`ctdrill inspect` exits 2 with one `error:` line. Memory bombs run in a fresh process",
        f"under `RLIMIT_AS` = {BOMB_ADDRESS_SPACE >> 30} GiB (a real load needs 0.4 GiB), as do",
        f"special files (named pipe, /dev/zero links), killed after {HANG_S:.0f} s.",
        "",
        f"{ok} of {len(rows)} cases behave as expected.",
        "",
        "| case | fault | expected | observed | CLI | verdict |",
        "|---|---|---|---|---|---|",
    ]
    for r in rows:
        out.append(
            f"| {r['case']} | {r['fault']} | {r['expected']} | {r['observed']} | {r['cli']} "
            f"| {r['verdict']} |"
        )
    out += [
        "",
        "## Fault injection (seeded campaign)",
        "",
        "Each DICOM example mutates one byte-level fault (flip, insert, delete, truncate,",
        "overwrite, or a data element's length field rewritten) into one file of a three-slice",
        "series seeded from pydicom's `CT_small.dcm` or the bundled demo phantom, and loads the",
        "folder under 1 GiB of address-space headroom. `refuse` is the package's input error;",
        "`known bug` rows are the reported bugs below; `NEW BUG` would be anything else. A",
        "mutation that lands in pixel data loads (different HU, same shape): that is expected.",
        "JSON documents take one structure mutation (delete, replace with a hostile value, wrap,",
        "stringify, duplicate) or a text cut; serial frames are followed by a valid heartbeat,",
        "which must always come through.",
        "",
    ]
    for title, counts in campaigns.items():
        out += [*_counts_table(title, counts), ""]
    out += [
        "## Hypothesis fuzz tests",
        "",
        "Marked `fuzz`: 40 examples each in `make test`, `CTDRILL_FUZZ_EXAMPLES` (20000 in",
        "`make fuzz`) otherwise. Only the package's own input error may escape; each example has",
        "5 s and 1 GiB of extra address space.",
        "",
        "| test | input | invariant |",
        "|---|---|---|",
        "| `test_fuzz_dicom.py` | 1-4 byte faults in one file of a 3-slice series "
        "(CT_small, demo phantom) | loads a finite volume or `ImagingInputError` |",
        "| `test_fuzz_json.py` | 1-3 structure or text faults in a plan, a Slicer markup, a "
        "calibration set | a finite, sane plan / a law finite for every int16 HU, or the "
        "package error |",
        "| `test_fuzz_pipeline.py` | faulty demo plans that still load | `plan_path` gives finite "
        "profiles and a stop within the plan, or an input error |",
        "| `test_fuzz_protocol.py` | faulty frames after garbage, split at random | only "
        "`ProtocolError`; the reader's buffer stays bounded; the next heartbeat decodes |",
        "| `test_fuzz_calibrate.py` | a hostile cell, a repeated or dropped row, or byte faults "
        "in the manifest or one of six recordings | a finite set that loads back, or the "
        "package error |",
        "| `test_fuzz_device.py` | uploads, ARM/STOP/RESET, hostile values, hands up to 100 N, "
        "ticks | force finite in 0..78 N; the drill never past the uploaded stop depth |",
        "",
        "## Found bugs",
        "",
        "Each open bug is a failing test in `tests/robustness/test_found_bugs.py`; fixed ones keep",
        "their minimal input in `test_regressions.py` (or as a corpus case).",
        "",
        "| bug | component | trigger | symptom | found by | status |",
        "|---|---|---|---|---|---|",
    ]
    for f in FINDINGS:
        out.append(
            f"| {f.key} | `{f.component}` | {f.trigger} | {f.symptom} | {f.found_by} | {f.status} |"
        )
    out += [
        "",
        "## Privacy",
        "",
        "`tests/robustness/test_privacy.py` rewrites the demo series with a known patient name,",
        "ID, birth date, accession number, institution and referring physician, study and series",
        "descriptions holding the name, and a site-minted SeriesInstanceUID, in a folder named",
        "after the patient, and scans every byte that `inspect` (text and `--json`), `export` and",
        "`rehearse` print or write: none appears (series are named by the SHA-256 of their UID).",
        "`export --include-phi` and `inspect --include-phi` are the positive controls.",
        "",
        "## Hostile inputs and records (issue 15)",
        "",
        "`tests/robustness/test_hostile_inputs.py` (each CLI run in a fresh process under",
        "`RLIMIT_AS` = 2 GiB and a timeout): calibration sets nested 1000 deep, holding a",
        "4301-digit integer or a lone surrogate; operator scripts, manifests and recordings that",
        "are a FIFO, `/dev/zero` or a folder; an operator script over 1 000 000 rows; a FIFO",
        "beside the series with `--include-phi`; a plan file name that is not UTF-8; 1200 nested",
        "undefined-length sequences through `export`, `rehearse` and the GUI. Unreadable files",
        "and folders (`tests/imaging/test_load_unreadable.py`, run as `nobody`) give",
        "`files_unreadable`. Outputs (`tests/app/test_records.py`, `test_output_faults.py`):",
        "14 `kill -9` at random moments of a 4.8 MB export leave the old or the new folder whole;",
        "a full 1 MiB tmpfs and `RLIMIT_FSIZE` give one `error:` line naming the file and leave",
        "the previous export or calibration set byte for byte.",
        "",
        "## Properties",
        "",
        "`tests/robustness/test_properties.py`: `CTVolume.sample` is finite for random volumes",
        "(rotation, padding masks) and points up to 1e300 mm or non-finite; the force law is",
        "finite and below its analytic bound for all 65536 int16 HU at feeds -5..1e6 mm/s; the",
        "stop depth never exceeds the planned depth and the clearance never grows with depth on",
        "randomised plans through the demo phantom.",
        "",
    ]
    return "\n".join(out)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--examples", type=int, default=300)
    parser.add_argument("--seed", type=int, default=20261121)
    parser.add_argument("--out", type=Path, default=ROOT / "docs" / "robustness.md")
    args = parser.parse_args()
    warnings.simplefilter("ignore")
    logging.getLogger("pydicom").setLevel(logging.CRITICAL)
    start = time.perf_counter()
    rng = random.Random(args.seed)
    with tempfile.TemporaryDirectory() as tmp:
        rows = corpus_rows(Path(tmp))
    campaigns = {
        "DICOM seed: fault": dicom_campaign(args.examples, rng),
        "JSON reader": json_campaign(args.examples, rng),
        "serial frame: fault": protocol_campaign(args.examples, rng),
    }
    text = render(rows, campaigns, args.examples, time.perf_counter() - start)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(text)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
