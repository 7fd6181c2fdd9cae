# The held-out rest points of the board's own model discovery (issue 29; docs/model-discovery.md
# "Held-out points on the board").  As `diagnose` holds out alternate 2-hour blocks, the board keeps
# the rest means that fall in odd blocks (host/accelcal/pipeline/restpoints.py: 2-hour blocks from
# the start, even train, odd held out) apart from the fit's points,
# so a candidate effect fitted on the fit points is scored on points it never saw.
# Formats (fixed.py): points Q16 g; conditions as bins.py: temperature Q2 degC, time in 64 s units,
# supply mV.  Storage is preallocated (CAPACITY points, int32 slots), nothing is allocated per
# point: a point near one of its own block (NEAR) replaces it; when full, a new point replaces
# the oldest point of the block holding most (of equals, the oldest), so the set follows the
# wear and stays spread over every block seen: the naming rule counts the blocks a candidate
# improves (a ring of the newest points held one block).
# Byte budget: CAPACITY x (3 point + COND condition + 1 block + 1 block's count + 1 weight)
# int32 slots = 144 x 9 x 4 = 5184 bytes of array storage (BUDGET_BYTES;
# tests/device/test_heldout.py checks it).  The counts keep choosing the point to replace
# linear in the points (a count per offer was CAPACITY**2 comparisons).
from acal.core.bins import COND, int32s
from acal.core.fixed import C_TIME
try:
    from micropython import const
except ImportError:  # CPython
    def const(x):
        return x

# Twice the wear fit's points (profile.WEAR_MAX_COUNT x 9): three days hold 18 held-out blocks,
# and a block's error summed over 4 points judged it by chance (72 points: seed 41's hidden
# temp_offset better in 8 of 12 blocks, 144: 10 of 12; docs/model-discovery.md).
CAPACITY = const(144)
# 2 hours is 112.5 units of 64 s: block = time * 64 // 7200 = 2 * time // 225, exact.
BLOCK_HALF_UNITS = const(225)
SLOT_BYTES = const(4)
# A rest mean within NEAR (max-norm, Q16 g: the bins' 0.1 g) of a held point of its own block
# replaces it: a wearer still in one posture for hours would otherwise fill a block with one
# point, and a block's error would be that point's.
NEAR = const(6554)
# Each slot counts the rest means it stands for (the newest kept), up to WEIGHT_CAP: `diagnose`
# scores a block on every rest point in it, so a posture held for an hour weighs more than one
# glanced at; score.py weighs each point's error so.
WEIGHT_CAP = const(16)
BUDGET_BYTES = const(5184)  # CAPACITY * (3 + COND + 3) * SLOT_BYTES


def block_of(time):
    """The 2-hour block (int) of a time in 64 s units."""
    return 2 * time // BLOCK_HALF_UNITS


def held_out(time):
    """True when a point taken at `time` (64 s units) belongs to the held-out set (odd block)."""
    return block_of(time) & 1 == 1


class HeldOut:
    """The held-out rest points: xyz (Q16 g, flat), cond (COND per point, flat), block (int)."""

    def __init__(self, capacity=CAPACITY):
        self.capacity = capacity
        self.xyz = int32s(3 * capacity)
        self.cond = int32s(COND * capacity)
        self.block = int32s(capacity)
        self.held = int32s(capacity)   # how many kept points share slot i's block
        self.weight = int32s(capacity)  # how many rest means slot i stands for (<= WEIGHT_CAP)
        self.count = 0

    def takes(self, time):
        """held_out(time), asked of the set (the pipeline imports no discovery module: a board
        without discovery loads none)."""
        return held_out(time)

    def total_weight(self):
        """The rest means the kept points stand for (the sum of their weights)."""
        n = 0
        for i in range(self.count):
            n += self.weight[i]
        return n

    def clear(self):
        self.count = 0

    def offer(self, x, y, z, cond):
        """Keep a rest mean seen at the conditions `cond` (bins.conditions(1)'s columns) when
        its time falls in a held-out block; True when kept."""
        time = cond[C_TIME]
        if not held_out(time):
            return False
        b = block_of(time)
        near = self._near(x, y, z, b)
        if near >= 0:
            s = near        # the same posture again in its block: the newer reading kept
            if self.weight[s] < WEIGHT_CAP:
                self.weight[s] += 1
        elif self.count < self.capacity:
            s = self.count
            self.count += 1
        else:
            s = self._victim()
            self._recount(self.block[s], -1)
        self.xyz[3 * s] = x
        self.xyz[3 * s + 1] = y
        self.xyz[3 * s + 2] = z
        for c in range(COND):
            self.cond[COND * s + c] = cond[c]
        if near < 0:
            self.weight[s] = 1
            self.block[s] = b
            self._recount(b, 1)
        return True

    def _near(self, x, y, z, b):
        # a slot of block b whose point lies within NEAR (max-norm) of (x, y, z), or -1
        d = NEAR
        xyz = self.xyz
        for i in range(self.count):
            if self.block[i] == b:
                j = 3 * i
                if -d < x - xyz[j] < d and -d < y - xyz[j + 1] < d and -d < z - xyz[j + 2] < d:
                    return i
        return -1

    def _recount(self, b, change):
        # the count of block b's points into each of its slots: change -1 while the slot
        # being replaced still holds b, +1 once the new slot holds it (counted afresh: linear)
        held = self.held
        blk = self.block
        n = 0
        for i in range(self.count):
            if blk[i] == b:
                n += 1
        if change < 0:
            n -= 1
        for i in range(self.count):
            if blk[i] == b:
                held[i] = n

    def _victim(self):
        # the slot of the oldest point of the block holding most points (of equals, the oldest)
        best = 0
        held = self.held
        cond = self.cond
        for i in range(1, self.count):
            if held[i] > held[best] or (held[i] == held[best] and
                                        cond[COND * i + 1] < cond[COND * best + 1]):
                best = i
        return best

    def blocks(self):
        """How many distinct held-out blocks the kept points span (no allocation: points of one
        block are counted at the first slot holding that block)."""
        n = 0
        for i in range(self.count):
            b = self.block[i]
            first = True
            for j in range(i):
                if self.block[j] == b:
                    first = False
                    break
            if first:
                n += 1
        return n
