# The device app's cost per sample and its log growth, inside the MicroPython unix port (started
# by host/accelcal/bench.py with the simulator on the path).  argv: stimulus, work dir, rate,
# samples to time, seconds to run for the log.  Prints "key value" lines.
import gc
import os
import sys
import time

from simboard import SimBoard as Board


def sim_only(board, n, period):
    # What the simulator costs for n register reads: the same bus calls, no app.
    buf = bytearray(6)
    bus = board.bus
    clock = board.clock
    t = time.ticks_us()
    for _ in range(n):
        clock.sleep_us(period)
        bus.readfrom_mem_into(0x18, 0xA8, buf)
    return time.ticks_diff(time.ticks_us(), t)


def main():
    from acal.logger.app import App
    stim, work, rate, n, seconds = sys.argv[1], sys.argv[2], int(sys.argv[3]), int(sys.argv[4]), int(sys.argv[5])
    os.chdir(work)
    for fifo in (0, 1):
        for f in ("log.bin", "cal_a.bin", "cal_b.bin"):
            try:
                os.remove(f)
            except OSError:
                pass
        app = App(Board(stim), rate_hz=rate, fifo=bool(fifo))
        gc.collect()
        t = time.ticks_us()
        while app.samples + app.lost < n:
            app.step()
        total = time.ticks_diff(time.ticks_us(), t)
        print("app_us_fifo%d" % fifo, total)
        print("samples_fifo%d" % fifo, app.samples + app.lost)
    print("sim_us", sim_only(Board(stim), n, 1000000 // rate))
    # Log growth: run the register app over the whole stimulus.
    for f in ("log.bin", "cal_a.bin", "cal_b.bin"):
        try:
            os.remove(f)
        except OSError:
            pass
    app = App(Board(stim), rate_hz=rate)
    app.run(seconds)
    print("log_bytes", app.log.size)
    print("log_seconds", (app.samples + app.lost) // rate)
    print("rest_logged", app.proc.rest_logged)
    print("rest_skipped", app.proc.rest_skipped)
    print("calibrations", app.proc.calibrations)


main()
