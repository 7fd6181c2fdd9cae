# Logs on flash: an append-only file of self-checking records, readable after a power cut at any
# byte.  The host decodes pulled logs with this same module.
#
# Record:  0xA5 | type u8 | length u8 | payload (length bytes) | CRC-32 of type..payload, u32 LE
# A reader scans for 0xA5, checks the length fits and the CRC matches, and otherwise skips one byte
# (reporting what it skipped): a torn record is dropped, the records after it are found again.
#
# Payloads (little-endian; points Q16 g, parameters Q24, fixed.py):
#   BOOT     <IHHBHBBBBBHBIbHBB log size at boot (bytes), version, rate_hz, seconds, threshold (Q10 g;
#                          0: from the noise, rest.AUTO), axis (3: all), range_g, fifo, min_count,
#                          max_count, differ (Q16 g), iterations, recal_seconds, temperature
#                          reference (degC; -128: none, temperatures are relative), model
#                          (effects.model_code: 0 is the paper's model), fit (profile.GRADIENT or
#                          NEWTON), discover (1: the board discovers its own missing effect,
#                          acal/discover/search.py).  Version 1 (before profiles) lacks fit and
#                          discover, read as GRADIENT and 0; version 2 lacks discover: 0.
#                          Version 1 was written in three shorter layouts before: without the
#                          model (BOOT_V1B: model 0, the paper's), and before that without the
#                          temperature reference too (BOOT_V1A: -128, temperatures relative;
#                          its first field the boot's number, not the log's size); all load.
#                          docs/boards-and-logs.md "Record layouts" tabulates every layout.
#   REST     <IiiibbH       sample index at the segment's end, mean x y z, temperature (degC:
#                          OUT_ADC3 + the reference, or relative), subset kept in (-1: none),
#                          rest segments merged into this record since the last one
#   CAL      <IHBBBII9i     sample index, calibration number, status, iterations, points,
#                          objective at p0 and at the end (Q40 >> 16, saturated), 9 parameters
#   EFFECT   <IBhI3i        after a CAL, one per effect of a composed model: sample index (the
#                          CAL's), effect id (effects.py), reference temperature (Q2 degC,
#                          fixed.TEMP_Q: the middle of the held points' range is a quarter
#                          degree even when the sensor reads whole ones) and time
#                          (64 s units of running time; a step's record: the step's time; a
#                          supply_offset's: the reference supply in mV), 3 parameters (Q24,
#                          effects.py fit form).  Written before Q2 temperatures (22 bytes,
#                          <IBbI3i, the reference in whole degC): read by its length, the
#                          reference scaled to Q2 (unpack, CalStore), so old logs and stores
#                          still load.
#   COUNTERS <9I            sample index, samples, lost samples, FIFO overruns, bus errors,
#                          bus retries, rest segments, rest records written, rest records
#                          skipped to keep the flash budget
#   SAMPLES  <IBb + n*<hhh  raw capture: first sample index, n, temperature (as REST), n samples
#                          (Q10 g)
#   GAP      <II            raw capture: sample index, samples lost there
#   SUPPLY   <IH            raw capture of a model that follows the board's supply: the sample
#                          index from which the supply (mV) holds, written when it changes
#   DISCOVERY <IBBIIBBB3i   after a board's own model discovery (acal/discover/search.py): sample
#                          index, the effects adopted (effects.model_code: an id, or two ids in
#                          4 bits each; 0: none), the closest candidate (the one chosen; 0: none
#                          testable), the held-out error before and with it (score.py's Q16 g^2
#                          sums, weighted), the held-out blocks it is better in and of how
#                          many, the effect its round added (its id; 0: none testable; the
#                          curve pair's: temp_offset) and that effect's 3 parameters (Q24; all
#                          of the model's in the EFFECT records after).  Written before version
#                          4 (28 bytes, <IBBIIBB3i: no effect, the parameters those of the
#                          closest's first effect, which a second round's are not): read by its
#                          length, the effect the closest's first (unpack).
#   STORE    CAL + k*EFFECT the calibration store's one record (CalStore): a CAL payload, then one
#                          EFFECT payload per effect of a composed model, under one CRC, so a
#                          cut anywhere leaves the whole calibration or none of it
import struct

from acal.core.emit import viper, ptr8, ptr32
from acal.core.fixed import TEMP_Q

SYNC = 0xA5
BOOT = 1
REST = 2
CAL = 3
COUNTERS = 4
SAMPLES = 5
GAP = 6
EFFECT = 7
STORE = 8
SUPPLY = 9
DISCOVERY = 10
# (the kinds' names and the older layouts by kind: the host's, bridge/boardlog.py; a board's
# heap keeps neither)
BOOT_V1A = "<IHHBHBBBBBHBI"    # the first app's (9562c53): no temperature reference, model
BOOT_V1B = "<IHHBHBBBBBHBIb"   # with the temperature reference (a3c88e0): no model
BOOT_V1 = "<IHHBHBBBBBHBIbH"
BOOT_V2 = "<IHHBHBBBBBHBIbHB"
FORMATS = {BOOT: "<IHHBHBBBBBHBIbHBB", REST: "<IiiibbH", CAL: "<IHBBBII9i", COUNTERS: "<9I",
           GAP: "<II", EFFECT: "<IBhI3i", SUPPLY: "<IH", DISCOVERY: "<IBBIIBBB3i"}
EFFECT_V1 = "<IBbI3i"   # the reference temperature in whole degC (before fixed.TEMP_Q)
DISCOVERY_V1 = "<IBBIIBB3i"   # before version 4: no effect field
SAMPLES_HEAD = "<IBb"
_CAL_SIZE = struct.calcsize(FORMATS[CAL])        # 53
_EFFECT_SIZE = struct.calcsize(FORMATS[EFFECT])  # 23: a STORE of 4 effects is 145 bytes
_EFFECT_V1_SIZE = struct.calcsize(EFFECT_V1)     # 22
# every older layout a record of each kind was written with: unpack reads each (sizes: BOOT 23,
# 24, 26, 27 beside 28 now; EFFECT 22 beside 23; DISCOVERY 28 beside 29), the host's
# bridge/boardlog.py OLD_FORMATS lists them by kind
MAX_PAYLOAD = 255
SAMPLES_PER_RECORD = 41  # (255 - 6) // 6
OVERHEAD = 7             # sync, type, length, CRC

try:
    from binascii import crc32
except ImportError:  # a port without binascii.crc32: the same CRC-32 (IEEE), bitwise
    def crc32(data, crc=0):
        crc = crc ^ 0xFFFFFFFF
        for b in data:
            crc ^= b
            for _ in range(8):
                crc = (crc >> 1) ^ (0xEDB88320 if crc & 1 else 0)
        return crc ^ 0xFFFFFFFF


PAD = MAX_PAYLOAD + OVERHEAD  # zero bytes written after a torn tail: more than a record can need


def _ends_clean(path, size):
    # True when the file's last bytes are one whole record (or the file is empty).
    if size == 0:
        return True
    n = size if size < PAD else PAD
    with open(path, "rb") as f:
        f.seek(size - n)
        tail = f.read(n)
    for s in range(n - OVERHEAD + 1):
        if tail[s] == SYNC and s + OVERHEAD + tail[s + 2] == n:
            if crc32(tail[s + 1:n - 4]) == struct.unpack_from("<I", tail, n - 4)[0]:
                return True
    return False


class Log:
    """Appends records to a file.  budget: bytes the file may reach (None: no limit); records
    that would pass it are refused (write returns False) and counted in `refused`.

    Opening a log whose last record was torn by a power cut first appends PAD zero bytes:
    otherwise the first bytes written now could complete the torn record's missing tail and
    the new record they belonged to would be lost.  The reader reports the pad as dropped."""

    def __init__(self, path, budget=None, flush_every=1):
        self.path = path
        self.budget = budget
        # Records are flushed (on the unix port: fsync; on littlefs: a commit) every
        # flush_every records: 1 for the log, more for a raw capture whose last few records a
        # power cut may take.
        self.flush_every = flush_every
        self.unflushed = 0
        self.buf = bytearray(MAX_PAYLOAD + OVERHEAD)
        self.mv = memoryview(self.buf)
        try:
            import os
            size = os.stat(path)[6]
        except OSError:
            size = 0
        self.padded = not _ends_clean(path, size)
        self.f = open(path, "ab")
        self.size = size
        if self.padded:
            self.f.write(bytes(PAD))
            self.f.flush()
            self.size += PAD
        self.refused = 0

    def room(self, n_payload):
        return self.budget is None or self.size + n_payload + OVERHEAD <= self.budget

    def write_payload(self, rtype, n):
        """Write a record whose payload is already in buf[3:3+n]."""
        if not self.room(n):
            self.refused += 1
            return False
        b = self.buf
        b[0] = SYNC
        b[1] = rtype
        b[2] = n
        c = crc32(self.mv[1:3 + n])
        struct.pack_into("<I", b, 3 + n, c)
        self.f.write(self.mv[0:n + OVERHEAD])
        self.unflushed += 1
        if self.unflushed >= self.flush_every:
            self.f.flush()
            self.unflushed = 0
        self.size += n + OVERHEAD
        return True

    def write(self, rtype, *values):
        """Pack values with the type's format and write the record."""
        fmt = FORMATS[rtype]
        struct.pack_into(fmt, self.buf, 3, *values)
        return self.write_payload(rtype, struct.calcsize(fmt))

    def flush(self):
        self.f.flush()
        self.unflushed = 0

    def close(self):
        self.f.close()


def encode(rtype, payload):
    """One record as bytes (host side and tests)."""
    n = len(payload)
    body = bytes([rtype, n]) + bytes(payload)
    return bytes([SYNC]) + body + struct.pack("<I", crc32(body))


def scan(data):
    """Records in data: returns (records, dropped) where records is a list of
    (offset, type, payload bytes) and dropped a list of (offset, length) of bytes skipped."""
    records = []
    dropped = []
    i = 0
    n = len(data)
    bad_start = -1
    while i < n:
        ok = False
        if data[i] == SYNC and i + 3 <= n:
            ln = data[i + 2]
            end = i + 3 + ln + 4
            if end <= n:
                body = data[i + 1:i + 3 + ln]
                if crc32(body) == struct.unpack_from("<I", data, i + 3 + ln)[0]:
                    ok = True
        if ok:
            if bad_start >= 0:
                dropped.append((bad_start, i - bad_start))
                bad_start = -1
            records.append((i, data[i + 1], bytes(data[i + 3:i + 3 + ln])))
            i = end
        else:
            if bad_start < 0:
                bad_start = i
            i += 1
    if bad_start >= 0:
        dropped.append((bad_start, n - bad_start))
    return records, dropped


def unpack(rtype, payload):
    """A record's payload as a tuple of ints (SAMPLES: first, n, temp, flat x y z ... tuple)."""
    if rtype == SAMPLES:
        first, count, temp = struct.unpack_from(SAMPLES_HEAD, payload, 0)
        return first, count, temp, struct.unpack_from("<%dh" % (3 * count), payload, 6)
    if rtype == BOOT and len(payload) == struct.calcsize(BOOT_V1A):
        return struct.unpack(BOOT_V1A, payload) + (-128, 0, 0, 0)
    if rtype == BOOT and len(payload) == struct.calcsize(BOOT_V1B):
        return struct.unpack(BOOT_V1B, payload) + (0, 0, 0)
    if rtype == BOOT and len(payload) == struct.calcsize(BOOT_V1):
        return struct.unpack(BOOT_V1, payload) + (0, 0)
    if rtype == BOOT and len(payload) == struct.calcsize(BOOT_V2):
        return struct.unpack(BOOT_V2, payload) + (0,)
    if rtype == EFFECT and len(payload) == _EFFECT_V1_SIZE:
        return _effect_v1(payload, 0)
    if rtype == DISCOVERY and len(payload) == struct.calcsize(DISCOVERY_V1):
        v = struct.unpack(DISCOVERY_V1, payload)   # its parameters: the closest's first effect's,
        return v[:7] + (v[2] & 0xF,) + v[7:]       # model_code's low 4 bits (effects.KIND_BITS)
    return struct.unpack(FORMATS[rtype], payload)


def _effect_v1(payload, at):
    # an EFFECT payload written before Q2 temperatures: its whole-degC reference in Q2
    v = struct.unpack_from(EFFECT_V1, payload, at)
    return v[:2] + (v[2] << TEMP_Q,) + v[3:]


class CalStore:
    """The current calibration, stored so that a power cut never loses the last good one nor
    mixes two: two slots (files), each holding one STORE record - the CAL fields and a composed
    model's EFFECT fields under one CRC - with the calibration number ordering them; a save
    writes the slot that does not hold the newest valid record, a load takes the newest valid
    one.  (A slot written before STORE existed, a CAL record alone, still loads; one followed by
    EFFECT records is refused: nothing ties its parts together.)"""

    def __init__(self, path_a, path_b):
        self.paths = (path_a, path_b)
        self.effects = []  # after load(): the newest calibration's EFFECT record tuples

    def _read(self, path):
        try:
            with open(path, "rb") as f:
                data = f.read()
        except OSError:
            return None
        recs, dropped = scan(data)
        if len(recs) != 1 or dropped or recs[0][0] != 0:
            return None
        rtype = recs[0][1]
        payload = recs[0][2]
        if rtype == CAL and len(payload) == _CAL_SIZE:
            return [unpack(CAL, payload)]
        if rtype != STORE or len(payload) < _CAL_SIZE:
            return None
        # the effects' size tells the format: 23 bytes each, or 22 written before Q2
        # temperatures (1 to 4 effects: 23 k and 22 k never coincide)
        rest = len(payload) - _CAL_SIZE
        size = _EFFECT_SIZE if rest % _EFFECT_SIZE == 0 else _EFFECT_V1_SIZE
        if rest % size:
            return None
        out = [struct.unpack_from(FORMATS[CAL], payload, 0)]
        for at in range(_CAL_SIZE, len(payload), size):
            out.append(struct.unpack_from(FORMATS[EFFECT], payload, at) if size == _EFFECT_SIZE
                       else _effect_v1(payload, at))
        return out

    def load(self):
        """(slot, CAL record tuple) of the newest valid calibration, or (-1, None); its EFFECT
        records in self.effects."""
        best = -1
        rec = None
        self.effects = []
        for s in range(2):
            r = self._read(self.paths[s])
            if r is not None and (rec is None or r[0][1] > rec[1]):
                best = s
                rec = r[0]
                self.effects = r[1:]
        return best, rec

    def save(self, values, effects=()):
        """values: a CAL record's fields; values[1] (the calibration number) orders the slots.
        effects: EFFECT records' fields, for a composed model."""
        slot, _ = self.load()
        target = 1 if slot == 0 else 0
        payload = bytearray(_CAL_SIZE + _EFFECT_SIZE * len(effects))
        struct.pack_into(FORMATS[CAL], payload, 0, *values)
        for j in range(len(effects)):
            struct.pack_into(FORMATS[EFFECT], payload, _CAL_SIZE + _EFFECT_SIZE * j, *effects[j])
        with open(self.paths[target], "wb") as f:
            f.write(encode(STORE, payload))
        return target


@viper
def pack_int16(source, n: int, dest, at: int):
    # n ints of source (an int32 array, each within int16) into the bytes dest[at:at + 2 n],
    # little-endian: a SAMPLES record's payload, the capture's per-sample hot loop (viper on
    # ports with emitters, acal/core/emit.py; only the low 16 bits of each word are read, so no sign
    # extension is needed).
    src = ptr32(source)
    dst = ptr8(dest)
    i = 0
    while i < n:
        v = int(src[i])
        dst[at] = v & 0xFF
        dst[at + 1] = (v >> 8) & 0xFF
        at += 2
        i += 1
