"""Crash-safe logs: after a power cut at any byte the reader recovers every complete record,
accepts no damaged one and says what it dropped; the stored calibration survives any cut."""
import random
import struct


from acal.core import effects
from acal.logger import log
from acal.core.fixed import TEMP_Q


def make_log(n=1000, seed=7):
    """n records of the app's types, as the device's Log writes them; returns (bytes, spans)."""
    rnd = random.Random(seed)
    recs = []
    for i in range(n):
        t = rnd.choice([log.REST, log.REST, log.REST, log.GAP, log.COUNTERS, log.CAL])
        if t == log.REST:
            v = (i, rnd.randrange(-80000, 80000), rnd.randrange(-80000, 80000), rnd.randrange(-80000, 80000),
                 rnd.randrange(-20, 20), rnd.randrange(-1, 9), rnd.randrange(100))
        elif t == log.GAP:
            v = (i, rnd.randrange(1000))
        elif t == log.COUNTERS:
            v = tuple(rnd.randrange(1 << 32) for _ in range(9))
        else:
            v = (i, i, 0, 50, 18, rnd.randrange(1 << 32), rnd.randrange(1 << 32),
                 *[rnd.randrange(-(1 << 31), 1 << 31) for _ in range(9)])
        recs.append((t, v))
    return recs


def write_with_device_log(path, recs):
    lg = log.Log(str(path))
    for t, v in recs:
        assert lg.write(t, *v)
    lg.close()
    data = path.read_bytes()
    spans, off = [], 0
    for t, _ in recs:
        n = struct.calcsize(log.FORMATS[t]) + log.OVERHEAD
        spans.append((off, off + n))
        off += n
    assert off == len(data)
    return data, spans


def decoded(records):
    return [(t, log.unpack(t, p)) for _, t, p in records]


def test_roundtrip(tmp_path):
    recs = make_log(50)
    data, _ = write_with_device_log(tmp_path / "a.log", recs)
    got, dropped = log.scan(data)
    assert decoded(got) == recs and dropped == []


def test_truncation_at_every_byte(tmp_path):
    recs = make_log(500)
    data, spans = write_with_device_log(tmp_path / "t.log", recs)
    j = 0  # records complete before the cut
    for cut in range(len(data) + 1):
        while j < len(spans) and spans[j][1] <= cut:
            j += 1
        got, dropped = log.scan(data[:cut])
        assert decoded(got) == recs[:j], cut
        torn = cut - (spans[j - 1][1] if j else 0)
        assert sum(n for _, n in dropped) == torn, cut  # exactly the torn tail is reported


def test_torn_record_then_reboot_appends(tmp_path):
    """A cut at every byte inside every record of a 400-record log (every record type); the
    device reboots, opens its log and appends more records."""
    recs = make_log(400, seed=8)
    data, spans = write_with_device_log(tmp_path / "r.log", recs)
    after = recs[-3:]
    path = tmp_path / "torn.log"
    checked = padded = 0
    for i in range(len(recs)):
        a, b = spans[i]
        for cut in range(a + 1, b):  # every byte inside the record
            path.write_bytes(data[:cut])
            lg = log.Log(str(path))
            padded += lg.padded
            for t, v in after:
                lg.write(t, *v)
            lg.close()
            got, dropped = log.scan(path.read_bytes())
            if data[cut:b] == bytes(b - cut):
                # the record's missing bytes were zeros: the pad completes it, byte for byte
                assert decoded(got) == recs[:i + 1] + after, (i, cut)
                assert dropped == [(b, log.PAD - (b - cut))]
            else:
                assert decoded(got) == recs[:i] + after, (i, cut)
                assert dropped == [(a, cut - a + log.PAD)]  # the torn bytes and the pad
            checked += 1
    assert checked > 6000 and padded == checked
    # a cut on a record boundary needs no pad
    path.write_bytes(data[:spans[10][1]])
    assert not log.Log(str(path)).padded


def test_flipped_bytes_are_never_accepted(tmp_path):
    recs = make_log(300, seed=9)
    data, spans = write_with_device_log(tmp_path / "f.log", recs)
    rnd = random.Random(3)
    for _ in range(2000):
        k = rnd.randrange(len(data))
        bad = bytearray(data)
        bad[k] ^= 1 << rnd.randrange(8)
        got, dropped = log.scan(bytes(bad))
        i = next(n for n, (a, b) in enumerate(spans) if a <= k < b)
        assert (recs[i][0], recs[i][1]) not in [r for n, r in enumerate(decoded(got)) if n == i] or len(got) < len(recs)
        assert all(r in recs for r in decoded(got))
        assert dropped  # the damage is reported


def test_budget_refuses_and_counts(tmp_path):
    lg = log.Log(str(tmp_path / "b.log"), budget=100)
    n = 0
    while lg.write(log.GAP, n, 1):
        n += 1
    assert n == 100 // 15 and lg.refused == 1 and (tmp_path / "b.log").stat().st_size <= 100


def cal_values(number, seed):
    rnd = random.Random(seed)
    return (number * 100, number, 0, 50, 18, rnd.randrange(1 << 32), rnd.randrange(1 << 32),
            *[rnd.randrange(-(1 << 24), 1 << 24) for _ in range(9)])


def test_calibration_survives_a_cut_at_any_point_of_its_update(tmp_path):
    a, b = tmp_path / "cal_a.bin", tmp_path / "cal_b.bin"
    store = log.CalStore(str(a), str(b))
    assert store.load() == (-1, None)
    store.save(cal_values(1, 1))
    store.save(cal_values(2, 2))
    slot, good = store.load()
    assert good == cal_values(2, 2)
    # The next save goes to the other slot; cut it at every byte (and tear it over old bytes).
    target = (a, b)[1 - slot]
    old = target.read_bytes()
    new = log.encode(log.CAL, struct.pack(log.FORMATS[log.CAL], *cal_values(3, 3)))
    for cut in range(len(new) + 1):
        for torn in (new[:cut], new[:cut] + old[cut:]):
            target.write_bytes(torn)
            _, rec = store.load()
            assert rec == (cal_values(3, 3) if cut == len(new) else cal_values(2, 2)), cut


def effect_values(index, kind, seed):
    rnd = random.Random(seed)
    return (index, kind, rnd.randrange(-500, 500), rnd.randrange(1 << 20),   # Q2 degC reference
            *[rnd.randrange(-(1 << 20), 1 << 20) for _ in range(3)])


def test_a_composed_calibration_is_never_mixed_with_the_previous_one(tmp_path):
    """One STORE record holds the CAL fields and every EFFECT's under one CRC: a cut at every
    byte of an update, and a tear over the slot's old bytes at every byte, load the previous
    calibration whole or the new one whole - never the new CAL without its effects, or with
    the previous one's."""
    a, b = tmp_path / "cal_a.bin", tmp_path / "cal_b.bin"
    store = log.CalStore(str(a), str(b))
    effs = {n: [effect_values(n * 100, k, 10 * n + k) for k in (1, 2, 3, 4)] for n in (1, 2, 3)}
    store.save(cal_values(1, 1), effs[1])
    store.save(cal_values(2, 2), effs[2])
    slot, good = store.load()
    assert good == cal_values(2, 2) and store.effects == effs[2]
    target = (a, b)[1 - slot]
    old = target.read_bytes()
    # the update's bytes, as save() writes them (into a scratch store)
    scratch = log.CalStore(str(tmp_path / "x_a.bin"), str(tmp_path / "x_b.bin"))
    scratch.save(cal_values(3, 3), effs[3])
    new = (tmp_path / "x_a.bin").read_bytes()
    assert len(new) == 7 + 53 + 4 * 23
    seen = set()
    for cut in range(len(new) + 1):
        for torn in (new[:cut], new[:cut] + old[cut:]):
            target.write_bytes(torn)
            _, rec = store.load()
            whole = (rec, store.effects)
            assert whole in ((cal_values(3, 3), effs[3]), (cal_values(2, 2), effs[2])), cut
            seen.add(rec[1])
    assert seen == {2, 3}


def test_effects_written_with_whole_degrees_still_load(tmp_path):
    """An EFFECT record and a STORE written before the temperature went to Q2 degC (22 bytes an
    effect, the reference an int8 of whole degC) are read by their length, the reference in Q2
    (the same temperature): old logs and stored calibrations keep loading."""
    old = [(index, kind, temp, time, *p) for index, kind, temp, time, *p in
           [effect_values(100, k, k) for k in (1, 2, 3, 4)]]
    old = [v[:2] + (v[2] // 20,) + v[3:] for v in old]          # whole degC, -25..24
    payload = struct.pack(log.EFFECT_V1, *old[0])
    assert len(payload) == 22
    want = old[0][:2] + (old[0][2] * (1 << TEMP_Q),) + old[0][3:]
    assert log.unpack(log.EFFECT, payload) == want
    for k in range(1, 5):
        a, b = tmp_path / f"a{k}.bin", tmp_path / f"b{k}.bin"
        body = struct.pack(log.FORMATS[log.CAL], *cal_values(5, 5)) + b"".join(
            struct.pack(log.EFFECT_V1, *v) for v in old[:k])
        a.write_bytes(log.encode(log.STORE, body))
        store = log.CalStore(str(a), str(b))
        _, rec = store.load()
        assert rec == cal_values(5, 5)
        assert store.effects == [v[:2] + (v[2] * (1 << TEMP_Q),) + v[3:] for v in old[:k]]


def test_discovery_records_written_before_version_4_still_load():
    """A DISCOVERY record written before it carried its effect (28 bytes): read by its length,
    the effect its parameters are of being the closest candidate's first (what such a board
    wrote); one of today's carries it."""
    closest = effects.model_code((effects.TEMP_OFFSET, effects.DRIFT))
    old = (900, closest, closest, 5000, 2000, 5, 6, 11, -12, 13)
    payload = struct.pack(log.DISCOVERY_V1, *old)
    assert len(payload) == 28
    assert log.unpack(log.DISCOVERY, payload) == old[:7] + (effects.TEMP_OFFSET,) + old[7:]
    new = old[:7] + (effects.DRIFT,) + old[7:]
    assert log.unpack(log.DISCOVERY, struct.pack(log.FORMATS[log.DISCOVERY], *new)) == new


def test_a_board_flashed_with_another_model_numbers_on_from_the_store(tmp_path):
    """The store holds calibration 7 of base+temp_offset; the board is flashed as base: it
    starts uncalibrated, its first calibration is number 8, the store's newest, and the next boot
    resumes it (the old model's stays in the other slot)."""
    from acal.logger.app import Processor
    a, b = tmp_path / "cal_a.bin", tmp_path / "cal_b.bin"
    store = log.CalStore(str(a), str(b))
    store.save(cal_values(7, 7), [effect_values(700, 1, 1)])
    proc = Processor(log.Log(str(tmp_path / "log.bin")), 25, store=store)
    fresh = Processor(log.Log(str(tmp_path / "log0.bin")), 25).params
    assert proc.calibrations == 7 and proc.params == fresh
    mine = (800, proc.calibrations + 1, 0, 5, 72, 1, 1,
            17000000, 16500000, 16800000, 10000, -20000, 30000, 40000, -50000, 60000)
    store.save(mine)
    again = Processor(log.Log(str(tmp_path / "log2.bin")), 25, store=store)
    assert again.calibrations == 8 and again.params == list(mine[7:])
    composed = Processor(log.Log(str(tmp_path / "log3.bin")), 25, store=store,
                         model="base+temp_offset")
    assert composed.calibrations == 8 and composed.params[:9] == fresh
    # a checksummed record outside the calibration bounds (no fit makes one) is not applied
    store.save((900, 9, 0, 5, 72, 1, 1) + (1 << 28,) * 9)
    odd = Processor(log.Log(str(tmp_path / "log4.bin")), 25, store=store)
    assert odd.calibrations == 9 and odd.params == fresh
