"""The acceptance rule of model discovery (acal/discovery.py): one definition for the host's
diagnose and the board, at its edges, and the same decisions under MicroPython."""
from acal import discovery
from accelcal.bridge import runtime
from accelcal.pipeline import diagnose


def test_the_rule_at_its_edges():
    assert discovery.improves(100, 90) and not discovery.improves(100, 91)
    assert discovery.share_holds(7, 10) and not discovery.share_holds(6, 10)
    assert discovery.share_holds(3, 3) and not discovery.share_holds(2, 3)
    assert discovery.names(100, 90, 7, 10)
    assert not discovery.names(100, 90, 6, 10) and not discovery.names(100, 95, 10, 10)
    # a step is kept only when the best plain effect is more than 1.5x its held-out error
    assert discovery.plain_preferred(2.0, 3.0) and not discovery.plain_preferred(2.0, 3.01)


def test_diagnose_decides_by_it():
    assert diagnose.MIN_IMPROVEMENT_PCT == discovery.MIN_IMPROVEMENT_PCT == 10
    assert diagnose.MIN_BLOCK_SHARE == discovery.MIN_BLOCK_SHARE_PCT / 100 == 0.7
    assert diagnose.STEP_PARSIMONY == 1.5


CASES = [(b, a, k, n) for b in (1000, 2047, 5) for a in range(0, 1200, 37) for n in (3, 10, 18)
         for k in range(n + 1)]

SCRIPT = r'''
from acal import discovery
out = []
for b, a, k, n in %r:
    out.append("1" if discovery.names(b, a, k, n) else "0")
    out.append("1" if discovery.plain_preferred(a + 1, b) else "0")
print("".join(out))
'''


def test_the_board_decides_as_the_host(tmp_path):
    f = tmp_path / "rule.py"
    f.write_text(SCRIPT % (CASES,))
    got = runtime.run_micropython_script(str(f)).strip()
    want = "".join(("1" if discovery.names(b, a, k, n) else "0") +
                   ("1" if discovery.plain_preferred(a + 1, b) else "0") for b, a, k, n in CASES)
    assert got == want and "1" in want and "0" in want
