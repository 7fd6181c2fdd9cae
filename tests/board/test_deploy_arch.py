"""`accelcal deploy` compiles the package for the architecture the board reports
(sys.implementation._mpy >> 10; issue 49): a board running the esp32 port gets xtensawin on an
ESP32/S3 and rv32imc on an ESP32-C3/C6 from the one board file, a Pico armv6m; a port without
emitters gets the sources.  Against a stand-in for mpremote that answers as such a board would
and keeps what deploy copies."""
import pytest

from accelcal.board import deploy

# sys.implementation._mpy of MicroPython 1.28 (.mpy v6.3) on each: version | 3 << 8 | arch << 10;
# 12038 is what the RV32 firmware of firmware/rv32 reports (docs/boards-and-logs.md)
MPY = {"armv6m": 6 | 3 << 8 | 4 << 10, "xtensawin": 6 | 3 << 8 | 10 << 10,
       "rv32imc": 12038, None: 6 | 3 << 8}


def fake_remote(platform, mpy, copied):
    class Board(deploy.Remote):
        def __init__(self, port, timeout=0):
            self.port = port

        def exec(self, code, stream=None, timeout=None):
            if code.startswith("import sys, os"):          # identify()
                return f"ACAL micropython {platform} {mpy}\nFILES boot.py:100\n"
            return "ACAL_OK 1\n" if "ACAL_OK" in code else ""

        def run(self, *args, stream=None, timeout=None):   # fs cp FILES... :lib/acal/ + ...
            end = args.index(":lib/acal/")
            for f in args[2:end]:
                with open(f, "rb") as fh:
                    copied[f.rsplit("/", 1)[-1]] = fh.read()
            return ""
    return Board


@pytest.mark.parametrize("platform,board,arch", [("esp32", "esp32", "xtensawin"),
                                                 ("esp32", "esp32", "rv32imc"),
                                                 ("rp2", "pico", "armv6m"),
                                                 ("esp32", "esp32", None)])
def test_deploy_compiles_for_the_arch_the_board_reports(monkeypatch, platform, board, arch):
    assert deploy.mpy_arch(MPY[arch]) == arch
    copied = {}
    monkeypatch.setattr(deploy, "Remote", fake_remote(platform, MPY[arch], copied))
    r = deploy.deploy("fake", write_main=False)
    assert r["board"] == board and r["arch"] == arch
    assert sorted(copied) == sorted(m + (".mpy" if arch else ".py") for m in deploy.APP_MODULES)
    if arch:
        # the modules with viper code carry the arch in their header (byte 2 >> 2), the rest
        # are bytecode (0), loadable anywhere
        archs = {deploy.MPY_ARCHS[data[2] >> 2] for data in copied.values()}
        assert archs == {arch, None} and copied["wide.mpy"][2] >> 2 == MPY[arch] >> 10
    else:
        assert b"@viper" in copied["wide.py"]


def test_a_board_file_without_arch_and_a_port_without_mpy_keep_theirs():
    virtual = deploy.board_info("virtual")
    assert deploy.board_arch(virtual, {"arch": "x64"}) is None     # the sources, as before
    esp32 = deploy.board_info("esp32")
    assert deploy.board_arch(esp32, {}) == "xtensawin"             # _mpy not reported
    assert deploy.board_arch(esp32, {"arch": "rv32imc"}) == "rv32imc"
    assert deploy.board_arch(esp32, {"arch": "armv6"}) is None     # no viper emitter built for it
