# Model discovery's acceptance rule, in integers: the one definition by which the host's
# `diagnose` names a missing effect and the board's own discovery (issue 29) adopts one: which
# candidate is named (best) and whether it is adopted (adopted, names).
# A candidate effect, fitted on the training blocks, is named when it lowers the held-out error
# by at least MIN_IMPROVEMENT_PCT and does so in at least MIN_BLOCK_SHARE_PCT of the held-out
# blocks (an effect is systematic: a fit that only chases noise improves some blocks and
# worsens others).  A change-point effect (a step) has a free split, so it is preferred to the
# best effect without one only when that one's held-out error is over STEP_PARSIMONY_TENTHS / 10
# times the step's.  The errors may be any numbers of one unit (mg on the host, the board's
# integers there: score.py's, -1 not testable); the comparisons are products, no division, and
# nothing allocates.
# A share of few blocks is weak evidence: 3 of 3 blocks better happens one time in eight by
# chance alone.  A named effect is clear evidence when a one-sided sign test (each block better
# or worse as a fair coin toss) sees that many blocks better at most one time in CHANCE_ONE_IN;
# otherwise it is named as weak evidence, to be confirmed on a longer recording.
try:
    from micropython import const
except ImportError:  # CPython
    def const(x):
        return x

from acal.core.effects import STEP

MIN_IMPROVEMENT_PCT = const(10)
MIN_BLOCK_SHARE_PCT = const(70)
STEP_PARSIMONY_TENTHS = const(15)
CHANCE_ONE_IN = const(20)
# The sign test is exact in integers up to SIGN_BLOCKS blocks (CHANCE_ONE_IN * 2**25 < 2**30);
# above it, every share that share_holds passes the test (each count to 10 000 checked in
# tests/device/test_rule.py), so the share decides alone.
SIGN_BLOCKS = const(25)


def share_holds(better, blocks):
    """True when `better` of `blocks` held-out blocks is at least MIN_BLOCK_SHARE_PCT."""
    return 100 * better >= MIN_BLOCK_SHARE_PCT * blocks


def improves(before, after):
    """True when the held-out error falls from `before` by at least MIN_IMPROVEMENT_PCT."""
    return 100 * (before - after) >= MIN_IMPROVEMENT_PCT * before


def names(before, after, better, blocks):
    """The rule: a candidate whose held-out error is `after` (the model without it: `before`),
    better in `better` of `blocks` held-out blocks, is named."""
    return improves(before, after) and share_holds(better, blocks)


def plain_preferred(step_error, plain_error):
    """True when the best effect without a change point (held-out error plain_error) is
    preferred to the best step (step_error): it comes within the step's parsimony factor."""
    return 10 * plain_error <= STEP_PARSIMONY_TENTHS * step_error


def clear(better, blocks):
    """True when `better` of `blocks` held-out blocks is a share the rule names (share_holds)
    and more than chance: the one-sided sign test's tail, sum over k >= better of
    C(blocks, k), is at most 2**blocks / CHANCE_ONE_IN.  Otherwise a named effect is weak
    evidence."""
    if not share_holds(better, blocks):
        return False
    if blocks > SIGN_BLOCKS:
        return True
    tail = 0
    term = 1    # C(blocks, k), from k = blocks down: C(n, k - 1) = C(n, k) k / (n - k + 1)
    k = blocks
    while k >= better:
        tail += term
        term = term * k // (blocks - k + 1)
        k -= 1
    return CHANCE_ONE_IN * tail <= 1 << blocks


def best(kinds, errs, n):
    """The index of the candidate to name, or -1 when none is testable: kinds[i] (effects ids)
    with held-out error errs[i] (-1: not testable), i < n.  The lowest error, except that a
    step gives way to the best effect without one when plain_preferred."""
    top = -1
    plain = -1
    for i in range(n):
        e = errs[i]
        if e < 0:
            continue
        if top < 0 or e < errs[top]:
            top = i
        if kinds[i] != STEP and (plain < 0 or e < errs[plain]):
            plain = i
    if top >= 0 and kinds[top] == STEP and plain >= 0:
        if plain_preferred(errs[top], errs[plain]):
            return plain
    return top


def adopted(before, errs, betters, blocks, i):
    """True when candidate i (from best) passes the naming rule against the model without it
    (held-out error before), better in betters[i] of `blocks` held-out blocks."""
    return i >= 0 and names(before, errs[i], betters[i], blocks)
