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
share allows once the waits are, not today's draw; the table gives no WFE-idle figure.
Each rate is run with the LIS3DH on I2C0 at 400 kHz and on SPI0 at 8.93 MHz (boards/pico.py's
wiring; the chip model is attached to the bus the run names): both waits for the bus are
awake (machine.I2C polls; machine.SPI polls, or waits for its DMA channels from 32 bytes)."""
from __future__ import annotations

import tempfile
from pathlib import Path

from accelcal.bridge import rp2040
from accelcal.locations import BOARDS_DIR

RATES = (10, 100, 400)
BUSES = ("i2c", "spi")
SHORT_S, LONG_S = 4, 12
APP = """import acal.logger.app, acal_board
app = acal.logger.app.App(acal_board, rate_hz={rate}, profile=1, bus={bus!r})
app.run({seconds})
print('ACAL_DONE', app.samples, app.lost)
"""
E = "rp2040_emulated_"
# the emulated boards: board file, firmware, the chip's I2C and SPI wiring (pico.mjs), key prefix,
# the instruction its firmware waits in (MicroPython's mp_hal_delay_ms: WFE; CircuitPython 10.2.1's
# idle, as the emulator sees it execute: WFI with interrupts masked around it)
BOARDS = {"pico": ("pico.py", "MICROPYTHON", "0,4,5", "SPI_PICO", E, "WFE"),
          "feather": ("feather_rp2040.py", "CIRCUITPYTHON", "1,2,3", "SPI_FEATHER",
                      "rp2040_circuitpython_", "WFI")}
# RP2040 datasheet 5.7.2 Table 637, typical average DVDD current, mA
RUN_MA = 9.4        # BOOTSEL mode - Active (48 MHz)
SLEEP_MA = 0.39     # Sleep (hello_sleep)


def key(bus: str, what: str, rate: int, board: str = "pico") -> str:
    """The figure's name: the Pico's I2C ones as before SPI came
    (rp2040_emulated_awake_pct_100hz), SPI's with spi_ before what; the Feather's the same after
    rp2040_circuitpython_."""
    return BOARDS[board][4] + ("spi_" if bus == "spi" else "") + f"{what}_{rate}hz"


def _run(stimulus: Path, rate: int, seconds: int, bus: str = "i2c",
         board: str = "pico") -> tuple[int, int, float, int]:
    from accelcal.board import emulated
    board_file, fw, i2c, spi = BOARDS[board][:4]
    r = emulated.run([APP.format(rate=rate, seconds=seconds, bus=bus)], stimulus=stimulus,
                     fw=getattr(rp2040, fw), i2c=i2c,
                     spi=getattr(emulated, spi) if bus == "spi" else None,
                     puts={"acal_board.py": (BOARDS_DIR / board_file).read_bytes()})
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


def measure_sleep(board: str = "pico") -> dict:
    import sys
    from accelcal.simulate.stimulus import calibration_dance
    print(f"the app sleeping between drains on the emulated {board} (a few minutes)...",
          file=sys.stderr)
    truth = [1.02, 0.98, 1.01, 0.01, -0.01, 0.005, 0.03, -0.02, 0.04]
    res = {}
    with tempfile.TemporaryDirectory() as tmp:
        stim = Path(tmp) / "stim.bin"
        calibration_dance(stim, 400, truth, seed=5, rounds=1, rest_s=9)
        for bus in BUSES:
            for rate in RATES:
                short = _run(stim, rate, SHORT_S, bus, board)
                long = _run(stim, rate, LONG_S, bus, board)
                share, wakeups = awake(short, long)
                res[key(bus, "awake_pct", rate, board)] = share
                res[key(bus, "wakeups_per_s", rate, board)] = wakeups
                res[key(bus, "sleep_state_dvdd_ma", rate, board)] = current_ma(share)
                res[key(bus, "lost", rate, board)] = short[3] + long[3]
    return res


def format_sleep(m: dict) -> str:
    lines = []
    for board, what in (("pico", "the emulated Pico (MicroPython)"),
                        ("feather", "the emulated Feather RP2040 (CircuitPython)")):
        if key("i2c", "awake_pct", RATES[0], board) in m:
            lines += _format_board(m, board, what)
    return "\n".join(lines)


def _format_board(m: dict, board: str, what: str) -> list[str]:
    k = lambda bus, w, rate: m[key(bus, w, rate, board)]   # noqa: E731
    wait = BOARDS[board][5]
    lines = ["", f"the app as deployed (FIFO, base model, wear profile) on {what}, "
             f"{LONG_S} s less {SHORT_S} s of emulated time: the core awake / waits ended by an "
             f"alarm a second ({wait} between drains), the LIS3DH on I2C and on SPI:"]
    for bus in BUSES:
        if key(bus, "awake_pct", RATES[0], board) not in m:
            continue
        for rate in RATES:
            lines.append(f"  {bus.upper()} {rate:>3} Hz: {k(bus, 'awake_pct', rate):.2f} % of the "
                         f"cycles awake, {k(bus, 'wakeups_per_s', rate):.1f} wake-ups a second, "
                         f"{k(bus, 'lost', rate)} samples lost (goal at 100 Hz: awake <= 2 %)")
    lines.append(f"  DVDD current were the waits the SLEEP state: {RUN_MA} mA awake, {SLEEP_MA} mA "
                 "asleep (RP2040 datasheet 5.7.2 Table 637, typical; awake: BOOTSEL active at "
                 "48 MHz, a floor):")
    for bus in BUSES:
        if key(bus, "awake_pct", RATES[0], board) in m:
            lines.append(f"  {bus.upper()}: " + ", ".join(
                f"{rate} Hz ~{current_ma(k(bus, 'awake_pct', rate)):.2f} mA" for rate in RATES)
                + f" (the {wait} waits today keep every clock running: more)")
    return lines
