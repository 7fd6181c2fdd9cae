// The 32-bit MicroPython runtime: MicroPython 1.27 compiled to WebAssembly (npm
// @micropython/micropython-webassembly-pyscript), run by Node.  Its small ints stop at 2**30 - 1
// as on an RP2040 or ESP32 (sys.maxsize = 2**31 - 1), so a value past 2**30 allocates here as it
// does on a board; micropython.heap_lock() works.
//
//   node mp32.mjs MICROPYTHON_MJS HEAP_BYTES PATH_DIRS SCRIPT [ARGS...]
//
// PATH_DIRS: folders joined by ":" whose .py files (and their folders' and packages') are copied
// into the interpreter's filesystem and put on sys.path (device/ first).  SCRIPT and every
// argument that names an existing file are copied in at the same absolute path, an existing
// folder is made (empty) there; files the script writes stay inside.  stdout and stderr are the script's; exit status 1 on an exception.
import fs from "node:fs";
import path from "node:path";

const [mjs, heap, dirs, script, ...args] = process.argv.slice(2);
const { loadMicroPython } = await import(mjs);

let failed = false;
const mp = await loadMicroPython({
  heapsize: Number(heap),
  stdout: (line) => process.stdout.write(line + "\n"),
  stderr: (line) => process.stderr.write(line + "\n"),
});

function mkdirs(p) {
  let cur = "";
  for (const part of p.split("/").filter(Boolean)) {
    cur += "/" + part;
    try { mp.FS.mkdir(cur); } catch (e) { /* exists */ }
  }
}

function copyIn(src, dst) {
  mkdirs(path.dirname(dst));
  mp.FS.writeFile(dst, fs.readFileSync(src));
}

// A folder's .py files and its folders', at any depth (packages, with an __init__.py or without:
// the device package's feature folders have none), but for caches and hidden folders.
function copyTree(d, root) {
  for (const entry of fs.readdirSync(d, { withFileTypes: true })) {
    const p = path.join(d, entry.name);
    if (entry.isFile() && entry.name.endsWith(".py")) {
      copyIn(p, `${root}/${entry.name}`);
    } else if (entry.isDirectory() && entry.name !== "__pycache__" && !entry.name.startsWith(".")) {
      copyTree(p, `${root}/${entry.name}`);
    }
  }
}

const lib = [];
dirs.split(":").filter(Boolean).forEach((d, i) => {
  const root = `/lib${i}`;
  mkdirs(root);
  copyTree(d, root);
  lib.push(root);
});

const absScript = path.resolve(script);
copyIn(absScript, absScript);
const argv = [absScript];
for (const a of args) {
  if (fs.existsSync(a) && fs.statSync(a).isFile()) {
    const abs = path.resolve(a);
    copyIn(abs, abs);
    argv.push(abs);
  } else if (fs.existsSync(a) && fs.statSync(a).isDirectory()) {
    const abs = path.resolve(a);   // made (empty) inside: the script may work in it
    mkdirs(abs);
    argv.push(abs);
  } else {
    argv.push(a);
  }
}

mp.globals.set("_acal_path", lib.join(":"));
mp.globals.set("_acal_argv", argv.join("\u0001"));
mp.globals.set("_acal_dir", path.dirname(absScript));
try {
  mp.runPython(`
import sys
for _p in reversed(_acal_path.split(":")):
    sys.path.insert(0, _p)
sys.argv[:] = _acal_argv.split("\\x01")
import os
os.chdir(_acal_dir)
_g = {"__name__": "__main__", "__file__": sys.argv[0]}
with open(sys.argv[0]) as _f:
    exec(_f.read(), _g)
`);
} catch (e) {
  process.stderr.write(String(e.message || e) + "\n");
  failed = true;
}
process.exitCode = failed ? 1 : 0;
