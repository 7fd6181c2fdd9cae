"""The one error type of bad input: the CLI prints its message on one line and exits with
status 2 (no traceback)."""


class InputError(Exception):
    """Bad input: the CLI prints the message on one line and exits with status 2."""


MESSAGE_MAX = 400    # an error line; longer ones keep their head and tail (where the advice is)


def printable(text: str) -> str:
    """Text from an input made safe for a terminal: control characters (terminal escapes,
    newlines, NUL) written as \\xNN escapes, everything printable kept as it is."""
    return "".join(c if c.isprintable() else
                   (f"\\x{ord(c):02x}" if ord(c) < 256 else f"\\u{ord(c):04x}") for c in text)


def one_line(message: str) -> str:
    """An error message as the one line the CLI prints: printable, at most MESSAGE_MAX chars."""
    s = printable(str(message))
    if len(s) > MESSAGE_MAX:
        s = s[:MESSAGE_MAX - 100] + " [...] " + s[-93:]
    return s
