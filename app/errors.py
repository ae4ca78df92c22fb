"""Errors raised by the application layer for bad user input (exit code 2), and every
package's bad-input base that the command line turns into one ``error:`` line."""

from __future__ import annotations

from ctdrill.engine.errors import EngineInputError
from ctdrill.haptics.errors import HapticsInputError
from ctdrill.imaging.errors import ImagingInputError
from ctdrill.model.errors import ModelInputError


class AppInputError(ValueError):
    """Bad input to a command: the message names the file or field and what to do."""


#: What bad input raises anywhere: exit code 2 and one ``error:`` line (the CLI, a batch row).
INPUT_ERRORS: tuple[type[Exception], ...] = (
    AppInputError,
    EngineInputError,
    ImagingInputError,
    ModelInputError,
    HapticsInputError,
)
