# `accelcal bench --runtime rp2040`: what a board pays for the device package's install units
# (docs/boards-and-logs.md "Install units"), on a fresh boot each (host/accelcal/studies/
# bench_chip.py appends main(WHAT)): `import acal.logger.app` timed and the heap free after it,
# then a Processor made as the board runs it and the heap free with it, and the acal modules
# loaded.  WHAT: "base" (core + logger: the wear profile's base model), "paper" (the paper
# profile: + acal.paper), "discover" (a discovering board: + acal.discover), "all" (every module
# of every unit imported).  Prints "key value" lines, the modules as a count and a list.
import gc
import os
import sys
import time

ticks = getattr(time, "ticks_us", None) or (lambda: time.monotonic_ns() // 1000)


def main(what):
    gc.collect()
    free0 = gc.mem_free()
    t0 = ticks()
    import acal.logger.app   # noqa: F401
    dt = time.ticks_diff(ticks(), t0) if hasattr(time, "ticks_diff") else ticks() - t0
    gc.collect()
    free1 = gc.mem_free()
    from acal.logger.processor import Processor
    from acal.core import profile
    if what == "paper":
        proc = Processor(None, 100, profile=profile.PAPER)
    elif what == "base":
        proc = Processor(None, 100)
    else:
        proc = Processor(None, 100, discover=True)
    if what == "all":
        for unit in ("core", "logger", "paper", "discover"):
            for f in sorted(os.listdir("/lib/acal/" + unit)):
                name = f.rsplit(".", 1)[0]
                if name != "__init__" and name != "lis3dh_cp":
                    __import__("acal.%s.%s" % (unit, name))
    gc.collect()
    free2 = gc.mem_free()
    mods = sorted(m for m in sys.modules if m.startswith("acal"))
    print("units_%s_import_app_us %d" % (what, dt))
    print("units_%s_free_before_bytes %d" % (what, free0))
    print("units_%s_free_after_import_bytes %d" % (what, free1))
    print("units_%s_free_with_processor_bytes %d" % (what, free2))
    print("units_%s_modules %d" % (what, len(mods)))
    print("units_%s_discover_modules %d" % (what, len([m for m in mods if m.startswith("acal.discover")])))
    print("units_%s_paper_modules %d" % (what, len([m for m in mods if m.startswith("acal.paper")])))
    print("loaded_%s %s" % (what, ",".join(mods)))
    return proc
