"""What a rehearsal session is made of: the operator, the injected faults, the session log.

The host loop that runs a session is :func:`ctdrill.haptics.run.run_session`.

Operators (``--operator``): ``push:N`` constant hand force N newtons; ``feed:V`` the hand
moves at a constant feed V mm/s (a stiff hand, its force capped at the device's peak force,
:data:`~ctdrill.haptics.physics.HAND_MAX_N`); ``script:FILE`` a CSV ``time_s,force_n`` (linear
between rows, held after the last); ``human:force=N,react_ms=T[,noise_n=S,seed=K]`` a person
(:class:`HumanSpec`; what it does in a session: :class:`ctdrill.haptics.hands.HumanHand`).

Faults (``--fault``, repeatable): ``link-loss@T`` the host's frames stop reaching the device
from T s on; ``garbage@T`` 64 random bytes (from the seed) on the link at T; ``delay@T:MS`` the
host's frames are held from T for MS ms then delivered late; ``reset@T`` the device reboots
at T.
"""

from __future__ import annotations

import bisect
import csv
import hashlib
import math
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from ctdrill.haptics.errors import HapticsInputError
from ctdrill.haptics.physics import HAND_MAX_FEED_MM_S, HAND_MAX_N
from ctdrill.haptics.protocol import DeviceState
from ctdrill.numtext import ascii_number, ascii_whole
from ctdrill.safeio import read_bytes_bounded

if TYPE_CHECKING:
    from ctdrill.haptics.device import TelemetrySample

#: ``session.csv``'s columns: the session time, the handle's and the drill's depth, the force
#: the device rendered, its state, and the device's reading of the hand's force (the reaction
#: observer's ``force_est_n``), from which the assessment is recomputed.
SESSION_COLUMNS = ("time_s", "master_mm", "drill_mm", "force_cmd_n", "state", "hand_force_n")
STATE_NAMES = {int(s): s.name.lower() for s in DeviceState}
FAULT_KINDS = ("link-loss", "garbage", "delay", "reset")
#: Largest operator script read, bytes, and its most rows (1 kHz for over 16 minutes).
MAX_SCRIPT_BYTES = 64 * 1024 * 1024
MAX_SCRIPT_ROWS = 1_000_000


#: The fields of a ``human:`` operator, required first (docs/rehearse.md).
HUMAN_FIELDS = ("force", "react_ms", "noise_n", "seed")
HUMAN_GRAMMAR = "human:force=N,react_ms=T[,noise_n=S,seed=K]"
#: Longest reaction time accepted, ms (a minute: longer is no reaction).
MAX_REACT_MS = 60_000.0


class SessionInputError(HapticsInputError):
    """A bad ``--operator`` or ``--fault`` specification or operator script."""


@dataclass(frozen=True)
class HumanSpec:
    """A modelled person (``human:`` operator).

    Attributes
    ----------
    force_n : float
        The push while the hand holds on, N (0 < force <=
        :data:`~ctdrill.haptics.physics.HAND_MAX_N`).
    react_ms : float
        Reaction time: the hand lets go this long after it feels a breakthrough or meets the
        wall, ms.
    noise_n : float
        Standard deviation of the Gaussian noise added to the push at 100 Hz, N.
    seed : int
        Seeds the noise.
    """

    force_n: float
    react_ms: float
    noise_n: float = 0.0
    seed: int = 0


@dataclass(frozen=True)
class Operator:
    """The simulated hand.

    Attributes
    ----------
    kind : str
        ``push``, ``feed``, ``script`` or ``human``.
    value : float
        Force N (push, human) or feed mm/s (feed); unused for script.
    script : tuple of (time_s, force_n)
        Script rows, times increasing (script only).
    spec : str
        The specification it was parsed from, as records name it (a script by its content's
        hash: :func:`script_label`).
    human : HumanSpec or None
        The person (human only).
    """

    kind: str
    value: float = 0.0
    script: tuple[tuple[float, float], ...] = ()
    spec: str = ""
    human: HumanSpec | None = None

    def force_at_n(self, t_s: float) -> float:
        """Hand force at session time ``t_s`` (push and script; a human's set push), N."""
        if self.kind in ("push", "human"):
            return self.value
        rows = self.script
        if t_s <= rows[0][0]:
            return rows[0][1]
        i = bisect.bisect_left(rows, (t_s, -math.inf))  # O(log n): long scripts keep the pace
        if i >= len(rows):
            return rows[-1][1]
        (t0, f0), (t1, f1) = rows[i - 1], rows[i]
        return f0 + (f1 - f0) * (t_s - t0) / (t1 - t0)


def _number(text: str, what: str, spec: str) -> float:
    value = ascii_number(text)
    if value is None:
        value = math.nan
    if not math.isfinite(value):
        raise SessionInputError(f"{spec}: {what} must be a finite number, got {text!r}")
    return value


def load_script(path: Path) -> tuple[tuple[float, float], ...]:
    """Read an operator script CSV with columns ``time_s,force_n``.

    A regular file of at most :data:`MAX_SCRIPT_BYTES` and :data:`MAX_SCRIPT_ROWS` rows (a FIFO
    would block, ``/dev/zero`` would never end): it is read whole before the device is armed.
    """
    return _load_script(path)[0]


def script_label(digest: str) -> str:
    """How records name a script operator: ``script:sha256=`` and the first 16 hex digits of
    the file's SHA-256, never its path (a folder named after a patient stays out of
    ``summary.json`` and the trainee record)."""
    return f"script:sha256={digest[:16]}"


def _load_script(path: Path) -> tuple[tuple[tuple[float, float], ...], str]:
    """The script's rows and the SHA-256 of its bytes (hex)."""
    if not path.exists() and not path.is_symlink():
        raise SessionInputError(f"operator script {path}: cannot read (no such file)")
    data = read_bytes_bounded(
        path, what="operator script", error=SessionInputError, max_bytes=MAX_SCRIPT_BYTES
    )
    try:
        text = data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise SessionInputError(
            f"operator script {path}: not UTF-8 text ({exc.reason} at byte {exc.start})"
        ) from exc
    lines = text.splitlines()
    if len(lines) > MAX_SCRIPT_ROWS + 1:
        raise SessionInputError(
            f"operator script {path}: {len(lines) - 1} rows, more than the {MAX_SCRIPT_ROWS} "
            "accepted; resample it (1 kHz is finer than a hand)"
        )
    reader = csv.reader(lines)
    header = next(reader, None)
    if header is None or [h.strip() for h in header[:2]] != ["time_s", "force_n"]:
        raise SessionInputError(f"operator script {path}: the first line must be 'time_s,force_n'")
    rows: list[tuple[float, float]] = []
    for lineno, row in enumerate(reader, start=2):
        if not row or not "".join(row).strip():
            continue
        if len(row) < 2:
            raise SessionInputError(f"operator script {path}:{lineno}: expected time_s,force_n")
        t = _number(row[0], f"time_s at line {lineno}", f"operator script {path}")
        f = _number(row[1], f"force_n at line {lineno}", f"operator script {path}")
        if rows and t <= rows[-1][0]:
            raise SessionInputError(f"operator script {path}:{lineno}: time_s must increase")
        if abs(f) > HAND_MAX_N:
            raise SessionInputError(
                f"operator script {path}:{lineno}: |force_n| must be <= {HAND_MAX_N:g} N"
            )
        rows.append((t, f))
    if not rows:
        raise SessionInputError(f"operator script {path}: no rows after the header")
    return tuple(rows), hashlib.sha256(data).hexdigest()


def _bounded(text: str, field: str, spec: str, low: float, high: float, *, open_low: bool) -> float:
    value = _number(text, field, f"--operator {spec!r}")
    if not (low < value if open_low else low <= value) or value > high:
        lower = f"> {low:g}" if open_low else f">= {low:g}"
        raise SessionInputError(f"--operator {spec!r}: {field} must be {lower} and <= {high:g}")
    return value


def parse_human(spec: str) -> HumanSpec:
    """The fields of ``human:force=N,react_ms=T[,noise_n=S,seed=K]`` (any order, each once).

    Raises
    ------
    SessionInputError
        Naming the field: unknown, repeated, missing or out of range.
    """
    arg = spec.partition(":")[2]
    fields: dict[str, str] = {}
    for item in arg.split(","):
        key, eq, text = (part.strip() for part in item.partition("="))
        if not eq or key not in HUMAN_FIELDS:
            raise SessionInputError(
                f"--operator {spec!r}: unknown field {key or item!r}; use {HUMAN_GRAMMAR}"
            )
        if key in fields:
            raise SessionInputError(f"--operator {spec!r}: field {key} is given twice")
        fields[key] = text
    for key in HUMAN_FIELDS[:2]:
        if key not in fields:
            raise SessionInputError(
                f"--operator {spec!r}: field {key} is missing ({HUMAN_GRAMMAR})"
            )
    force = _bounded(fields["force"], "force", spec, 0.0, HAND_MAX_N, open_low=True)
    react = _bounded(fields["react_ms"], "react_ms", spec, 0.0, MAX_REACT_MS, open_low=False)
    noise = _bounded(fields.get("noise_n", "0"), "noise_n", spec, 0.0, HAND_MAX_N, open_low=False)
    seed_text = fields.get("seed", "0")
    seed = ascii_whole(seed_text, max_digits=18)
    if seed is None:
        raise SessionInputError(
            f"--operator {spec!r}: seed must be a whole number >= 0 in digits 0-9 (at most 18 "
            f"digits), got {seed_text!r}"
        )
    return HumanSpec(force, react, noise, seed)


def parse_operator(spec: str) -> Operator:
    """``push:N``, ``feed:V``, ``script:FILE`` or ``human:...`` (:data:`HUMAN_GRAMMAR`)."""
    kind, sep, arg = spec.partition(":")
    if not sep or kind not in ("push", "feed", "script", "human") or not arg:
        raise SessionInputError(
            f"--operator {spec!r}: use push:N (newtons), feed:V (mm/s), script:FILE or "
            f"{HUMAN_GRAMMAR}"
        )
    if kind == "human":
        human = parse_human(spec)
        return Operator("human", value=human.force_n, spec=spec, human=human)
    if kind == "script":  # recorded by its content's hash: no path reaches the records
        rows, digest = _load_script(Path(arg))
        return Operator("script", script=rows, spec=script_label(digest))
    value = _number(arg, "the value", f"--operator {spec!r}")
    if kind == "push" and abs(value) > HAND_MAX_N:
        raise SessionInputError(f"--operator {spec!r}: force must be within +-{HAND_MAX_N:g} N")
    if kind == "feed" and abs(value) > HAND_MAX_FEED_MM_S:
        raise SessionInputError(
            f"--operator {spec!r}: feed must be within +-{HAND_MAX_FEED_MM_S:g} mm/s"
        )
    return Operator(kind, value=value, spec=spec)


@dataclass(frozen=True)
class FaultSpec:
    """An injected fault: ``kind`` at session time ``time_s`` (``delay``: for ``duration_ms``)."""

    kind: str
    time_s: float
    duration_ms: float = 0.0
    spec: str = ""


def parse_fault(spec: str) -> FaultSpec:
    """``link-loss@T``, ``garbage@T``, ``delay@T:MS`` or ``reset@T``."""
    kind, sep, rest = spec.partition("@")
    if not sep or kind not in FAULT_KINDS:
        raise SessionInputError(
            f"--fault {spec!r}: use link-loss@T, garbage@T, delay@T:MS or reset@T (T in s)"
        )
    t_text, _, ms_text = rest.partition(":")
    t = _number(t_text, "the time", f"--fault {spec!r}")
    if t < 0.0:
        raise SessionInputError(f"--fault {spec!r}: the time must be >= 0 s")
    ms = 0.0
    if kind == "delay":
        ms = _number(ms_text, "the delay (ms)", f"--fault {spec!r}")
        if ms <= 0.0:
            raise SessionInputError(f"--fault {spec!r}: the delay must be > 0 ms")
    elif ms_text:
        raise SessionInputError(f"--fault {spec!r}: only delay takes ':MS'")
    return FaultSpec(kind, t, ms, spec)


#: One ``session.csv`` row: ``(time_s, master_mm, drill_mm, force_cmd_n, state, hand_force_n)``.
Row = tuple[float, float, float, float, str, float]


def sample_row(t_s: float, sample: TelemetrySample) -> Row:
    """The ``session.csv`` row of a telemetry ``sample`` at session time ``t_s``."""
    state = STATE_NAMES.get(sample.state, "?")
    return (t_s, sample.master_mm, sample.drill_mm, sample.force_cmd_n, state, sample.force_est_n)


def csv_cells(row: Row) -> tuple[str, str, str, str, str, str]:
    """A row's ``session.csv`` cells: the one place their digits are chosen (the assessment
    reads the values as written, so the file recomputes it exactly)."""
    t, m, d, f, s, h = row
    return (f"{t:.4f}", f"{m:.5f}", f"{d:.5f}", f"{f:.4f}", s, f"{h:.4f}")


def session_cells(rows: Sequence[Row]) -> Iterator[tuple[str, str, str, str, str, str]]:
    """``session.csv``'s cells of ``rows`` (:data:`SESSION_COLUMNS`), formatted
    (:func:`csv_cells`); the file is written by :mod:`ctdrill.app.session_csv`."""
    return (csv_cells(r) for r in rows)
