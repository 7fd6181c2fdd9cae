"""The board's choice among candidate effects (device/acal/discover/candidates.py, issue 29): the lowest
held-out error, a step giving way to a plain effect within 1.5x of it, untestable ones skipped,
adoption only under the naming rule (10 % lower, 70 % of blocks) - the rule diagnose states."""
from acal.discover import candidates
from acal.core.effects import DRIFT, STEP, TEMP_OFFSET


def test_lowest_error_wins_and_untestable_are_skipped():
    assert candidates.best((TEMP_OFFSET, DRIFT), (80, 60), 2) == 1
    assert candidates.best((TEMP_OFFSET, DRIFT), (-1, 60), 2) == 1
    assert candidates.best((TEMP_OFFSET, DRIFT), (-1, -1), 2) == -1


def test_a_step_gives_way_to_a_plain_effect_within_its_parsimony_factor():
    kinds = (TEMP_OFFSET, STEP)
    assert candidates.best(kinds, (150, 100), 2) == 0     # 1.5x the step's: plain preferred
    assert candidates.best(kinds, (151, 100), 2) == 1     # past 1.5x: the step
    assert candidates.best((STEP,), (100,), 1) == 0       # no plain one to prefer


def test_adopted_only_under_the_naming_rule():
    errs, betters = (90, 91), (7, 7)
    assert candidates.adopted(100, errs, betters, 10, 0)      # 10 % lower, 7 of 10 blocks
    assert not candidates.adopted(100, errs, betters, 10, 1)  # 9 % lower
    assert not candidates.adopted(100, errs, (6, 7), 10, 0)   # 6 of 10 blocks
    assert not candidates.adopted(100, errs, betters, 10, -1)
