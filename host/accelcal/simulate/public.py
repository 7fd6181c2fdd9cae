"""accelcal.simulate_wrist, the Python API's: the CLI's checks (`accelcal simulate wrist`), then
the simulation (simulate/wearer.py).  Every argument is checked as the command line checks its
option (files/arguments.py: days in (0, 3650], rate 10/25/50/100 Hz, range 2/4/8/16 g, a seed,
catalogue effects, each once), and no file is written over without force=True: the recording,
its truth file and the stimulus (one line, InputError, before anything is simulated)."""
from __future__ import annotations

from pathlib import Path

from accelcal.errors import InputError
from accelcal.files import arguments as a
from accelcal.files.outputs import check_output


def simulate_wrist(output: str | Path, days: float = 1.0, rate: int = 25, seed: int = 0,
                   effect=(), stimulus: str | Path | None = None, range_g: int = 2,
                   progress=None, events_within_days: float | None = None, *,
                   force: bool = False) -> dict:
    """Write a simulated wrist recording CSV and its truth (NAME.truth.json) as `accelcal
    simulate wrist -o output` does; returns the truth (simulate/wearer.py simulate_wrist).
    force: replace files that exist (else InputError, as the CLI without --force)."""
    from accelcal.model.effects import CATALOGUE
    from accelcal.simulate import wearer
    a.paths(required=("output",), output=output, stimulus=stimulus)
    days = a.number("days", days)
    rate = a.choice("rate", rate)
    range_g = a.choice("range", range_g)
    seed = a.whole("seed", seed)
    effects = effect
    if isinstance(effects, str) or not all(isinstance(e, str) for e in effects):
        raise InputError(f"argument --effect: {effects!r:.60}: a list of effect names")
    for name in effects:
        if name not in CATALOGUE:
            raise InputError(f"--effect {name!r}: not an effect (one of {', '.join(CATALOGUE)}, "
                             "or one --effects FILE declares)")
    if len(set(effects)) != len(effects):
        raise InputError("--effect: the same effect twice")
    if events_within_days is not None:
        events_within_days = a.number("days", events_within_days)
    if not isinstance(force, bool):
        raise InputError(f"force={force!r:.40}: True or False")
    out = check_output(output, (), force, "-o/--output")
    check_output(out.with_suffix(".truth.json"), (), force, "its truth file")
    if stimulus is not None:
        check_output(stimulus, [out], force, "--stimulus")
    return wearer.simulate_wrist(out, days, rate, seed, effect=tuple(effects),
                                 stimulus=stimulus, range_g=range_g, progress=progress,
                                 events_within_days=events_within_days)
