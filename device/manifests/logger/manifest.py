# The install unit `logger` of the device package acal, for a MicroPython firmware that freezes
# only the units its board runs: in the board's manifest (FROZEN_MANIFEST), include() this folder
# for each unit: core and logger on every board, paper for the paper profile, discover for
# --discover.  Written by tools/units.py from the walk deploy copies (host/accelcal/board/tree.py);
# device/logger.json is the same unit for mip.  The sources as they are: `make build` writes
# build/BOARD/freeze/ with the same units and the hot loops compiled as viper.
include("../core")
package(
    "acal",
    files=[
        "logger/app.py",
        "logger/lis3dh.py",
        "logger/lis3dh_spi.py",
        "logger/log.py",
        "logger/processor.py",
    ],
    base_path="../..",
)
