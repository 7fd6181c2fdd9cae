# The native emitters, from one source (docs/method-and-formats.md "Emitters").
#
# A hot loop is written once, as plain Python marked `@viper` (this module's no-op decorator),
# with its arrays read through ptr32() (here: the array itself).  CPython, the WebAssembly port
# and CircuitPython (no emitters) run it as it stands.  The .mpy build for a port with emitters
# (armv6m, xtensawin, rv32imc: accelcal/bridge/rp2040.py emitted_source) rewrites the marker line into
# `@micropython.viper`, which MicroPython's compiler recognises by name; inside a viper function
# ptr32(...) is then its typed pointer, the name this module defines is not called.
# Viper ints are machine words that wrap at 32 bits: every value in a marked function is proven
# below 2**30 by tests/device/test_ranges.py.

import sys

# A viper int is a machine word: on a 64-bit MicroPython (the unix port the tests run) a ptr32
# load is zero-extended, so a marked function reads each signed int32 as int(p[i]) << w >> w with
# w = SIGN_SHIFT: 32 there, 0 on the 32-bit boards (where it costs nothing) and on CPython.
SIGN_SHIFT = 32 if sys.implementation.name == "micropython" and sys.maxsize >> 32 else 0


def viper(f):
    return f


def ptr32(a):
    return a


def ptr8(a):
    return a


@viper
def copy_ints(src, at: int, dst, to: int, n: int):
    # n words of the int32 array src from index at into dst from index to, in a viper loop on
    # ports with emitters (a word copied as it is: no sign extension needed): bins.gather's
    # copies (126 points and their conditions: 0.93 ms on an RP2040, 11.5 ms as Python loops)
    s = ptr32(src)
    d = ptr32(dst)
    i = 0
    while i < n:
        d[to + i] = s[at + i]
        i += 1
