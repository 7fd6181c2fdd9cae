// The ST LIS3DH on the emulated RP2040's I2C0: the register model of the virtual board's
// simulate/chip/vlis3dh.py, written again for Node (the emulator calls it on every bus event) and
// held to it by tests/bridge/test_pico_lis3dh.py (the same register operations at the same times,
// every byte read compared) and, field by field, to the datasheet by
// tests/device/test_lis3dh_conformance.py (docs/lis3dh-conformance.md).  Written from ST's
// datasheet (DocID17530 Rev 2) and register header (lis3dh_reg.h), as vlis3dh.py says: WHO_AM_I;
// BOOT; CTRL_REG1 ODR/LPen; CTRL_REG4 FS/HR/BDU; TEMP_CFG_REG and OUT_ADC3 (relative temperature,
// 1 digit/degC); outputs left-justified at 12/10/8 bits; STATUS_REG ZYXDA/ZYXOR; the 32-level
// FIFO (bypass, FIFO, stream, stream-to-FIFO by INT1 = I1_WTM.WTM + I1_OVERRUN.OVRN_FIFO) keeping
// 10 bits, FIFO_SRC_REG WTM (unread > FTH), OVRN_FIFO (32 unread), EMPTY, FSS (31 at 32);
// auto-increment with the FIFO's roll-over from OUT_Z_H to OUT_X_L.  Samples are converted on the
// emulated clock at the ODR, each reading the stimulus sample of its time (vlis3dh.py's format).
//
// What the wire adds (the Python model is called per transaction; here the bytes come one by one):
//  * bus time: START, each byte (9 bits) and STOP take their SCL periods, from the I2C block's
//    own SCL counts (400 kHz: 22.5 us a byte), so a read costs the firmware what it costs a Pico;
//  * BDU: with CTRL_REG4's BDU set, an axis's output is held from the read of its low byte to the
//    read of its high byte (without it a sample converted between the two tears the value);
//  * faults: fault_per_mille of transactions (a START that is not a repeated one) are NACKed in
//    the address phase, drawn from vbus.py's seeded generator (Lehmer, m = 2^30 - 35, a = 16808).
//    rp2040js raises no TX_EMPTY after an address NACK (the TX FIFO is flushed: on the chip
//    that level-triggered interrupt is then set), so the SDK would wait out its timeout and report
//    ETIMEDOUT; it is set here, and machine.I2C raises EIO as on a Pico;
//  * pins: the chip answers only when GP4/GP5 (boards/pico.py) are switched to I2C.
import fs from 'node:fs';

export const WHO_AM_I_VALUE = 0x33;
const ODR_HZ = [0, 1, 10, 25, 50, 100, 200, 400, 1600, 1344];
const SO_MG = [1, 2, 4, 12];

const STATUS_AUX = 0x07, OUT_ADC1_L = 0x08, WHO_AM_I = 0x0f, TEMP_CFG = 0x1f, CTRL1 = 0x20;
const CTRL3 = 0x22, CTRL4 = 0x23, CTRL5 = 0x24, STATUS = 0x27, OUT_X_L = 0x28, FIFO_CTRL = 0x2e, FIFO_SRC = 0x2f;

const floorDiv = (a, b) => Math.floor(a / b);
const mod = (a, b) => ((a % b) + b) % b;

// ---------------------------------------------------------------- the stimulus file
export class Stimulus {
  constructor(path) {
    this.fd = fs.openSync(path, 'r');
    const head = Buffer.alloc(16);
    if (fs.readSync(this.fd, head, 0, 16, 0) !== 16 || head.toString('latin1', 0, 4) !== 'ACST') {
      throw new Error(`not a stimulus file: ${path}`);
    }
    const version = head.readUInt16LE(4);
    this.rateHz = head.readUInt16LE(6);
    this.n = head.readUInt32LE(8);
    this.hasSupply = version === 2;
    this.size = this.hasSupply ? 20 : 16;
    this.block = Buffer.alloc(this.size * 256);
    this.first = -1;
    this.count = 0;
    this.x = this.y = this.z = this.tempMc = this.supplyMv = 0;
  }

  load(k) { // sample k current; false past the end (the last one stays)
    if (k >= this.n) return false;
    if (!(this.first <= k && k < this.first + this.count)) {
      this.first = k;
      this.count = Math.floor(fs.readSync(this.fd, this.block, 0, this.block.length, 16 + this.size * k) / this.size);
    }
    const j = this.size * (k - this.first);
    this.x = this.block.readInt32LE(j);
    this.y = this.block.readInt32LE(j + 4);
    this.z = this.block.readInt32LE(j + 8);
    this.tempMc = this.block.readInt32LE(j + 12);
    if (this.hasSupply) this.supplyMv = this.block.readInt32LE(j + 16);
    return true;
  }
}

// ---------------------------------------------------------------- the register model
// clock: { s, us } now (whole seconds and microseconds), as vclock.Clock keeps them.
export class LIS3DH {
  constructor(stimulus, clock, tempRefMc = 25000) {
    this.stim = stimulus;
    this.clock = clock;
    this.tempRefMc = tempRefMc;
    this.regs = new Uint8Array(0x40);
    this.fifo = Array.from({ length: 32 }, () => [0, 0, 0]);
    this.dropped = 0;      // ground truth: samples the FIFO overwrote or refused
    this.generated = 0;    // samples converted since the ODR was (re)started
    this.converted = 0;    // samples converted since power-up
    this.starts = [];      // each (re)start of the ODR's time line: [s, us] since the epoch
    this.exhausted = false;
    this.spiSelected = false; // the SPI front end (vlis3dh.py spi_select/spi_byte): CS low
    this.spiCmd = -1;
    this.spiReg = 0;
    this.onSample = null;  // (this) after each conversion: the board's supply follows it
    const [s, us] = this.now();
    this.epochS = s;
    this.epochUs = us;
    this.reset();
  }

  now() { const c = this.clock(); return [c.s, c.us]; }

  reset() {
    this.regs.fill(0);
    this.regs[WHO_AM_I] = WHO_AM_I_VALUE;
    this.regs[CTRL1] = 0x07;
    this.fifoLevel = 0;   // u: unread sets
    this.fifoHead = 0;
    this.fifoStopped = false; // FIFO mode filled up: nothing more until bypass
    this.start();
    this.out = [0, 0, 0];
    this.shown = [0, 0, 0];   // what the output registers show (BDU holds an axis here)
    this.held = [false, false, false];
    this.newData = false;
    this.overrun = false;
  }

  start() {
    [this.startS, this.startUs] = this.now();
    this.generated = 0;
    this.starts.push([this.startS - this.epochS, this.startUs - this.epochUs]);
  }

  odrHz() { const c = this.regs[CTRL1] >> 4; return c < 10 ? ODR_HZ[c] : 0; }
  bits() { return this.regs[CTRL1] & 0x08 ? 8 : (this.regs[CTRL4] & 0x08 ? 12 : 10); }
  soMg() { return SO_MG[(this.regs[CTRL4] >> 4) & 3] << (12 - this.bits()); }
  fifoMode() { return this.regs[CTRL5] & 0x40 ? (this.regs[FIFO_CTRL] >> 6) & 3 : 0; }
  bdu() { return (this.regs[CTRL4] & 0x80) !== 0; }
  fth() { return this.regs[FIFO_CTRL] & 0x1f; }
  wtm() { return this.fifoLevel > this.fth(); }
  int1() { const c3 = this.regs[CTRL3]; return !!((c3 & 0x04 && this.wtm()) || (c3 & 0x02 && this.fifoLevel === 32)); }
  collectingMode() { // 1 FIFO (stops when full), 2 stream (overwrites); stream-to-FIFO by its pin
    const m = this.fifoMode();
    if (m === 3) return (this.regs[FIFO_CTRL] & 0x20 ? false : this.int1()) ? 1 : 2;
    return m;
  }

  raw(ug) { // to the digit of the resolution (half away from zero), clipped, left-justified
    const bits = this.bits(), step = this.soMg() * 1000;
    let d = ug >= 0 ? floorDiv(ug + floorDiv(step, 2), step) : -floorDiv(-ug + floorDiv(step, 2), step);
    const lim = 1 << (bits - 1);
    if (d >= lim) d = lim - 1; else if (d < -lim) d = -lim;
    return (d << (16 - bits)) & 0xffff;
  }

  catchUp() { // every sample due by now (vlis3dh.py catch_up, the same integers)
    const hz = this.odrHz();
    if (hz === 0) return;
    const period = floorDiv(1000000, hz), sps = floorDiv(1000000, period), defect = 1000000 - sps * period;
    const [s, us] = this.now();
    const ds = s - this.startS;
    const due = ds * sps + floorDiv(ds * defect + us - this.startUs, period);
    const rate = this.stim.rateHz;
    while (this.generated < due) {
      const n = this.generated + 1, a = floorDiv(n, sps);
      let tS = this.startS - this.epochS + a;
      let tUs = this.startUs - this.epochUs + (n - a * sps) * period - a * defect;
      tS += floorDiv(tUs, 1000000);
      tUs = mod(tUs, 1000000);
      const k = tS * rate + floorDiv(floorDiv(tUs, 1000) * rate + floorDiv((tUs % 1000) * rate, 1000), 1000);
      if (!this.stim.load(k)) this.exhausted = true;
      this.generated++;
      this.converted++;
      const out = this.out;
      out[0] = this.raw(this.stim.x);
      out[1] = this.raw(this.stim.y);
      out[2] = this.raw(this.stim.z);
      for (let i = 0; i < 3; i++) if (!this.held[i]) this.shown[i] = out[i];
      if (this.newData) this.overrun = true;
      this.newData = true;
      this.store(out);
      if (this.onSample) this.onSample(this);
    }
  }

  store(out) { // the FIFO's side of a conversion (vlis3dh.py _store)
    const mode = this.collectingMode();
    if (!mode) return;
    let slot = null;
    if (this.fifoStopped && this.fifoMode() === 1) {
      this.dropped++;
    } else if (this.fifoLevel < 32) {
      slot = this.fifo[(this.fifoHead + this.fifoLevel) % 32];
      this.fifoLevel++;
      if (this.fifoLevel === 32 && this.fifoMode() === 1) this.fifoStopped = true;
    } else if (mode === 2) { // stream: the oldest is overwritten
      slot = this.fifo[this.fifoHead];
      this.fifoHead = (this.fifoHead + 1) % 32;
      this.dropped++;
    } else { // FIFO mode stops when full
      this.dropped++;
    }
    if (slot) for (let i = 0; i < 3; i++) slot[i] = out[i] & 0xffc0; // the top 10 bits kept
  }

  readByte(reg) {
    if (reg >= OUT_X_L && reg < OUT_X_L + 6) {
      const k = reg - OUT_X_L, axis = k >> 1;
      let v;
      if (this.fifoMode()) {
        v = (this.fifoLevel === 0 ? this.out : this.fifo[this.fifoHead])[axis];
        if (k === 5 && this.fifoLevel > 0) { // empty: the latest conversion, nothing popped
          this.fifoHead = (this.fifoHead + 1) % 32;
          this.fifoLevel--;
        }
      } else {
        v = this.shown[axis];
        if (this.bdu()) this.held[axis] = !(k & 1); // held from its low byte to its high byte
        if (!this.held[axis]) this.shown[axis] = this.out[axis];
        if (k === 5) { this.newData = false; this.overrun = false; }
      }
      return k & 1 ? (v >> 8) & 0xff : v & 0xff;
    }
    if (reg === STATUS) return (this.newData ? 0x08 : 0) | (this.overrun ? 0x80 : 0);
    if (reg === FIFO_SRC) {
      const u = this.fifoLevel;
      return (u > this.fth() ? 0x80 : 0) | (u === 32 ? 0x40 : 0) | (u === 0 ? 0x20 : 0) | (u === 32 ? 31 : u);
    }
    if (reg >= OUT_ADC1_L && reg < OUT_ADC1_L + 6) {
      if (reg >= 0x0c && (this.regs[TEMP_CFG] & 0xc0) === 0xc0) {
        let d = floorDiv(this.stim.tempMc - this.tempRefMc + 500, 1000);
        d = Math.max(-128, Math.min(127, d));
        return reg === 0x0d ? d & 0xff : 0;
      }
      return 0;
    }
    if (reg === STATUS_AUX) return (this.regs[TEMP_CFG] & 0xc0) === 0xc0 ? 0x44 : 0;
    return this.regs[reg];
  }

  writeByte(reg, v) {
    this.catchUp();
    if (reg === CTRL5 && v & 0x80) { this.reset(); return; } // BOOT
    if (reg === WHO_AM_I || reg === STATUS || reg === FIFO_SRC || (reg >= OUT_X_L && reg < OUT_X_L + 6)) return;
    const oldOdr = this.odrHz();
    this.regs[reg] = v;
    if (reg === CTRL1 && this.odrHz() !== oldOdr) this.start();
    if ((reg === FIFO_CTRL || reg === CTRL5) && this.fifoMode() === 0) { // bypass empties it
      this.fifoLevel = 0;
      this.fifoHead = 0;
      this.fifoStopped = false;
    }
  }

  // The SPI front end (DocID17530 6.2; vlis3dh.py spi_select/spi_byte): CS low starts a
  // transaction whose first byte is RW (bit 7), MS (bit 6), AD5:0; SDO not driven reads 0.
  spiSelect(low) { this.spiSelected = low; this.spiCmd = -1; }

  spiByte(v) {
    if (!this.spiSelected) return 0;
    this.catchUp();
    if (this.spiCmd < 0) { this.spiCmd = v; this.spiReg = v & 0x3f; return 0; }
    const reg = this.spiReg;
    if (this.spiCmd & 0x40) this.spiReg = reg + 1 === OUT_X_L + 6 && this.fifoMode() ? OUT_X_L : reg + 1;
    if (this.spiCmd & 0x80) return this.readByte(reg);
    this.writeByte(reg, v);
    return 0;
  }

  // A transaction's bytes, as vlis3dh.py's read()/write() take them (the equivalence test).
  read(reg, n) {
    this.catchUp();
    const inc = reg & 0x80, out = [];
    reg &= 0x7f;
    for (let i = 0; i < n; i++) {
      out.push(this.readByte(reg));
      if (inc) { reg++; if (reg === OUT_X_L + 6 && this.fifoMode()) reg = OUT_X_L; }
    }
    return out;
  }

  write(reg, data) {
    const inc = reg & 0x80;
    reg &= 0x7f;
    for (const v of data) { this.writeByte(reg, v); if (inc) reg++; }
  }
}

// ---------------------------------------------------------------- faults (vbus.py's generator)
const M = 1073741789, A = 16808, Q = 63882, RQ = 13133;
export class Faults {
  constructor(perMille = 0, seed = 1) { this.perMille = perMille; this.state = seed % M || 1; }
  next() { // true: this transaction fails
    if (!this.perMille) return false;
    let x = this.state;
    x = A * (x % Q) - RQ * Math.floor(x / Q);
    if (x <= 0) x += M;
    this.state = x;
    return x % 1000 < this.perMille;
  }
}

// ---------------------------------------------------------------- on the emulated I2C0
// The emulated clock as { s, us }.
export function emulatedClock(mcu) {
  return () => { const us = Math.floor(mcu.clock.nanos / 1000); return { s: Math.floor(us / 1e6), us: us % 1e6 }; };
}

const R_TX_EMPTY = 1 << 4;
const FUNC_I2C = 3, FUNC_SPI = 1;
const SSPCR0_SPO = 1 << 6, SSPCR0_SPH = 1 << 7;

// Wire the model to the chip's I2C (bus, sda, scl) or, with spi = { bus, sck, mosi, miso, cs },
// to an SPI block and a chip-select GPIO instead (the chip is wired one way, as on a board).
// Returns { lis3dh, stats }.
export function attachLis3dh(chip, { stimulus, address = 0x18, faultPerMille = 0, seed = 1,
  bus = 0, sda = 4, scl = 5, busTiming = true, tempRefMc = 25000, spi = null } = {}) {
  const { mcu } = chip;
  const dev = new LIS3DH(new Stimulus(stimulus), emulatedClock(mcu), tempRefMc);
  const faults = new Faults(faultPerMille, seed);
  const stats = { transactions: 0, faults: 0, bytes: 0 };
  if (dev.stim.hasSupply) {
    dev.onSample = (d) => { mcu.adc.channelValues[3] = Math.max(0, Math.min(4095, Math.round(d.stim.supplyMv * 4095 / 9900))); };
  }
  if (spi) { attachSpi(mcu, dev, stats, spi, busTiming); return { lis3dh: dev, stats, faults }; }
  const i2c = mcu.i2c[bus];
  let pending = null;
  const alarm = mcu.clock.createAlarm(() => { const f = pending; pending = null; f(); });
  const bitNs = () => Math.max(1, i2c.sclHighPeriod + i2c.sclLowPeriod) * 8; // clk_sys at 125 MHz
  const after = (bits, f) => { if (!busTiming) { f(); return; } pending = f; alarm.schedule(bits * bitNs()); };
  // The bus's pull-ups: SDA and SCL read high (rp2040js reads a pin as 0 unless told).  After a
  // failed register-address write MicroPython ends the transfer with a STOP bit-banged on the
  // pins, which waits for SCL to read high: without this, its 50 ms timeout on every fault.
  for (const p of [sda, scl]) mcu.gpio[p].setInputValue(true);
  const wired = () => mcu.gpio[sda].functionSelect === FUNC_I2C && mcu.gpio[scl].functionSelect === FUNC_I2C;

  // A transaction starts on a START after a STOP: rp2040js calls a START "repeated" whenever the
  // SDK flags its first byte RESTART, which it does after a failed write that kept the bus.
  let reg = 0, first = false, ours = false, failing = false, idle = true;
  i2c.onStart = () => {
    if (idle) { stats.transactions++; failing = faults.next(); if (failing) stats.faults++; }
    idle = false;
    after(1, () => i2c.completeStart());
  };
  i2c.onConnect = (addr, mode) => {
    ours = addr === address && wired() && !failing;
    if (ours && mode === 1) dev.catchUp();
    first = mode === 0;
    after(9, () => {
      i2c.completeConnect(ours);
      if (!ours) i2c.setInterrupts(R_TX_EMPTY); // the flushed TX FIFO: see the top
    });
  };
  i2c.onWriteByte = (v) => {
    stats.bytes++;
    if (first) reg = v; // the sub-address
    else { dev.writeByte(reg & 0x7f, v); if (reg & 0x80) reg = (reg & 0x80) | ((reg & 0x7f) + 1); }
    first = false;
    after(9, () => i2c.completeWrite(true));
  };
  i2c.onReadByte = () => {
    stats.bytes++;
    dev.catchUp();
    const r = reg & 0x7f;
    const v = dev.readByte(r);
    if (reg & 0x80) {
      let nr = r + 1;
      if (nr === OUT_X_L + 6 && dev.fifoMode()) nr = OUT_X_L;
      reg = 0x80 | nr;
    }
    after(9, () => i2c.completeRead(v));
  };
  i2c.onStop = () => { idle = true; after(1, () => i2c.completeStop()); };
  return { lis3dh: dev, stats, faults };
}

// The SPI front end on an RP2040 SPI block (rp2040js's PL022: onTransmit(byte) for each frame
// the block starts, completeTransmit(rx) when it ends): CS is a GPIO the firmware drives (SIO);
// while it is low each byte goes to the model (LIS3DH.spiByte) and its answer comes back
// dataBits SPI clock periods later, the clock from the block's own prescaler and SCR
// (clk_peri / (CPSDVSR (1 + SCR)): 8.93 MHz for MicroPython's baudrate=10_000_000 at 125 MHz).
// The chip answers only with SCK/MOSI/MISO switched to SPI and in mode 0 or 3 (CPOL = CPHA: it
// latches SDI on SPC's rising edge); else MISO reads 0.  Frames follow each other without gaps
// (the PL022 in Motorola mode with SPH = 1 keeps SSPFSSOUT low; we do not model the one-bit gap
// it inserts with SPH = 0).  DMA (MicroPython uses it for 32 bytes and more) works through the
// block's DREQs, which rp2040js raises.
function attachSpi(mcu, dev, stats, { bus = 0, sck, mosi, miso, cs }, busTiming) {
  const port = mcu.spi[bus];
  stats.spi = { bus, sck, mosi, miso, cs };
  const wired = () => [sck, mosi, miso].every((p) => mcu.gpio[p].functionSelect === FUNC_SPI)
    && !(port.control0 & SSPCR0_SPO) === !(port.control0 & SSPCR0_SPH);
  mcu.gpio[cs].addListener((v) => { // 0: GPIOPinState.Low, an output driven low
    const low = v === 0;
    if (low === dev.spiSelected) return;
    dev.spiSelect(low);
    if (low) stats.transactions++;
  });
  let pending = null;
  const alarm = mcu.clock.createAlarm(() => { const f = pending; pending = null; f(); });
  port.onTransmit = (v) => {
    stats.bytes++;
    const rx = dev.spiSelected && wired() ? dev.spiByte(v) : 0;
    if (!busTiming || !port.clockFrequency) { port.completeTransmit(rx); return; }
    pending = () => port.completeTransmit(rx);
    alarm.schedule(Math.round(port.dataBits * 1e9 / port.clockFrequency));
  };
}

// The model's ground truth, for a run's report.
export function lis3dhReport(att) {
  const d = att.lis3dh;
  return { converted: d.converted, generated: d.generated, dropped: d.dropped, exhausted: d.exhausted,
    starts: d.starts, stimulus_rate_hz: d.stim.rateHz, transactions: att.stats.transactions,
    faults: att.stats.faults, bytes: att.stats.bytes, spi: att.stats.spi || null };
}

// ---------------------------------------------------------------- the equivalence test's driver
// node lis3dh.mjs --ops OPS.json --stimulus STIM: OPS is a list of [t_us, 'w', reg, [bytes]] or
// [t_us, 'r', reg, n] (I2C) or [t_us, 's', 0, [bytes]] (one SPI transaction, its bytes read back); prints one JSON list of the bytes each read gave.
async function main() {
  const { parseArgs } = await import('node:util');
  const { values } = parseArgs({ options: { ops: { type: 'string' }, stimulus: { type: 'string' } } });
  let t = 0;
  const dev = new LIS3DH(new Stimulus(values.stimulus), () => ({ s: Math.floor(t / 1e6), us: t % 1e6 }));
  const reads = [];
  for (const [tUs, op, reg, arg] of JSON.parse(fs.readFileSync(values.ops, 'utf8'))) {
    t = tUs;
    if (op === 'w') dev.write(reg, arg);
    else if (op === 's') { // one SPI transaction: CS low, the bytes, CS high
      dev.spiSelect(true);
      reads.push(arg.map((b) => dev.spiByte(b)));
      dev.spiSelect(false);
    } else reads.push(dev.read(reg, arg));
  }
  process.stdout.write(JSON.stringify({ reads, dropped: dev.dropped, converted: dev.converted }) + '\n');
}

const { pathToFileURL } = await import('node:url');
if (process.argv[1] && import.meta.url === pathToFileURL(process.argv[1]).href) {
  main().catch((e) => { console.error(`lis3dh.mjs: ${e.message}`); process.exitCode = 2; });
}
