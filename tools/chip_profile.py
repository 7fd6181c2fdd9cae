"""Where a script's cycles go on the emulated Pico, by firmware function: the script runs on a
fresh boot (rp2040.run_script, the package installed), every cycle it takes is counted at the
address of the instruction that took it (rp2040.mjs --profile), and the addresses are named by
the firmware's symbols (firmware/micropython-rp2040/firmware-nodebug.elf, read with nm).

    python tools/chip_profile.py SCRIPT [--minus BASE] [--rev REV] [--top 30]

--minus BASE: BASE's profile taken away, address by address (BASE: the same set-up without the
part to profile; the emulator is deterministic, so what both do cancels).  --rev REV: REV's
device package (`git archive`, as tools/units_at.py) instead of this checkout's.  Code in RAM is
the native code viper compiled ("RAM: native code"), below 0x4000 the boot ROM.  Prints one line
a function: cycles, share of the total, name; the total first.  Found with it (docs/notes/
boards-and-logs.md): gc_alloc took 30 % of the Processor's per-sample cycles, its calls' frames.
"""
import argparse
import bisect
import json
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path[:0] = [str(ROOT / "host"), str(ROOT / "device")]

from accelcal.bridge import rp2040  # noqa: E402

ELF = ROOT / "firmware" / "micropython-rp2040" / "firmware-nodebug.elf"


def symbols(elf: Path = ELF) -> tuple[list[int], list[str]]:
    """The ELF's code symbols (nm: t, T, w, W), sorted by address, Thumb bit cleared."""
    out = subprocess.run(["nm", "-n", "--defined-only", str(elf)], capture_output=True, text=True,
                         check=True).stdout
    syms = sorted((int(a, 16) & ~1, name) for a, kind, name in
                  (line.split()[:3] for line in out.splitlines() if len(line.split()) >= 3)
                  if kind in "tTwW" and not name.startswith("$"))
    return [a for a, _ in syms], [n for _, n in syms]


def name_of(pc: int, addrs: list[int], names: list[str]) -> str:
    if pc < 0x4000:
        return "boot ROM"
    if pc >= 0x20000000:
        return "RAM: native code"
    i = bisect.bisect_right(addrs, pc) - 1
    return names[i] if i >= 0 else "?"


def profile(code: str, image: Path | None = None) -> tuple[dict[int, int], int]:
    """The script's cycles by instruction address, and its cycles as --stats counts them."""
    with tempfile.TemporaryDirectory() as tmp:
        f = Path(tmp) / "profile.json"
        run = rp2040.run_script(code, image=image, profile=f)
        return {int(k): v for k, v in json.loads(f.read_text()).items()}, run.cycles


def by_function(prof: dict[int, int], addrs: list[int], names: list[str]) -> dict[str, int]:
    out: dict[str, int] = {}
    for pc, c in prof.items():
        n = name_of(pc, addrs, names)
        out[n] = out.get(n, 0) + c
    return out


def main(argv: list[str]) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("script", type=Path)
    ap.add_argument("--minus", type=Path, help="a set-up script whose profile is taken away")
    ap.add_argument("--rev", help="an older revision's device package (git archive)")
    ap.add_argument("--top", type=int, default=30)
    a = ap.parse_args(argv)
    for f in (a.script, a.minus):
        if f is not None and not f.is_file():
            print(f"chip_profile: {f} is not a file", file=sys.stderr)
            return 2
    if not ELF.is_file():
        print(f"chip_profile: {ELF} is missing (the firmware's symbols)", file=sys.stderr)
        return 2
    if shutil.which("nm") is None:
        print("chip_profile: nm (binutils) is not installed: it reads the firmware's symbols",
              file=sys.stderr)
        return 2
    addrs, names = symbols()
    with tempfile.TemporaryDirectory() as tmp:
        image = None
        if a.rev:   # the older tree's package on a flash image of its own (as units_at.py)
            import units_at
            try:
                old = units_at.old_package(a.rev, Path(tmp))
            except SystemExit as e:
                print(str(e.code).replace("units_at", "chip_profile"), file=sys.stderr)
                return 2
            image = Path(tmp) / "old.bin"
            shutil.copyfile(rp2040.flash_image(rp2040.MICROPYTHON, old), image)
        prof, cycles = profile(a.script.read_text(), image)
        if a.minus:
            base, base_cycles = profile(a.minus.read_text(), image)
            for pc, c in base.items():
                prof[pc] = prof.get(pc, 0) - c
            cycles -= base_cycles
    funcs = by_function(prof, addrs, names)
    total = sum(funcs.values())
    print(f"{total:>14,} cycles ({total / rp2040.HZ * 1e3:.1f} ms at 125 MHz)"
          + ("" if total == cycles else f"; --stats counted {cycles:,}"))
    for n, c in sorted(funcs.items(), key=lambda kv: -abs(kv[1]))[:a.top]:
        print(f"{c:>14,} {100 * c / total if total else 0:6.1f} %  {n}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
