# Fixed-point formats of the device core: the one place where they are defined.
#
# Notation: "Qn g" means an int whose least significant bit is 2**-n g.
# Small ints: 32-bit MicroPython ports keep |int| < 2**30 unboxed; past that an int is a
# heap-allocated long.  The per-sample path (rest detector, apply) and the default profile's fit
# (gaussnewton.py, solve.py; its wide products through wide.py) stay inside 2**30 for every
# in-range input (tests/device/test_ranges.py proves it at the worst case, tests/device/test_heap.py under
# heap_lock on the 32-bit MicroPython).  So does the paper profile's gradient descent: its
# objective (below) is defined by ~50-bit products and values to ~2**62, and computed exactly in
# 14-bit limbs (objective.py) inside a domain it checks - parameters in the fit region (below)
# widened by H_PARAM, points within +-16 g per axis (|u| < 2**28 in Q24), at most 128 points;
# outside it model.objective takes the long-int formula and the optimiser refuses the points
# (docs/method-and-formats.md "Integer ranges").
try:
    from micropython import const
except ImportError:  # CPython without Blinka
    def const(x):
        return x

# --- samples ------------------------------------------------------------------------------
# SAMPLE: Q10 g (1 LSB = 0.977 mg).  The LIS3DH at +-2 g in high-resolution mode gives 1 mg/digit,
# so one digit is one LSB to within 2.4 %, a scale error the calibration removes anyway.
# Range: |sample| <= SAMPLE_MAX (+-16 g, the LIS3DH's largest full scale).
SAMPLE_Q = const(10)
SAMPLE_ONE_G = const(1024)
SAMPLE_MAX = const(16383)
# The rounding onto Q10: sample i of a stream (its index from the stream's first sample) is
# floor(g * 1024 + d_i), d_i = ((i * DITHER_STEP) & DITHER_MASK) / 2**DITHER_BITS, a deterministic
# dither (i * 0.618..., the golden ratio's Weyl sequence, mod 1: it spreads evenly over any run
# of samples), not round(g * 1024): a source's own steps (the LIS3DH's 1 mg, 1.024 LSB) re-rounded
# to the nearest LSB keep a bias of up to 0.49 mg in every still window's mean, the same in every
# window of a posture, which the fit took for the sensor's error (issue 50 part 5: 1.49x the true
# model on clean wear; docs/real-recordings.md "Where the last tenth goes").  A value on the grid
# (a .cwa's 1/256 g, a board's logged Q10) is kept as it is.  In integers, the driver's form:
# (g in Q24 + d_i in Q14 of an LSB) >> 14; DITHER_STEP is odd, so d_i takes all 16384 values.
DITHER_BITS = const(14)
DITHER_MASK = const(16383)
DITHER_STEP = const(10127)   # round(0.6180339887 * 2**14) = 10126, made odd: 10127

# --- temperature ------------------------------------------------------------------------------
# TEMP: Q2 degC (1 LSB = 0.25 degC), the device's temperature condition everywhere past the
# feeder: the bins' conditions and thresholds, the effects' dT, the apply's temperature, the fit's
# reference (EFFECT/STORE records).  Whole degrees are too coarse: a curve about 25 degC read at
# 33 degC has a slope of 16 e per degC, so a half-degree rounding is a real offset error
# (docs/model-discovery.md "Curves").  The LIS3DH's OUT_ADC3 gives whole degC: the Processor
# scales it (temp << TEMP_Q); a recording's temperatures are rounded to Q2 on the host
# (fixedpoint.device_conditions).  Range: |temp| <= 125 degC -> 500 (absolute, with a board's
# TEMP_REF_C; relative otherwise); dT is clamped to +-TEMP_DT_MAX (effects.py) before any product.
TEMP_Q = const(2)         # 1 degC: 4
TEMP_DT_MAX = const(128)  # 32 degC: dT's clamp either side of the reference (effects.py)

# --- conditions: the quantities a point is taken at, a column each ------------------------------
# Every fact of a column stands here, a line in each table below: its index C_* and unit, its
# least spread (DIFFERS), its regressor's source (SOURCES) and, for a quantity the board file
# reads, its reader (BOARD_READERS).  A new board quantity is these lines, its reader function in
# the board file, its effect's row in effects.py (EFFECTS) and the host's row in
# fixedpoint.QUANTITIES (docs/model-discovery.md "How to add a board quantity").
# The board's conditions now (bins.conditions(1), the Processor's `now`) and each point's, by
# column (effects.condition_of's order; the host's fixedpoint.QUANTITIES):
C_TEMP = const(0)    # Q2 degC (TEMP_Q): the LIS3DH's OUT_ADC3 + the board's TEMP_REF_C
C_TIME = const(1)    # 64 s units (effects.DT_UNIT_S) from the first sample
C_SUPPLY = const(2)  # mV, the board's supply (board.supply_mv), clamped to 0..65535
COND = const(3)      # columns: the conditions a point (flat arrays of COND apiece, bins.py)
# The least spread of each column the bins' held points need for an effect that reads it (the
# bins' thresholds: pipeline.track, bins.set_differ; the host's diagnose asks the same), by column
# (no name apiece: a board holds this module's every name, and past 73 its table grows by 192 B):
DIFFERS = (
    3 << TEMP_Q,    # C_TEMP: 3 degC in Q2
    675,            # C_TIME: 64 s units, 12 h
    100,            # C_SUPPLY: mV
)
# The sources of the effects' regressors (effects.py EFFECTS' source; 0 there: the reading
# itself) and where each stands in the relative conditions d (a point's or a block's conditions
# minus their references, made once a block or a point): source: (column, shift, clamp) - the
# value d[column] clamped to +-clamp (0: the effect row's time reach) and shifted left into the
# regressor's Q16 base (effects.regressor).  A step reads its column unclamped against ts.
SOURCE_TEMP = const(1)      # dT, Q2 degC from the reference; clamped to +-TEMP_DT_MAX
SOURCE_TIME = const(2)      # dt, 64 s units from the reference; clamped to +-the row's reach
SOURCE_STEP = const(3)      # [dt >= ts]: a step at ts (acal/core/changepoint.py finds it)
SOURCE_SUPPLY = const(4)    # dV, mV of the board's supply from its reference; +-1024 mV
SOURCES = {
    SOURCE_TEMP: (C_TEMP, 10, TEMP_DT_MAX),     # dT / 16 in Q16 from Q2 degC, <= 2**17
    SOURCE_TIME: (C_TIME, 3, 0),                # dt / 2**13 in Q16
    SOURCE_STEP: (C_TIME, 0, 0),                # [dt >= ts]
    SOURCE_SUPPLY: (C_SUPPLY, 6, 1024),         # dV / 1024 in Q16 (the unit: 1024 mV), <= 2**16
}
# The columns a board file may read: (column, its function's name, low clamp, high clamp).  The
# app reads each the board file defines once a block, clamped, before the block is fed (a failed
# read, OSError, keeps the last value); a model with an effect of a column whose function the
# board file lacks is refused (logger/app.py).  The temperature is the chip's (the driver's).
BOARD_READERS = (
    (C_SUPPLY, "supply_mv", 0, 65535),
)

# --- segments -----------------------------------------------------------------------------
# Segment sums: sum of <= SEGMENT_MAX_SAMPLES samples, so |sum| <= 16383 * 65535 < 2**30.
SEGMENT_MAX_SAMPLES = const(65535)

# --- points (rest means) --------------------------------------------------------------------
# POINT: Q16 g (1 LSB = 15.3 ug).  A segment mean is floor(sum * 2**6 / n), computed without
# leaving 2**30 (rest.py).  Range: |point| <= 16 g -> 2**20.
POINT_Q = const(16)
POINT_ONE_G = const(65536)
POINT_FROM_SAMPLE_SHIFT = const(6)  # POINT_Q - SAMPLE_Q

# --- optimiser (the paper profile's gradient descent; the default profile's fit reads its
# own formats, written in model.py and gaussnewton.py) -------------------------------------
# PARAM: every parameter in Q24: scales and misalignments dimensionless (1.0 = 2**24), offsets
# in g (1 g = 2**24).  Points enter as u = (v << 8) + o, in Q24 g.
PARAM_Q = const(24)
PARAM_ONE = const(16777216)  # 2**24
POINT_TO_PARAM_SHIFT = const(8)  # PARAM_Q - POINT_Q
# Corrected point a = K u: the Q48 product is kept in Q28 g (shift 20), so the change that a
# gradient step h makes in a (h * |u| ~ 2**11 LSB at 1 g) is resolved to ~0.05 %.
A_Q = const(28)
A_SHIFT = const(20)  # 2 * PARAM_Q - A_Q
# Gradient step h = 2**-17 (7.6e-6; the paper recommends 1e-5 for 32-bit fixed point) in every
# parameter, a power of two so that dividing by h is a shift.
H_SHIFT = const(17)
H_PARAM = const(128)  # 2**(PARAM_Q - H_SHIFT)
# Residual r = |a|^2 - 1 g^2: |a|^2 is Q56 g^2, r is kept in Q30 g^2 (shift 26).
R_SHIFT = const(26)
# Objective term r^2: Q60 g^4 -> Q40 g^4 (shift 20).  1 LSB of the objective = 2**-40 g^4.
F_SHIFT = const(20)
OBJ_Q = const(40)
# Update: p -= alpha * (f(p+h e_i) - f(p)) / h / N, where f is the *sum* over the N points and the
# division by N makes it the paper's objective averaged over the points (the scaling under which
# the paper's learning rates converge; docs/method-and-formats.md "Learning-rate scaling").  In
# integers:
#   dp[LSB of Q24] = alpha * df[LSB of Q40] * 2**(PARAM_Q + H_SHIFT - OBJ_Q) / N
#                  = alpha_tenths * df * 2 // (10 * N)
UPDATE_MUL = const(2)  # 2**(PARAM_Q + H_SHIFT - OBJ_Q)
ALPHA_DEN = const(10)  # learning rates are given in tenths: 0.3 -> 3
# Learning rates of the paper (alpha_s, alpha_m, alpha_o) for the square-root-free objective.
ALPHA_SCALE = const(3)
ALPHA_MISALIGN = const(8)
ALPHA_OFFSET = const(2)

# Calibration bounds.  A result must lie inside them; a calibration inside them keeps the
# per-sample apply below 2**30 at every full scale (calibration.Calibration).  They hold every
# real LIS3DH (offset +-40 mg typ., sensitivity within a few %) with a wide margin.
K_DIAG_MIN = const(12582912)   # 0.75
K_DIAG_MAX = const(20971520)   # 1.25
K_OFF_MAX = const(2097152)     # |misalignment| <= 0.125
O_MAX = const(4194304)         # |offset| <= 0.25 g
# Fit region, wider: the first steps may overshoot (alpha_m = 0.8 against large initial
# residuals) and come back.  Leaving this region means the fit diverged.
FIT_K_DIAG_MIN = const(8388608)  # 0.5
FIT_K_DIAG_MAX = const(33554432) # 2.0
FIT_K_OFF_MAX = const(8388608)   # 0.5
FIT_O_MAX = const(8388608)       # 0.5 g

# --- apply (per sample) -----------------------------------------------------------------------
# Calibrated sample = K (v + o), with K in Q14 and o in Q14 g (a composed model's apply; the base
# model keeps K - I and K o finer, APPLY_D_Q below, within the same bounds):
#   u = (x << 4) + o14 (Q14 g),  a = sum(k14 * u) >> 15 (APPLY_OUT: Q13 g, 0.12 mg).
# At +-2.048 g (the LIS3DH's 12-bit +-2 g range) and inside the parameter bounds:
# |u| <= (2.048 + 0.25) * 2**14 = 37650 and |k14| row sum <= (1.25 + 2 * 0.125) * 2**14 = 24576,
# so every product and sum is <= 9.3e8 < 2**30 (tests/device/test_ranges.py runs the worst case).
# The output keeps the sub-LSB resolution a still sensor's mean has (its noise is below one Q10
# step, so a Q10 output's rounding would not average out): |a| <= 9.3e8 >> 15 = 28 236, an int16
# word, as the log's samples are.
APPLY_Q = const(14)
APPLY_FROM_SAMPLE_SHIFT = const(4)  # APPLY_Q - SAMPLE_Q
APPLY_PARAM_SHIFT = const(10)       # PARAM_Q - APPLY_Q
APPLY_OUT_Q = const(13)             # the calibrated sample at +-2 g (APPLY_OUT_Q - e: below)
APPLY_OUT_SHIFT = const(15)         # 2 * APPLY_Q - APPLY_OUT_Q, at every full scale
# Larger full scales (+-4, 8, 16 g: range shift e = 1, 2, 3; apply_range_shift()) keep the same
# bound by giving up e bits of the reading and offset formats, as the readings span 2**e times
# more: u = (x << (4 - e)) + o in Q(14 - e) g (o = param >> (10 + e)), K still in Q14,
# a = sum(k u) >> 15 in Q(13 - e) g (APPLY_OUT_Q - e: 0.24, 0.49, 0.98 mg), the reading first
# clamped to the range's full scale, +-(APPLY_IN_MAX << e) in Q10.  Then |u| <=
# (2.048 + 0.25 / 2**e) 2**(14 - e) <= 37650 and the row sums <= 24576 again, so the products stay
# <= 9.3e8 and |a| <= 28 236 (an int16) at every range (tests/device/test_ranges.py; on the
# 32-bit MicroPython under heap_lock, test_heap.py).
APPLY_IN_MAX = const(2097)          # 2.048 g in Q10: +-2 g full scale
# A composed model first removes its effects (acal/core/effects.py) from the reading in Q(14 - e) g;
# the result is clamped to the range a reading can have, +-2.048 * 2**e g, so the bound above
# still holds (a correction that would go beyond full scale is clipped, as the sensor itself
# clips).
APPLY_W_MAX = const(33552)          # 2097 << 4: 2.048 * 2**e g in Q(14 - e)
# The base model's apply (no effects: calibration._apply_block) keeps more of the parameters:
# K = I + D with D in Q(18 - e) (d = (K24 - I) >> (6 + e), rounded) and the offsets taken in
# once, c = K o in Q(28 - e) g computed exactly from the Q24 parameters at set() (wide.mul_shift),
# and the output rounded with a dither: per sample i (the count of samples the Calibration has
# applied, from 0), with the reading x in Q10,
#   a = ((x << (18 - e)) + sum(d x) + c + r_i) >> 15   (Q(13 - e) g, as above),
#   r_i = (i * APPLY_DITHER_STEP) & APPLY_DITHER_MASK   (Q15: sqrt(2) - 1's Weyl sequence).
# A still window's readings are a few Q10 values, so sum(d x) + c keeps one fraction of the
# output's LSB through the window: rounded to the nearest (r_i = 2**14) it left up to half an LSB
# (0.06 mg a window at +-2 g, the same in every window of a posture; seed 5 of the study 1.17x
# the true model for 1.08x unrounded); the dither's mean over any run of samples is the half.
# At +-2.048 * 2**e g: |x << (18 - e)| <= 2097 * 2**18 = 5.50e8, |D| row sum <= (0.25 + 2 *
# 0.125) 2**(18 - e) so |sum(d x)| <= 0.5 * 2097 * 2**18 = 2.75e8, |c| <= 1.5 * 0.25 * 2**(28 - e)
# = 1.01e8, r_i < 2**15: every sum <= 9.26e8 < 2**30 and |a| <= 28 236 again
# (tests/device/test_ranges.py).
# The Q14 offsets' rounding (+-0.03 mg a window, the same in every window of a posture) was the
# written output's last share over the device's fit (issue 50 part 5, docs/real-recordings.md).
APPLY_D_Q = const(18)               # D = K - I in Q(APPLY_D_Q - e)
APPLY_C_Q = const(28)               # c = K o in Q(APPLY_C_Q - e) g
APPLY_DITHER_STEP = const(13573)    # round((sqrt(2) - 1) * 2**15), odd: all 2**15 values
APPLY_DITHER_MASK = const(32767)    # (literals in calibration._apply_block: viper)


def apply_range_shift(range_g):
    """The apply format's shift e for a full scale of range_g (2, 4, 8 or 16 g)."""
    for e in range(4):
        if range_g == 2 << e:
            return e
    raise ValueError("full scale must be 2, 4, 8 or 16 g")


def apply_out_q(range_g):
    """The calibrated sample's format at a full scale of range_g: Q(APPLY_OUT_Q - e) g."""
    return APPLY_OUT_Q - apply_range_shift(range_g)


# Parameter order (paper eq. 6).
KXX = const(0)
KYY = const(1)
KZZ = const(2)
KXY = const(3)
KXZ = const(4)
KYZ = const(5)
OX = const(6)
OY = const(7)
OZ = const(8)
N_PARAMS = const(9)
PARAM_NAMES = ("kxx", "kyy", "kzz", "kxy", "kxz", "kyz", "ox", "oy", "oz")

