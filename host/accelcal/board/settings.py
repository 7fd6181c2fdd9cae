"""The settings `deploy` records on the board (acal_settings.json at the top of its filesystem),
so that `acquire`, `pull` and `report` run with and show what the board was deployed with: the
app options as the command line named them (`options`), the arguments acal.logger.app.main() gets from
them (`app`), the board file and the format of the modules.  An option given again on
`acquire`'s command line must agree with the recorded one (else one line, exit 2)."""
from __future__ import annotations

import json

from accelcal.errors import InputError

SETTINGS_FILE = "acal_settings.json"
FORMAT = 1


def settings_text(options: dict, app: dict, board: str, module_format: str) -> str:
    return json.dumps({"format": FORMAT, "board": board, "modules": module_format,
                       "options": options, "app": app}, indent=1, sort_keys=True) + "\n"


def parse(text: str, where: str) -> dict:
    """A settings file's contents, checked: one line naming where it came from if it is not
    one deploy wrote."""
    try:
        s = json.loads(text)
    except ValueError:
        s = None
    if not isinstance(s, dict) or s.get("format") != FORMAT or not isinstance(s.get("options"), dict) \
            or not isinstance(s.get("app"), dict):
        raise InputError(f"{where}: {SETTINGS_FILE} is not one `accelcal deploy` wrote (deploy "
                         "again to record the settings)")
    return s


def resolve(given: dict, defaults: dict, flags: dict, recorded: dict | None, port: str) -> dict:
    """The app options to run with: the recorded ones (deploy's), or the defaults for a board
    deployed before settings were recorded; an option given (not None) must equal what it
    resolves to, else one line naming the option, both values and how to change it."""
    base = dict(defaults, **(recorded or {}))
    for dest, value in given.items():
        if value is None or value == base.get(dest):
            continue
        if recorded is None:     # nothing recorded: the command line rules, as before
            base[dest] = value
            continue
        was = base.get(dest)
        raise InputError(f"{flags[dest]} {show(value)}: the board at {port} was deployed with "
                         f"{flags[dest]} {show(was)} (run `accelcal deploy` with the new "
                         "settings, or leave the option out)")
    return base


def show(value) -> str:
    if value is True:
        return "(given)"
    if value in (False, None):
        return "(not given)"
    return str(value)


