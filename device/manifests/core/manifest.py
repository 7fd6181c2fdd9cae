# The install unit `core` of the device package acal, for a MicroPython firmware that freezes
# only the units its board runs: in the board's manifest (FROZEN_MANIFEST), include() this folder
# for each unit: core and logger on every board, paper for the paper profile, discover for
# --discover.  Written by tools/units.py from the walk deploy copies (host/accelcal/board/tree.py);
# device/core.json is the same unit for mip.  The sources as they are: `make build` writes
# build/BOARD/freeze/ with the same units and the hot loops compiled as viper.
package(
    "acal",
    files=[
        "__init__.py",
        "core/bins.py",
        "core/calibration.py",
        "core/changepoint.py",
        "core/effects.py",
        "core/emit.py",
        "core/fixed.py",
        "core/gaussnewton.py",
        "core/hemisphere.py",
        "core/model.py",
        "core/normal_sums.py",
        "core/pipeline.py",
        "core/profile.py",
        "core/reference.py",
        "core/rest.py",
        "core/solve.py",
        "core/status.py",
        "core/wide.py",
    ],
    base_path="../..",
)
