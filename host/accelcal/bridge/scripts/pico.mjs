// The emulated Pico board: the RP2040 of rp2040.mjs with the LIS3DH of lis3dh.mjs on its I2C0
// (GP4/GP5, as boards/pico.py wires it), fed by a stimulus file.
//
//   node pico.mjs --rp2040js INDEX_JS --firmware FW.uf2 --bootrom ROM.bin [--flash-in IMG]
//        [--flash-out IMG] [--stimulus STIM] [--bus-faults PER_MILLE] [--seed N]
//        [--flavour micropython|circuitpython] [--i2c BUS,SDA,SCL | --spi BUS,SCK,MOSI,MISO,CS] MODE ...
//
// --i2c: where the LIS3DH is wired (default 0,4,5: the Pico's I2C0; the Feather RP2040's
// board.I2C() is 1,2,3); --spi: wired to an SPI block and a chip-select GPIO instead (the Pico's
// SPI0 as boards/pico.py has it: 0,18,19,16,17; the Feather's board.SPI() and D5: 0,18,19,20,7).  CircuitPython (--flavour): its drive is made writable to code for the
// --put files (until the next power-up: a board that logs does it in boot.py).
//
// MODE run:   [--put LOCAL=REMOTE]... [--exec SCRIPT]... [--get REMOTE=LOCAL]... [--report FILE]
//             as rp2040.mjs's command (boot, raw REPL, put, soft reset, run each script), then
//             copy files off the board; --report: one JSON object, the chip model's ground truth
//             (samples converted, FIFO overwrites, ODR starts, bus transactions and faults) and
//             each script's cycles.  A script that raises: exit 1.
// MODE serve: the board's USB CDC on stdin/stdout, byte for byte, for a relay to a pseudo-
//             terminal (board/emulated.py); the flash image is saved to --flash-out when stdin
//             closes or on SIGTERM.  Emulated time runs while the firmware has work (a script, a
//             sleep with its timer armed) and stands still while it waits for the host, so an
//             idle board costs nothing and a session's samples do not depend on the host's pace.
// MODE cuts:  --cut-at C1,C2,... --exec WORKLOAD --exec RESUME [--get REMOTE]... --report FILE:
//             for each cut, from --flash-in: run WORKLOAD and power off C cycles into it ('end':
//             no cut), then power up a second chip on the flash as the cut left it, read the
//             --get files (as they are before anything runs), run RESUME, read them again; one
//             JSON line per cut in FILE (files in hex; a boot or script that fails, its error).
import fs from 'node:fs';
import { parseArgs } from 'node:util';
import { pathToFileURL } from 'node:url';
import * as R from './rp2040.mjs';
import { attachLis3dh, lis3dhReport } from './lis3dh.mjs';
import { attachProbeAck } from './i2c_probe.mjs';

const OPTIONS = {
  rp2040js: { type: 'string' }, firmware: { type: 'string' }, bootrom: { type: 'string' },
  'flash-in': { type: 'string' }, 'flash-out': { type: 'string' },
  stimulus: { type: 'string' }, 'bus-faults': { type: 'string', default: '0' },
  seed: { type: 'string', default: '1' },
  flavour: { type: 'string', default: 'micropython' }, i2c: { type: 'string', default: '0,4,5' },
  spi: { type: 'string' },
  put: { type: 'string', multiple: true, default: [] }, exec: { type: 'string', multiple: true, default: [] },
  get: { type: 'string', multiple: true, default: [] }, report: { type: 'string' },
  'cut-at': { type: 'string' },
};

// The files that exist among names, in hex, read by one script.
const hexFiles = (chip, names) => {
  const r = R.exec(chip, `import binascii\nfor n in ${JSON.stringify(names)}:
    try:
        f = open(n, 'rb')
    except OSError:
        continue
    print(n, binascii.hexlify(f.read()).decode())
    f.close()
`);
  if (r.err) throw new Error(r.err.trim().split('\n').pop());
  const out = {};
  for (const line of r.out.split('\n')) {
    const [n, hex] = line.trim().split(' ');
    if (n) out[n] = hex || '';
  }
  return out;
};

// One power cut and the power-up after it (MODE cuts).
function cutAndReboot(emu, v, cutAt, tmpImage) {
  const { chip } = bootPico(emu, v);
  R.enterRawRepl(chip);
  chip.send(fs.readFileSync(v.exec[0], 'utf8'));
  chip.runUntil(chip.sent, 'the code upload');
  const c0 = chip.cycles;
  if (cutAt !== 'end') chip.stopAt = c0 + Number(cutAt);
  chip.send('\x04');
  let finished = false;
  try {
    chip.runUntil(() => chip.rx.eots >= 2 && chip.rx.endsWith('\x04>'), 'the workload end', R.HZ * 3600);
    finished = true;
  } catch (e) {
    if (!(e instanceof R.PowerCut)) throw e;
  }
  const rec = { cut_at: cutAt, ran: chip.cycles - c0, finished, out: chip.rx.take().replace(/^OK/, '') };
  fs.writeFileSync(tmpImage, chip.flashImage());
  const again = bootPico(emu, { ...v, 'flash-in': tmpImage });
  try {
    R.enterRawRepl(again.chip);
    rec.before = hexFiles(again.chip, v.get);
    const r = R.exec(again.chip, fs.readFileSync(v.exec[1], 'utf8'), { maxCycles: R.HZ * 600 });
    rec.resume_out = r.out;
    rec.resume_err = r.err;
    rec.after = hexFiles(again.chip, v.get);
  } catch (e) {
    rec.boot_error = e.message;
  }
  return rec;
}

export function bootPico(emu, v) {
  const chip = R.createChip(emu, { firmware: v.firmware, bootrom: v.bootrom, flavour: v.flavour,
    flashIn: v['flash-in'] && fs.existsSync(v['flash-in']) ? v['flash-in'] : null });
  const [bus, sda, scl] = v.i2c.split(',').map(Number);
  let spi = null;
  if (v.spi) {
    const [sb, sck, mosi, miso, cs] = v.spi.split(',').map(Number);
    spi = { bus: sb, sck, mosi, miso, cs };
  }
  const sensor = v.stimulus ? attachLis3dh(chip, { stimulus: v.stimulus, bus, sda, scl, spi,
    faultPerMille: Number(v['bus-faults']), seed: Number(v.seed) }) : null;
  // CircuitPython bit-bangs its address probe on the pins
  if (sensor && !spi && v.flavour === 'circuitpython') attachProbeAck(chip, { sda, scl, address: 0x18 });
  return { chip, sensor };
}

function putAll(chip, puts) {
  for (const spec of puts) {
    const [local, remote] = spec.split('=');
    R.putFile(chip, fs.readFileSync(local), remote);
  }
}

function exists(chip, remote) {
  const r = R.exec(chip, `import os\ntry:\n    os.stat(${JSON.stringify(remote)})\n    print(1)\nexcept OSError:\n    print(0)\n`);
  return r.out.trim() === '1';
}

function run(chip, sensor, v) {
  R.enterRawRepl(chip);
  if (v.put.length) R.makeWritable(chip);   // CircuitPython only; until the next power-up
  putAll(chip, v.put);
  R.softReset(chip);
  const report = { scripts: [] };
  let failed = false;
  for (const file of v.exec) {
    const r = R.exec(chip, fs.readFileSync(file, 'utf8'));
    process.stdout.write(r.out.replace(/\r\n/g, '\n'));
    report.scripts.push({ script: file, cycles: r.cycles, wakeups: r.wakeups, emulated_ms: r.emuMs,
      wall_ms: r.wallMs });
    if (r.err) { process.stderr.write(r.err.replace(/\r\n/g, '\n')); failed = true; break; }
  }
  for (const spec of v.get) { // absent files are skipped: the caller sees which arrived
    const [remote, local] = spec.split('=');
    if (exists(chip, remote)) fs.writeFileSync(local, R.readFile(chip, remote));
  }
  if (sensor) report.lis3dh = lis3dhReport(sensor);
  report.cycles = chip.cycles;
  return { report, failed };
}

// The USB CDC on stdin/stdout.  The chip runs in slices between the event loop's turns, so
// host bytes arrive while it runs; with no work and nothing from the host it waits for stdin.
function serve(chip, v) {
  let closing = false;
  const save = () => { // whole or not at all: a kill mid-write leaves the previous image
    if (!v['flash-out']) return;
    const part = `${v['flash-out']}.${process.pid}.partial`;
    fs.writeFileSync(part, chip.flashImage());
    fs.renameSync(part, v['flash-out']);
  };
  const finish = () => { if (closing) return; closing = true; save(); process.exit(0); };
  process.on('SIGTERM', finish);
  process.stdin.on('end', finish);
  let waiting = null;
  process.stdin.on('data', (buf) => {
    chip.send(buf);
    if (waiting) { const w = waiting; waiting = null; setImmediate(w); }
  });
  const slice = () => {
    if (closing) return;
    const t0 = performance.now();
    // short turns while the firmware has read all the host sent (a reply may be on its way):
    // each turn lets stdin in, and a raw-REPL round trip costs a few of them
    const turnMs = chip.sent() && chip.waitingForHost() ? 2 : 20;
    let busy = true;
    while (performance.now() - t0 < turnMs) {
      chip.feed();
      busy = chip.step(20000);
      if (chip.rx.length) process.stdout.write(Buffer.from(chip.rx.take(), 'latin1'));
      if (!busy && chip.sent()) break;
    }
    if (!busy && chip.sent()) waiting = slice; // asleep with no timer: until the host speaks
    else setImmediate(slice);
  };
  slice();
}

async function main() {
  const { values: v, positionals } = parseArgs({ options: OPTIONS, allowPositionals: true });
  for (const need of ['rp2040js', 'firmware', 'bootrom']) {
    if (!v[need]) { console.error(`pico.mjs: --${need} is required`); process.exit(2); }
  }
  const mode = positionals[0] || 'run';
  const emu = await R.loadEmulator(v.rp2040js);
  if (mode === 'cuts') {
    const tmpImage = `${v.report}.${process.pid}.img`;
    for (const c of v['cut-at'].split(',')) {
      fs.appendFileSync(v.report, JSON.stringify(cutAndReboot(emu, v, c, tmpImage)) + '\n');
    }
    fs.rmSync(tmpImage, { force: true });
    return;
  }
  const { chip, sensor } = bootPico(emu, v);
  if (mode === 'serve') { serve(chip, v); return; }
  const { report, failed } = run(chip, sensor, v);
  if (v['flash-out']) fs.writeFileSync(v['flash-out'], chip.flashImage());
  if (v.report) fs.writeFileSync(v.report, JSON.stringify(report) + '\n');
  process.exitCode = failed ? 1 : 0;
}

if (process.argv[1] && import.meta.url === pathToFileURL(process.argv[1]).href) {
  main().catch((e) => { console.error(`pico.mjs: ${e.message}`); process.exitCode = 3; });
}
