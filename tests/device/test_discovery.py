"""The acceptance rule of model discovery (acal/discover/rule.py): one definition for the host's
diagnose and the board, at its edges, and the same decisions under MicroPython."""
from acal.discover import rule as discovery
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


def test_few_blocks_are_weak_evidence_by_an_exact_sign_test():
    """discovery.clear against the binomial tail computed here with exact fractions: clear when
    the share is named and chance alone sees that many blocks better at most 1 time in 20."""
    from fractions import Fraction
    from math import comb
    for n in range(1, discovery.SIGN_BLOCKS + 6):
        for k in range(n + 1):
            p = Fraction(sum(comb(n, j) for j in range(k, n + 1)), 2 ** n)
            assert discovery.clear(k, n) == (discovery.share_holds(k, n) and p <= Fraction(1, 20))
    # 3 of 3 (1 in 8) and 4 of 5 (6 in 32) weak; 5 of 5, 6 of 6 and 12 of 14 clear
    assert not discovery.clear(3, 3) and not discovery.clear(4, 5)
    assert discovery.clear(5, 5) and discovery.clear(6, 6) and discovery.clear(12, 14)


def test_above_the_exact_range_a_named_share_passes_the_sign_test():
    """Why clear() trusts the share above SIGN_BLOCKS blocks: the fewest blocks better that the
    share names (70 %, rounded up) passes the sign test for every count to 10 000 (the tail by
    scipy's binomial, an independent computation)."""
    import numpy as np
    from scipy.stats import binom
    n = np.arange(discovery.SIGN_BLOCKS + 1, 10_001)
    fewest = -(-discovery.MIN_BLOCK_SHARE_PCT * n // 100)
    assert all(discovery.share_holds(int(k), int(m)) and not discovery.share_holds(int(k) - 1,
                                                                                   int(m))
               for k, m in zip(fewest[:200], n[:200]))
    assert binom.sf(fewest - 1, n, 0.5).max() <= 1 / discovery.CHANCE_ONE_IN


def test_the_sign_test_stays_in_small_ints():
    from accelcal.bridge.ranges import SMALL_INT_LIMIT, Tracer, traced
    tracer = Tracer()
    T = traced(tracer)
    for n in range(1, discovery.SIGN_BLOCKS + 1):
        for k in range(n + 1):
            discovery.clear(T(k), T(n))
    assert tracer.ops > 0 and tracer.max_abs < SMALL_INT_LIMIT and tracer.big == 0
    assert discovery.CHANCE_ONE_IN << discovery.SIGN_BLOCKS < SMALL_INT_LIMIT


CASES = [(b, a, k, n) for b in (1000, 2047, 5) for a in range(0, 1200, 37)
         for n in (3, 5, 10, 18, 25, 26) for k in range(n + 1)]

SCRIPT = r'''
from acal.discover import rule as discovery
out = []
for b, a, k, n in %r:
    out.append("1" if discovery.names(b, a, k, n) else "0")
    out.append("1" if discovery.plain_preferred(a + 1, b) else "0")
    out.append("1" if discovery.clear(k, n) else "0")
print("".join(out))
'''


def test_the_board_decides_as_the_host(tmp_path):
    f = tmp_path / "rule.py"
    f.write_text(SCRIPT % (CASES,))
    got = runtime.run_micropython_script(str(f)).strip()
    want = "".join(("1" if discovery.names(b, a, k, n) else "0") +
                   ("1" if discovery.plain_preferred(a + 1, b) else "0") +
                   ("1" if discovery.clear(k, n) else "0") for b, a, k, n in CASES)
    assert got == want and "1" in want and "0" in want
