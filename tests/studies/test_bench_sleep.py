"""`accelcal bench --runtime rp2040`'s sleeping board (studies/bench_sleep.py): the emulator
counts the waits the core slept through (bridge/scripts/rp2040.mjs), and the app as deployed,
between drains, is awake a small share of the time and loses nothing."""
import pytest

from conftest import emulated_chip


def test_the_awake_share_and_wake_ups_are_the_difference_of_two_runs():
    from accelcal.studies import bench_sleep
    # 1.25e9 cycles of 12 s less 0.5e9 of 4 s: 0.75e9 cycles in 8 s of 125 MHz = 75 %
    share, wakeups = bench_sleep.awake((500_000_000, 40, 4000.0, 0), (1_250_000_000, 120, 12000.0, 0))
    assert share == pytest.approx(75.0) and wakeups == pytest.approx(10.0)


@pytest.mark.slow
@pytest.mark.parametrize("board", ["pico", "feather"])
def test_the_app_sleeps_between_drains_on_the_emulated_boards(capsys, board):
    from accelcal.bridge import rp2040
    from accelcal.studies import bench_sleep
    emulated_chip(getattr(rp2040, bench_sleep.BOARDS[board][1]))
    m = bench_sleep.measure_sleep(board)
    k = lambda bus, what, rate: bench_sleep.key(bus, what, rate, board)   # noqa: E731
    for bus in bench_sleep.BUSES:
        for rate in bench_sleep.RATES:
            assert m[k(bus, "lost", rate)] == 0
            assert 0 < m[k(bus, "awake_pct", rate)] < 50
            # at least a wake-up a drain, and a drain takes at most the FIFO's 32 (nothing
            # lost): 25 a drain when it comes on time, a few more when a wait ends late
            assert m[k(bus, "wakeups_per_s", rate)] >= rate / 32
        # the work is per sample: more samples, more awake
        assert m[k(bus, "awake_pct", 10)] < m[k(bus, "awake_pct", 100)] < m[k(bus, "awake_pct", 400)]
    # the bus wait is per byte: ~45x faster on SPI, less awake at every rate
    assert all(m[k("spi", "awake_pct", r)] < m[k("i2c", "awake_pct", r)] for r in bench_sleep.RATES)
    print(bench_sleep.format_sleep(m))


def test_the_current_estimate_weighs_the_datasheets_figures_by_the_awake_share():
    from accelcal.studies import bench_sleep
    # RP2040 datasheet Table 637 (typical DVDD): 9.4 mA running, 0.39 mA in SLEEP
    assert (bench_sleep.RUN_MA, bench_sleep.SLEEP_MA) == (9.4, 0.39)
    assert bench_sleep.current_ma(0.0) == pytest.approx(0.39)
    assert bench_sleep.current_ma(100.0) == pytest.approx(9.4)
    assert bench_sleep.current_ma(2.0) == pytest.approx(0.02 * 9.4 + 0.98 * 0.39)   # 0.570 mA
    m = {bench_sleep.key(b, k, r): v * (1 if b == "i2c" else 0.5) for r in bench_sleep.RATES
         for b in bench_sleep.BUSES
         for k, v in (("awake_pct", 2.0), ("wakeups_per_s", r / 25), ("lost", 0))}
    text = bench_sleep.format_sleep(m)
    assert "I2C: 10 Hz ~0.57 mA, 100 Hz ~0.57 mA" in text and "Table 637" in text
    assert "SPI: 10 Hz ~0.48 mA" in text and "SPI 100 Hz: 1.00 % of the cycles awake" in text


def test_each_boards_figures_print_under_its_name():
    from accelcal.studies import bench_sleep
    m = {bench_sleep.key(b, k, r, "feather"): v for r in bench_sleep.RATES for b in bench_sleep.BUSES
         for k, v in (("awake_pct", 8.0 if b == "i2c" else 2.5), ("wakeups_per_s", r / 25), ("lost", 0))}
    assert all(k.startswith("rp2040_circuitpython_") for k in m)
    text = bench_sleep.format_sleep(m)
    assert "Feather RP2040 (CircuitPython)" in text and "Pico" not in text
    assert "SPI 100 Hz: 2.50 % of the cycles awake" in text and "I2C 100 Hz: 8.00 %" in text
