// The emulated RP2040: real MicroPython (or CircuitPython) firmware booted on the npm emulator
// rp2040js, driven over its raw REPL on the emulated USB CDC.  Cycles are counted at 125 MHz.
//
// A library (createChip, enterRawRepl, exec, putFile, ...) for the project's other Node scripts,
// and a command:
//
//   node rp2040.mjs --rp2040js INDEX_JS --firmware FW.uf2 --bootrom ROM.bin
//        [--flavour micropython|circuitpython] [--flash-in IMG] [--flash-out IMG]
//        [--put LOCAL=REMOTE ...] [--exec SCRIPT[::STDIN_FILE] ...] [--stats FILE] [--quiet]
//        [--profile FILE]
//
// In this order: boot (from a saved flash image if given), enter the raw REPL, put each file on
// the board's filesystem (folders made as needed), soft-reset (a clean heap), run each script
// (its STDIN_FILE, if any, streamed to the script's sys.stdin while it runs) and print what it
// prints; save the flash image.  A script that raises: its error on stderr, exit 1.
// --stats appends one JSON line per script: cycles, emulated ms, wall ms.  --profile writes the
// scripts' cycles by the address of the instruction that took them, {"address": cycles, ...}
// in JSON: every cycle --stats counts, nothing else (tools/chip_profile.py names the firmware's
// functions from its ELF's symbols).
//
// What this adds to rp2040js, each marked below:
//  1. Flash writes: the boot ROM's flash_range_erase ('RE') and flash_range_program ('RP') are
//     done on the flash array (rp2040js emulates XIP reads only), so littlefs / FAT persist and
//     a flash image can be saved, cut and reloaded.
//  2. USB NAK: an OUT transfer waits until the host has bytes (rp2040js answers at once with a
//     zero-length packet: an interrupt every ~10 us, counted in every figure otherwise).
//  3. (CircuitPython) PIO stepped with the core: rp2040js runs PIO from setTimeout, which never
//     fires inside this synchronous loop; the Feather's NeoPixel is driven through PIO at boot.
//  4. (CircuitPython) BOOTSEL released: the button is sensed on the flash chip-select line,
//     which rp2040js leaves low ("pressed").
//  5. WFI with an interrupt already pending does not sleep (ARMv6-M: WFI wakes on a pending
//     interrupt that would be taken ignoring PRIMASK; rp2040js sleeps until a new one arrives).
//     CircuitPython sleeps as `disable interrupts; arm a TIMER alarm; WFI; enable`: an alarm
//     that fired before the WFI left the emulated core asleep for good, no alarm scheduled
//     (the Feather's 74-s end-to-end run stuck at 61.7 emulated s, on some heap layouts).
import fs from 'node:fs';
import { parseArgs } from 'node:util';
import { pathToFileURL } from 'node:url';

// rp2040js warns on every read of the inter-core FIFO, which the firmware polls harmlessly
const warn = console.warn;
console.warn = (...a) => { if (!/invalid SIO address/.test(String(a[0]))) warn(...a); };

export const HZ = 125e6;
const NS_PER_CYCLE = 8;
export const FLASH_SIZE = 2 * 1024 * 1024; // RPI_PICO; CircuitPython falls back to 2 MB here too
const PROMPT = 'raw REPL; CTRL-B to exit\r\n>';
const WFI = 0xbf30; // the Thumb encoding

export async function loadEmulator(indexJs) {
  return import(pathToFileURL(indexJs).href);
}

// ---------------------------------------------------------------- the chip
export function createChip(emu, { firmware, bootrom, flashIn = null, flavour = 'micropython' }) {
  const { RP2040, USBCDC, ConsoleLogger, LogLevel } = emu;
  const mcu = new RP2040();
  mcu.logger = new ConsoleLogger(LogLevel.Error);
  const rom = fs.readFileSync(bootrom);
  mcu.loadBootrom(new Uint32Array(rom.buffer, rom.byteOffset, rom.length / 4)); // resets flash
  if (flashIn) mcu.flash.set(fs.readFileSync(flashIn).subarray(0, FLASH_SIZE), 0);
  loadFirmware(mcu, firmware); // after a saved image: the firmware wins
  mcu.core.PC = 0x10000000; // boot2 at the start of flash

  // 1. flash writes, through the ROM function table (its pointer at 0x14)
  const romHalf = (a) => (mcu.bootrom[a >> 2] >>> ((a & 2) * 8)) & 0xffff;
  const romFunc = (name) => {
    const code = name.charCodeAt(0) | (name.charCodeAt(1) << 8);
    for (let p = romHalf(0x14); romHalf(p); p += 4) if (romHalf(p) === code) return romHalf(p + 2) & ~1;
    throw new Error(`ROM function ${name} not found`);
  };
  const chip = { mcu, cycles: 0, wakeups: 0, flavour, flashWrites: 0, hooks: new Map(), stopAt: Infinity,
    profile: null, profiling: false };
  chip.hooks.set(romFunc('RE'), (r) => { mcu.flash.fill(0xff, r[0], r[0] + r[1]); chip.flashWrites++; });
  chip.hooks.set(romFunc('RP'), (r) => { // NOR flash only clears bits
    for (let i = 0; i < r[2]; i++) mcu.flash[r[0] + i] &= mcu.readUint8(r[1] + i);
    chip.flashWrites++;
  });

  const pios = flavour === 'circuitpython' ? mcu.pio : [];
  if (flavour === 'circuitpython') {
    for (const p of mcu.pio) p.run = () => {}; // 3. stepped below instead
    mcu.qspi[1].padValue = 0x5a; // 4. the SS pad at its reset value, the line pulled high
    mcu.qspi[1].setInputValue(true);
  }

  // 2. USB CDC with NAK
  const cdc = new USBCDC(mcu.usbCtrl);
  const usb = mcu.usbCtrl;
  const answerRead = usb.onEndpointRead;
  let pendingRead = null;
  usb.onEndpointRead = (ep, size) => {
    if (ep === cdc.outEndpoint && cdc.txFIFO.empty) pendingRead = [ep, size];
    else answerRead(ep, size);
  };
  chip.cdc = cdc;
  chip.connected = false;
  chip.host = { queue: Buffer.alloc(0), pos: 0 }; // bytes the host has yet to send
  chip.rx = new Rx();
  cdc.onDeviceConnected = () => { chip.connected = true; };
  cdc.onSerialData = (buf) => chip.rx.push(buf);

  chip.send = (data) => {
    const h = chip.host;
    const more = Buffer.isBuffer(data) ? data : Buffer.from(data, 'latin1');
    h.queue = Buffer.concat([h.queue.subarray(h.pos), more]);
    h.pos = 0;
  };
  chip.sent = () => chip.host.pos >= chip.host.queue.length;
  chip.feed = () => { // host -> device, as the 512-byte FIFO has room
    const h = chip.host;
    while (h.pos < h.queue.length && !cdc.txFIFO.full) cdc.txFIFO.push(h.queue[h.pos++]);
    if (pendingRead && !cdc.txFIFO.empty) { const [ep, size] = pendingRead; pendingRead = null; answerRead(ep, size); }
  };
  chip.waitingForHost = () => pendingRead !== null;

  // run up to n cycles; false when the core sleeps with nothing scheduled
  chip.step = (n) => {
    const { core, clock } = mcu;
    const prof = chip.profiling ? chip.profile : null;   // exec() counts a script's cycles
    const end = Math.min(chip.cycles + n, chip.stopAt);
    while (chip.cycles < end) {
      if (core.waiting) { // WFE/WFI: skip to the next alarm (a wake-up when it ends the wait)
        if (!clock.nextAlarm) return false;
        chip.wakeups++;
        clock.tick(Math.max(clock.nanosToNextAlarm, 0));
        continue;
      }
      if (core.PC < 0x4000) {
        const hook = chip.hooks.get(core.PC);
        if (hook) { hook(core.registers); core.PC = core.LR & ~1; continue; } // return to the caller
      }
      const pc = prof !== null ? core.PC : 0;
      const c = core.executeInstruction();
      chip.cycles += c;
      if (prof !== null) prof.set(pc, (prof.get(pc) || 0) + c);
      // 5. WFI with an interrupt already pending does not sleep
      if (core.waiting && (core.pendingInterrupts & core.enabledInterrupts)
          && mcu.readUint16((core.PC - 2) >>> 0) === WFI) core.waiting = false;
      clock.tick(c * NS_PER_CYCLE);
      for (const p of pios) if (!p.stopped) for (let i = 0; i < c; i++) p.step();
    }
    return true;
  };

  chip.runUntil = (done, what, maxCycles = HZ * 600) => {
    const start = chip.cycles;
    while (!done()) {
      if (chip.cycles >= chip.stopAt) throw new PowerCut(chip.cycles);
      chip.feed();
      // asleep, nothing scheduled, the host's bytes all delivered (a read waiting for more
      // waits for good): nothing can change
      if (!chip.step(20000) && !done() && chip.sent() && (!pendingRead || cdc.txFIFO.empty)) {
        if (!chip.step(1)) throw new Error(`stuck waiting for ${what}; got: ${chip.rx.tail(300)}`);
      }
      if (chip.cycles - start > maxCycles) throw new Error(`timeout waiting for ${what}`);
    }
  };
  chip.flashImage = () => Buffer.from(mcu.flash.subarray(0, FLASH_SIZE));
  return chip;
}

// The chip stopped at chip.stopAt cycles (a power cut): what ran before it is in the flash.
export class PowerCut extends Error {
  constructor(cycles) { super(`power cut at cycle ${cycles}`); this.cycles = cycles; }
}

// Bytes from the device: kept as chunks, with the count of ^D (0x04) seen, so that waiting for
// the end of a long output costs nothing per byte.
class Rx {
  constructor() { this.chunks = []; this.length = 0; this.eots = 0; this.last = Buffer.alloc(0); }
  push(buf) {
    const b = Buffer.from(buf);
    this.chunks.push(b);
    this.length += b.length;
    for (const x of b) if (x === 4) this.eots++;
    this.last = Buffer.concat([this.last, b]).subarray(-64);
  }
  endsWith(s) { return this.last.toString('latin1').endsWith(s); }
  text() { return Buffer.concat(this.chunks).toString('latin1'); }
  take() { const s = this.text(); this.chunks = []; this.length = 0; this.eots = 0; this.last = Buffer.alloc(0); return s; }
  tail(n) { return this.text().slice(-n); }
}

function loadFirmware(mcu, file) {
  const data = fs.readFileSync(file);
  if (file.endsWith('.uf2')) { // 512-byte blocks: magic, flags, address, size, ..., payload at 32
    for (let off = 0; off + 512 <= data.length; off += 512) {
      if (data.readUInt32LE(off) !== 0x0a324655 || data.readUInt32LE(off + 508) !== 0x0ab16f30) {
        throw new Error(`${file}: not a UF2 file`);
      }
      const addr = data.readUInt32LE(off + 12), size = data.readUInt32LE(off + 16);
      mcu.flash.set(data.subarray(off + 32, off + 32 + size), addr - 0x10000000);
    }
  } else mcu.flash.set(data, 0); // a .bin image of flash from 0x10000000
}

// ---------------------------------------------------------------- the raw REPL
export function enterRawRepl(chip) {
  chip.runUntil(() => chip.connected, 'USB enumeration', HZ * 30);
  chip.send('\r\x03\x03');
  chip.runUntil(() => chip.rx.text().includes('>>> '), 'the friendly prompt', HZ * 30);
  chip.rx.take();
  chip.send('\x01');
  chip.runUntil(() => chip.rx.endsWith(PROMPT), 'the raw REPL', HZ * 30);
  chip.rx.take();
}

export function softReset(chip) { // in the raw REPL: ^D soft-reboots and stays raw
  chip.send('\x04');
  chip.runUntil(() => chip.rx.endsWith(PROMPT), 'a soft reset', HZ * 30);
  chip.rx.take();
}

// Run code; stdin (bytes) is streamed to the script while it runs.  Returns
// { out, err, cycles, wakeups, emuMs, wallMs }: cycles executed from ^D to the reply, and the
// waits (WFE/WFI) the core slept through to an alarm meanwhile.
export function exec(chip, code, { stdin = null, maxCycles = HZ * 3600 } = {}) {
  chip.send(code);
  chip.runUntil(chip.sent, 'the code upload');
  const c0 = chip.cycles, w0 = chip.wakeups, n0 = chip.mcu.clock.nanos, t0 = performance.now();
  chip.send('\x04');
  if (stdin) chip.send(stdin);
  // "OK", the output, ^D, the error, ^D, ">"
  chip.profiling = Boolean(chip.profile);
  try {
    chip.runUntil(() => chip.rx.eots >= 2 && chip.rx.endsWith('\x04>'), 'the script end', maxCycles);
  } finally {
    chip.profiling = false;
  }
  const wallMs = performance.now() - t0;
  const text = chip.rx.take();
  if (!text.startsWith('OK')) throw new Error(`the raw REPL refused the code: ${text.slice(0, 200)}`);
  const [out, err] = text.slice(2, -1).split('\x04');
  return { out, err, cycles: chip.cycles - c0, wakeups: chip.wakeups - w0,
    emuMs: (chip.mcu.clock.nanos - n0) / 1e6, wallMs };
}

function check(r) {
  if (r.err) throw new Error(r.err.trim().split('\n').pop());
  return r;
}

// CircuitPython's drive is read-only to code until remounted (a board does it in boot.py).
export function makeWritable(chip) {
  if (chip.flavour === 'circuitpython') check(exec(chip, "import storage\nstorage.remount('/', readonly=False)"));
}

// A file onto the board: one script receives it as hex lines on stdin (no code per chunk).
export function putFile(chip, data, remote) {
  const dirs = remote.split('/').slice(0, -1).map((_, i, a) => a.slice(0, i + 1).join('/')).filter(Boolean);
  const hex = data.toString('hex').match(/.{1,1024}/g) || [];
  const code = `import os, sys, binascii
for d in ${JSON.stringify(dirs)}:
    try:
        os.mkdir(d)
    except OSError:
        pass
with open(${JSON.stringify(remote)}, 'wb') as f:
    for _ in range(${hex.length}):
        f.write(binascii.unhexlify(sys.stdin.readline().strip()))
`;
  check(exec(chip, code, { stdin: hex.map((h) => h + '\n').join('') }));
}

export function readFile(chip, remote) {
  const r = check(exec(chip, `import binascii\nwith open(${JSON.stringify(remote)}, 'rb') as f:\n    while True:\n        b = f.read(512)\n        if not b:\n            break\n        print(binascii.hexlify(b).decode())\n`));
  return Buffer.from(r.out.replace(/\s+/g, ''), 'hex');
}

// ---------------------------------------------------------------- command line
function main() {
  const { values } = parseArgs({ options: {
    rp2040js: { type: 'string' }, firmware: { type: 'string' }, bootrom: { type: 'string' },
    flavour: { type: 'string', default: 'micropython' },
    'flash-in': { type: 'string' }, 'flash-out': { type: 'string' },
    put: { type: 'string', multiple: true, default: [] }, exec: { type: 'string', multiple: true, default: [] },
    stats: { type: 'string' }, quiet: { type: 'boolean', default: false },
    profile: { type: 'string' },
  } });
  for (const need of ['rp2040js', 'firmware', 'bootrom']) {
    if (!values[need]) { console.error(`rp2040.mjs: --${need} is required`); process.exit(2); }
  }
  const log = (s) => { if (!values.quiet) console.error(s); };
  return loadEmulator(values.rp2040js).then((emu) => {
    const t0 = performance.now();
    const chip = createChip(emu, { firmware: values.firmware, bootrom: values.bootrom,
      flashIn: values['flash-in'], flavour: values.flavour });
    enterRawRepl(chip);
    log(`# booted: ${chip.cycles} cycles, ${(performance.now() - t0).toFixed(0)} wall ms`);
    if (values.put.length) makeWritable(chip);
    for (const spec of values.put) {
      const [local, remote] = spec.split('=');
      putFile(chip, fs.readFileSync(local), remote);
    }
    softReset(chip);
    if (values.profile) chip.profile = new Map();
    let failed = false;
    for (const spec of values.exec) {
      const [file, input] = spec.split('::');
      const r = exec(chip, fs.readFileSync(file, 'utf8'), { stdin: input ? fs.readFileSync(input) : null });
      process.stdout.write(r.out.replace(/\r\n/g, '\n'));
      if (r.err) { process.stderr.write(r.err.replace(/\r\n/g, '\n')); failed = true; }
      if (values.stats) {
        fs.appendFileSync(values.stats, JSON.stringify({ script: file, cycles: r.cycles,
          ms: r.cycles / (HZ / 1e3), emulated_ms: r.emuMs, wall_ms: r.wallMs }) + '\n');
      }
      log(`# ${file}: ${r.cycles} cycles = ${(r.cycles / (HZ / 1e3)).toFixed(1)} ms at 125 MHz, wall ${r.wallMs.toFixed(0)} ms`);
      if (failed) break;
    }
    if (values['flash-out']) fs.writeFileSync(values['flash-out'], chip.flashImage());
    if (values.profile) fs.writeFileSync(values.profile, JSON.stringify(Object.fromEntries(chip.profile)));
    process.exitCode = failed ? 1 : 0;
  });
}

if (process.argv[1] && import.meta.url === pathToFileURL(process.argv[1]).href) {
  main().catch((e) => { console.error(`rp2040.mjs: ${e.message}`); process.exitCode = 3; });
}
