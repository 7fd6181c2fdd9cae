"""A board that sleeps between drains (issue 46, part 5): the app as `deploy` starts it (the
FIFO with its watermark, the base model, the wear profile) on the emulated Pico at 10, 100 and
400 Hz.  Between drains the app sleeps in time.sleep_ms (whole ms, rounded up), which
MicroPython's rp2 port spends in WFE with a timer alarm armed (mp_hal_delay_ms; its sleep_us
busy-waits the last partial ms); the emulator skips such a wait to the alarm and counts it
(bridge/scripts/rp2040.mjs `wakeups`).  The awake share is the core's executed cycles over the
emulated time's cycles at 125 MHz; each figure is the difference of a long and a short run, so
the import and set-up cancel.  No current estimate: it needs the RP2040 datasheet's run and
SLEEP/DORMANT currents (its section 5.4 "Power Consumption" table), whose rows the tools this
project searches with did not return; none is made up (docs/boards-and-logs.md)."""
from __future__ import annotations

import tempfile
from pathlib import Path

from accelcal.bridge import rp2040
from accelcal.locations import BOARDS_DIR

RATES = (10, 100, 400)
SHORT_S, LONG_S = 4, 12
APP = """import acal.logger.app, acal_board
app = acal.logger.app.App(acal_board, rate_hz={rate}, profile=1)
app.run({seconds})
print('ACAL_DONE', app.samples, app.lost)
"""
E = "rp2040_emulated_"


def _run(stimulus: Path, rate: int, seconds: int) -> tuple[int, int, float, int]:
    from accelcal.board import emulated
    r = emulated.run([APP.format(rate=rate, seconds=seconds)], stimulus=stimulus,
                     puts={"acal_board.py": (BOARDS_DIR / "pico.py").read_bytes()})
    lost = int(r.out.split("ACAL_DONE")[1].split()[1])
    s = r.report["scripts"][0]
    return s["cycles"], s["wakeups"], s["emulated_ms"], lost


def awake(short: tuple, long: tuple) -> tuple[float, float]:
    """(awake share %, wake-ups a second) of the time between a short run and a long one."""
    ms = long[2] - short[2]
    return (100.0 * (long[0] - short[0]) / (ms * rp2040.HZ / 1000),
            (long[1] - short[1]) / (ms / 1000))


def measure_sleep() -> dict:
    import sys
    from accelcal.simulate.stimulus import calibration_dance
    print("the app sleeping between drains on the emulated Pico (a few minutes)...",
          file=sys.stderr)
    truth = [1.02, 0.98, 1.01, 0.01, -0.01, 0.005, 0.03, -0.02, 0.04]
    res = {}
    with tempfile.TemporaryDirectory() as tmp:
        stim = Path(tmp) / "stim.bin"
        calibration_dance(stim, 400, truth, seed=5, rounds=1, rest_s=9)
        for rate in RATES:
            short, long = _run(stim, rate, SHORT_S), _run(stim, rate, LONG_S)
            share, wakeups = awake(short, long)
            res[E + f"awake_pct_{rate}hz"] = share
            res[E + f"wakeups_per_s_{rate}hz"] = wakeups
            res[E + f"lost_{rate}hz"] = short[3] + long[3]
    return res


def format_sleep(m: dict) -> str:
    if E + f"awake_pct_{RATES[0]}hz" not in m:
        return ""
    lines = ["", "the app as deployed (FIFO, base model, wear profile) on the emulated Pico, "
             f"{LONG_S} s less {SHORT_S} s of emulated time: the core awake / waits ended by an "
             "alarm a second (WFE between drains):"]
    for rate in RATES:
        lines.append(f"  {rate:>3} Hz: {m[E + f'awake_pct_{rate}hz']:.2f} % of the cycles awake, "
                     f"{m[E + f'wakeups_per_s_{rate}hz']:.1f} wake-ups a second, "
                     f"{m[E + f'lost_{rate}hz']} samples lost (goal at 100 Hz: awake <= 2 %)")
    lines.append("  current: not estimated (the RP2040 datasheet's run and sleep currents, section "
                 "5.4, not found by the project's search tools; none made up)")
    return "\n".join(lines)
