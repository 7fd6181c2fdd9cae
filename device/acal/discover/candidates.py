# The board's choice among candidate effects (issue 29), as `diagnose` chooses
# (host/accelcal/pipeline/diagnose.py): the candidate with the lowest held-out error, except that
# a change point (the step) gives way to the best effect without one when rule.py's
# parsimony rule prefers it; the choice is then adopted only when discovery.names holds.
# Errors: score.py's integers (-1: not testable); no allocation.
from acal.discover import rule as discovery
from acal.core.effects import STEP


def best(kinds, errs, n):
    """The index of the candidate to name, or -1 when none is testable: kinds[i] (effects ids)
    with held-out error errs[i] (-1: not testable)."""
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
        if discovery.plain_preferred(errs[top], errs[plain]):
            return plain
    return top


def adopted(before, errs, betters, blocks, i):
    """True when candidate i (from best) passes the naming rule against the model without it
    (held-out error before), better in betters[i] of `blocks` held-out blocks."""
    return i >= 0 and discovery.names(before, errs[i], betters[i], blocks)
