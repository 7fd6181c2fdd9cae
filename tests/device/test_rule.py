"""The acceptance rule of model discovery (acal/discover/rule.py): one definition for the host's
diagnose and the board, at its edges, and the same decisions under MicroPython; the board's choice
among candidate effects (best, adopted): the lowest held-out error, a step giving way to a plain
effect within 1.5x of it, untestable ones skipped, adoption only under the naming rule (10 % lower,
70 % of blocks) - the rule diagnose states."""
from acal.discover import rule
from acal.core.effects import DRIFT, STEP, TEMP_OFFSET
from accelcal.bridge import runtime
from accelcal.pipeline import diagnose


def test_the_rule_at_its_edges():
    assert rule.improves(100, 90) and not rule.improves(100, 91)
    assert rule.share_holds(7, 10) and not rule.share_holds(6, 10)
    assert rule.share_holds(3, 3) and not rule.share_holds(2, 3)
    assert rule.names(100, 90, 7, 10)
    assert not rule.names(100, 90, 6, 10) and not rule.names(100, 95, 10, 10)
    # a step is kept only when the best plain effect is more than 1.5x its held-out error
    assert rule.plain_preferred(2.0, 3.0) and not rule.plain_preferred(2.0, 3.01)


def test_lowest_error_wins_and_untestable_are_skipped():
    assert rule.best((TEMP_OFFSET, DRIFT), (80, 60), 2) == 1
    assert rule.best((TEMP_OFFSET, DRIFT), (-1, 60), 2) == 1
    assert rule.best((TEMP_OFFSET, DRIFT), (-1, -1), 2) == -1


def test_a_step_gives_way_to_a_plain_effect_within_its_parsimony_factor():
    kinds = (TEMP_OFFSET, STEP)
    assert rule.best(kinds, (150, 100), 2) == 0     # 1.5x the step's: plain preferred
    assert rule.best(kinds, (151, 100), 2) == 1     # past 1.5x: the step
    assert rule.best((STEP,), (100,), 1) == 0       # no plain one to prefer


def test_adopted_only_under_the_naming_rule():
    errs, betters = (90, 91), (7, 7)
    assert rule.adopted(100, errs, betters, 10, 0)      # 10 % lower, 7 of 10 blocks
    assert not rule.adopted(100, errs, betters, 10, 1)  # 9 % lower
    assert not rule.adopted(100, errs, (6, 7), 10, 0)   # 6 of 10 blocks
    assert not rule.adopted(100, errs, betters, 10, -1)


def test_diagnose_decides_by_it():
    assert diagnose.MIN_IMPROVEMENT_PCT == rule.MIN_IMPROVEMENT_PCT == 10
    assert diagnose.MIN_BLOCK_SHARE == rule.MIN_BLOCK_SHARE_PCT / 100 == 0.7
    assert diagnose.STEP_PARSIMONY == 1.5


def test_few_blocks_are_weak_evidence_by_an_exact_sign_test():
    """rule.clear against the binomial tail computed here with exact fractions: clear when
    the share is named and chance alone sees that many blocks better at most 1 time in 20."""
    from fractions import Fraction
    from math import comb
    for n in range(1, rule.SIGN_BLOCKS + 6):
        for k in range(n + 1):
            p = Fraction(sum(comb(n, j) for j in range(k, n + 1)), 2 ** n)
            assert rule.clear(k, n) == (rule.share_holds(k, n) and p <= Fraction(1, 20))
    # 3 of 3 (1 in 8) and 4 of 5 (6 in 32) weak; 5 of 5, 6 of 6 and 12 of 14 clear
    assert not rule.clear(3, 3) and not rule.clear(4, 5)
    assert rule.clear(5, 5) and rule.clear(6, 6) and rule.clear(12, 14)


def test_above_the_exact_range_a_named_share_passes_the_sign_test():
    """Why clear() trusts the share above SIGN_BLOCKS blocks: the fewest blocks better that the
    share names (70 %, rounded up) passes the sign test for every count to 10 000 (the tail by
    scipy's binomial, an independent computation)."""
    import numpy as np
    from scipy.stats import binom
    n = np.arange(rule.SIGN_BLOCKS + 1, 10_001)
    fewest = -(-rule.MIN_BLOCK_SHARE_PCT * n // 100)
    assert all(rule.share_holds(int(k), int(m)) and not rule.share_holds(int(k) - 1,
                                                                                   int(m))
               for k, m in zip(fewest[:200], n[:200]))
    assert binom.sf(fewest - 1, n, 0.5).max() <= 1 / rule.CHANCE_ONE_IN


def test_the_sign_test_stays_in_small_ints():
    from accelcal.bridge.ranges import SMALL_INT_LIMIT, Tracer, traced
    tracer = Tracer()
    T = traced(tracer)
    for n in range(1, rule.SIGN_BLOCKS + 1):
        for k in range(n + 1):
            rule.clear(T(k), T(n))
    assert tracer.ops > 0 and tracer.max_abs < SMALL_INT_LIMIT and tracer.big == 0
    assert rule.CHANCE_ONE_IN << rule.SIGN_BLOCKS < SMALL_INT_LIMIT


CASES = [(b, a, k, n) for b in (1000, 2047, 5) for a in range(0, 1200, 37)
         for n in (3, 5, 10, 18, 25, 26) for k in range(n + 1)]

SCRIPT = r'''
from acal.discover import rule
out = []
for b, a, k, n in %r:
    out.append("1" if rule.names(b, a, k, n) else "0")
    out.append("1" if rule.plain_preferred(a + 1, b) else "0")
    out.append("1" if rule.clear(k, n) else "0")
print("".join(out))
'''


def test_the_board_decides_as_the_host(tmp_path):
    f = tmp_path / "rule.py"
    f.write_text(SCRIPT % (CASES,))
    got = runtime.run_micropython_script(str(f)).strip()
    want = "".join(("1" if rule.names(b, a, k, n) else "0") +
                   ("1" if rule.plain_preferred(a + 1, b) else "0") +
                   ("1" if rule.clear(k, n) else "0") for b, a, k, n in CASES)
    assert got == want and "1" in want and "0" in want
