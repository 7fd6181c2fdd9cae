"""The one error type of bad input: the CLI prints its message on one line and exits with
status 2 (no traceback)."""


class InputError(Exception):
    """Bad input: the CLI prints the message on one line and exits with status 2."""
