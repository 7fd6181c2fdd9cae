# The install unit `discover` of the device package acal, for a MicroPython firmware that freezes
# only the units its board runs: in the board's manifest (FROZEN_MANIFEST), include() this folder
# for each unit: core and logger on every board, paper for the paper profile, discover for
# --discover.  Written by tools/units.py from the walk deploy copies (host/accelcal/board/tree.py);
# device/discover.json is the same unit for mip.  The sources as they are: `make build` writes
# build/BOARD/freeze/ with the same units and the hot loops compiled as viper.
include("../core")
package(
    "acal",
    files=[
        "discover/heldout.py",
        "discover/plug.py",
        "discover/rule.py",
        "discover/score.py",
        "discover/search.py",
        "discover/stepplace.py",
    ],
    base_path="../..",
)
