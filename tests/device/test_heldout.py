"""The board's held-out set (device/acal/discover/heldout.py, issue 29): it keeps exactly the rest points
the host's diagnose holds out (odd 2-hour blocks from the start), with their conditions; its
preallocated storage is the written byte budget; once full it follows the wear (the oldest point
of the fullest block replaced, so every block seen keeps points);
and keeping a point allocates nothing under the real MicroPython, 64- and 32-bit ports."""
from acal.discover import heldout
from acal.core.bins import COND, conditions
from acal.core.fixed import C_SUPPLY, C_TEMP, C_TIME

from accelcal.bridge import runtime


def offer(h, x, y, z, temp=0, time=0, supply=0):
    """h.offer with the conditions as the board's one array (bins.conditions(1))."""
    cond = conditions(1)
    cond[C_TEMP], cond[C_TIME], cond[C_SUPPLY] = temp, time, supply
    return h.offer(x, y, z, cond)


def test_held_out_blocks_are_the_hosts_odd_two_hour_blocks():
    for t64 in range(0, 2000, 7):
        seconds = 64 * t64                   # the board's time unit is 64 s
        assert heldout.held_out(t64) == ((seconds // 7200) % 2 == 1), t64


def test_byte_budget_is_the_preallocated_storage():
    h = heldout.HeldOut()
    arrays = (h.xyz, h.cond, h.block, h.held, h.weight)
    stored = sum(a.itemsize * len(a) for a in arrays)
    assert stored == heldout.BUDGET_BYTES == 5184      # the figure docs/model-discovery.md states
    assert stored == heldout.CAPACITY * (3 + COND + 3) * 4


def test_offer_keeps_odd_block_points_with_their_conditions():
    h = heldout.HeldOut(capacity=4)
    even, odd = 10, 120                       # 640 s (block 0), 7680 s (block 1)
    assert not offer(h, 1, 2, 3, temp=20, time=even, supply=3300)
    assert h.count == 0
    assert offer(h, 65536, -5, 7, temp=31, time=odd, supply=3100)
    assert h.count == 1
    assert list(h.xyz[0:3]) == [65536, -5, 7]
    assert list(h.cond[0:COND]) == [31, odd, 3100]
    assert h.block[0] == 1


def test_a_full_set_replaces_its_oldest_point_and_counts_blocks():
    h = heldout.HeldOut(capacity=3)
    times = [120, 130, 400, 620]              # blocks 1, 1, 3, 5 (all odd)
    for i, t in enumerate(times):
        assert offer(h, i, 0, 0, time=t)
    assert h.count == 3
    assert sorted(h.xyz[3 * s] for s in range(3)) == [1, 2, 3]   # point 0 was the oldest
    assert h.blocks() == 3                    # blocks 1, 3, 5 remain


def test_the_same_posture_in_a_block_is_one_point():
    h = heldout.HeldOut(capacity=8)
    offer(h, 65536, 0, 0, temp=30, time=120)
    offer(h, 65536 + 6553, 100, -100, temp=31, time=125)     # within 0.1 g: replaces it
    assert h.count == 1 and h.xyz[0] == 65536 + 6553 and h.cond[0] == 31
    offer(h, 65536 + 6553 + 6554, 0, 0, time=126)            # 0.1 g away: a point of its own
    offer(h, 65536, 0, 0, time=400)                          # the same posture, another block
    assert h.count == 3 and h.blocks() == 2
    assert list(h.weight[:3]) == [2, 1, 1] and h.total_weight() == 4


def test_a_point_weighs_the_rest_means_it_stands_for_up_to_the_cap():
    h = heldout.HeldOut(capacity=4)
    for k in range(heldout.WEIGHT_CAP + 5):                 # one posture held for long
        offer(h, 65536, k, 0, time=120 + k % 3)
    assert h.count == 1 and h.weight[0] == heldout.WEIGHT_CAP
    offer(h, 0, 65536, 0, time=400)                          # a new point starts at 1
    assert h.weight[1] == 1 and h.total_weight() == heldout.WEIGHT_CAP + 1


def test_a_full_set_stays_spread_over_the_blocks():
    # 4 points a block in blocks 1, 3, ..., 35: the newest 8 would be two blocks; the kept 8
    # span seven, the newest (the current block takes a second slot from the oldest block)
    h = heldout.HeldOut(capacity=8)
    postures = ((65536, 0, 0), (0, 65536, 0), (0, 0, 65536), (-65536, 0, 0))
    for b in range(1, 36, 2):
        for k in range(4):
            offer(h, *postures[k], time=(b * 225 + 1) // 2 + 10 * k)
    blocks = sorted(h.block[i] for i in range(h.count))
    assert h.count == 8 and h.blocks() == 7, blocks
    assert blocks == [23, 25, 27, 29, 31, 33, 35, 35]


SCRIPT = r'''
import micropython
from acal.discover.heldout import HeldOut
from acal.core.bins import conditions
h = HeldOut()
cond = conditions(1)
kept = 0   # a new module global made under the lock would itself allocate


def work(h, cond):
    kept = 0
    for i in range(300):
        cond[0] = 25 + (i & 7)      # fixed.C_TEMP, C_TIME, C_SUPPLY
        cond[1] = 3 * i
        cond[2] = 3300 - i
        if h.offer(65536 - i, i, -i, cond):
            kept += 1
    return kept


micropython.heap_lock()
try:
    kept = work(h, cond)
    micropython.heap_unlock()
    print("OK", kept, h.count, h.blocks())
except MemoryError:
    micropython.heap_unlock()
    print("ALLOCATED")
'''


def _expected():
    h = heldout.HeldOut()
    kept = sum(offer(h, 65536 - i, i, -i, 25 + (i & 7), 3 * i, 3300 - i) for i in range(300))
    return ["OK", str(kept), str(h.count), str(h.blocks())]


def test_keeping_points_allocates_nothing_on_micropython(tmp_path):
    f = tmp_path / "heldout_heap.py"
    f.write_text(SCRIPT)
    assert runtime.run_micropython_script(str(f)).split() == _expected()


def test_keeping_points_allocates_nothing_on_the_32_bit_port(tmp_path, mp32):
    f = tmp_path / "heldout_heap32.py"
    f.write_text(SCRIPT)
    assert mp32(str(f)).split() == _expected()
