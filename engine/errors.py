"""Errors raised by the engine for bad input (exit code 2)."""


class EngineInputError(ValueError):
    """Bad input to the engine: the message names the option or field and what to do."""


class ExportInputError(EngineInputError):
    """Bad export settings (feed, rate, HU uncertainty, grey map)."""
