"""tools/chip_profile.py: where a script's cycles go on the emulated Pico, by firmware function.
Every cycle the run's --stats counts is in the profile (no more, no fewer), the names come from
the firmware's symbols (the interpreter's loop for bytecode, RAM for viper's native code), and
the same script twice on fresh boots gives the same profile to the cycle, so --minus cancels
what two scripts share.  Bad input: one line, exit 2."""
import shutil
import subprocess
import sys

import pytest

from conftest import ROOT

TOOL = ROOT / "tools" / "chip_profile.py"
sys.path.insert(0, str(ROOT / "tools"))
import chip_profile  # noqa: E402

SCRIPT = """from acal.core.emit import viper


@viper
def native(n: int) -> int:
    s = 0
    i = 0
    while i < n:
        s += i
        i += 1
    return s


def interpreted(n):
    s = 0
    for i in range(n):
        s += i
    return s


print(native(20000), interpreted(2000))
"""


@pytest.mark.parametrize("args, says", [(["/no/such/script.py"], "is not a file"),
                                        ([__file__, "--rev", "no-such-revision"],
                                         "is not a revision")])
def test_bad_input_is_one_line(args, says):
    r = subprocess.run([sys.executable, str(TOOL), *args], capture_output=True, text=True,
                       timeout=120)
    assert r.returncode == 2 and r.stdout == ""
    assert r.stderr.count("\n") == 1 and says in r.stderr and "Traceback" not in r.stderr


@pytest.mark.skipif(shutil.which("nm") is None, reason="binutils' nm reads the firmware's symbols")
def test_the_profile_holds_every_cycle_and_names_the_firmwares_functions():
    prof, cycles = chip_profile.profile(SCRIPT)
    assert sum(prof.values()) == cycles > 0
    again, _ = chip_profile.profile(SCRIPT)
    assert again == prof       # deterministic: a script minus itself is nothing
    addrs, names = chip_profile.symbols()
    funcs = chip_profile.by_function(prof, addrs, names)
    assert sum(funcs.values()) == cycles
    top = sorted(funcs, key=funcs.get, reverse=True)[:5]
    assert "mp_execute_bytecode" in top and "RAM: native code" in funcs, top
    # the viper loop's 20 000 rounds run in RAM, at least an add, an increment, a compare each
    assert funcs["RAM: native code"] >= 3 * 20000
