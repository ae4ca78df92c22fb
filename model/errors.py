"""Typed errors of the ``model`` package."""


class ModelInputError(ValueError):
    """Bad input (file, field or value): the message names it and says what to do.

    The CLI turns every subclass into one ``error:`` line on stderr and exit code 2.
    """


class CalibrationError(ModelInputError):
    """A calibration set is missing, unreadable or has an invalid field."""
