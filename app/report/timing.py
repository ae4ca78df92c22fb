"""Seconds per stage of a report (``ctdrill report --timings``)."""

from __future__ import annotations

from dataclasses import dataclass, field


@dataclass
class Timings:
    """Seconds spent in each stage (``ctdrill report`` prints them with ``--timings``)."""

    stages: dict[str, float] = field(default_factory=dict)

    def add(self, stage: str, seconds: float) -> None:
        """Count ``seconds`` to ``stage``."""
        self.stages[stage] = self.stages.get(stage, 0.0) + seconds

    def line(self) -> str:
        """``stage 0.12 s, ...; total 0.5 s``."""
        parts = ", ".join(f"{k} {v:.2f} s" for k, v in self.stages.items())
        return f"{parts}; total {sum(self.stages.values()):.2f} s"
