"""A board that sleeps between drains (issue 46, part 5): the app as `deploy` starts it (the
FIFO with its watermark, the base model, the wear profile) on the emulated Pico at 10, 100 and
400 Hz.  Between drains the app sleeps in time.sleep_ms (whole ms, rounded up), which
MicroPython's rp2 port spends in WFE with a timer alarm armed (mp_hal_delay_ms; its sleep_us
busy-waits the last partial ms); the emulator skips such a wait to the alarm and counts it
(bridge/scripts/rp2040.mjs `wakeups`).  The awake share is the core's executed cycles over the
emulated time's cycles at 125 MHz; each figure is the difference of a long and a short run, so
the import and set-up cancel.  The current is estimated from the RP2040 datasheet's section
5.7.2, Table 637 "Power Consumption" (typical average DVDD, the core supply): awake at its one
running figure, BOOTSEL mode active (9.4 mA, clk_sys 48 MHz: a floor for 125 MHz), the waits at
its SLEEP figure (0.39 mA, hello_sleep: clocks gated by SLEEP_EN).  The app's WFE waits are not
that state (every clock keeps running; lightsleep comes close), so the figure is what the awake
share allows once the waits are, not today's draw; the table gives no WFE-idle figure."""
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
# RP2040 datasheet 5.7.2 Table 637, typical average DVDD current, mA
RUN_MA = 9.4        # BOOTSEL mode - Active (48 MHz)
SLEEP_MA = 0.39     # Sleep (hello_sleep)


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


def current_ma(awake_pct: float) -> float:
    """Average DVDD current (mA) with the core awake awake_pct % of the time at RUN_MA and
    asleep the rest at SLEEP_MA (the datasheet's typical figures)."""
    a = awake_pct / 100.0
    return a * RUN_MA + (1.0 - a) * SLEEP_MA


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
            res[E + f"sleep_state_dvdd_ma_{rate}hz"] = current_ma(share)
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
    lines.append(f"  DVDD current were the waits the SLEEP state: {RUN_MA} mA awake, {SLEEP_MA} mA "
                 "asleep (RP2040 datasheet 5.7.2 Table 637, typical; awake: BOOTSEL active at "
                 "48 MHz, a floor):")
    lines.append("  " + ", ".join(f"{rate} Hz ~{current_ma(m[E + f'awake_pct_{rate}hz']):.2f} mA"
                                  for rate in RATES)
                 + " (the WFE waits today keep every clock running: more)")
    return "\n".join(lines)
