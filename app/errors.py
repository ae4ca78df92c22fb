"""Errors raised by the application layer for bad user input (exit code 2)."""


class AppInputError(ValueError):
    """Bad input to a command: the message names the file or field and what to do."""
