"""`accelcal deploy` compiles the package for the architecture the board reports
(sys.implementation._mpy >> 10; issue 49): a board running the esp32 port gets xtensawin on an
ESP32/S3 and rv32imc on an ESP32-C3/C6 from the one board file, a Pico armv6m; a port without
emitters gets the sources.  Against a stand-in for mpremote answering identify() as such a board
would (the real Remote parses its printout), stopped where deploy compiles; the .mpy each arch
gives carry it in their header (tests/device/test_integer_only.py)."""
import pytest

from accelcal.board import deploy

# sys.implementation._mpy of MicroPython 1.28 (.mpy v6.3) on each: version | 3 << 8 | arch << 10;
# 12038 is what the RV32 firmware of firmware/rv32 reports (bridge/rv32.py)
MPY = {"armv6m": 6 | 3 << 8 | 4 << 10, "xtensawin": 6 | 3 << 8 | 10 << 10,
       "rv32imc": 12038, None: 6 | 3 << 8}


class Compiling(Exception):
    """Raised where deploy hands the package to the compiler: what it chose is recorded."""


def fake_remote(platform, mpy):
    class Board(deploy.Remote):
        def __init__(self, port, timeout=0):
            self.port = port
            self.timeout = timeout

        def exec(self, code, stream=None, timeout=None):   # identify()'s probe
            assert code.startswith("import sys, os")
            return f"ACAL micropython {platform} {mpy}\nFILES boot.py:100\n"
    return Board


@pytest.mark.parametrize("platform,board,arch", [("esp32", "esp32", "xtensawin"),
                                                 ("esp32", "esp32", "rv32imc"),
                                                 ("rp2", "pico", "armv6m"),
                                                 ("esp32", "esp32", None)])
def test_deploy_compiles_for_the_arch_the_board_reports(monkeypatch, platform, board, arch):
    assert deploy.mpy_arch(MPY[arch]) == arch
    monkeypatch.setattr(deploy, "Remote", fake_remote(platform, MPY[arch]))
    chosen = []

    def package_files(info, *args, **kwargs):
        chosen.append((info["name"], info["ARCH"]))
        raise Compiling
    monkeypatch.setattr(deploy, "package_files", package_files)
    with pytest.raises(Compiling):
        deploy.deploy("fake", write_main=False)
    assert chosen == [(board, arch)]


def test_a_board_file_without_arch_and_a_port_without_mpy_keep_theirs():
    virtual = deploy.board_info("virtual")
    assert deploy.board_arch(virtual, {"arch": "x64"}) is None     # the sources, as before
    esp32 = deploy.board_info("esp32")
    assert deploy.board_arch(esp32, {}) == "xtensawin"             # _mpy not reported
    assert deploy.board_arch(esp32, {"arch": "rv32imc"}) == "rv32imc"
    assert deploy.board_arch(esp32, {"arch": "armv6"}) is None     # no viper emitter built for it
