"""Typed errors of the ``haptics`` package."""


class HapticsInputError(ValueError):
    """Bad input (file, field or value): the message names it and says what to do.

    The CLI turns every subclass into one ``error:`` line on stderr and exit code 2.
    """
