// CircuitPython probes an I2C address (adafruit_bus_device's I2CDevice, busio's scan) with a
// zero-length write, which the RP2040's I2C block cannot send: it bit-bangs that one on the pins
// (SIO).  The LIS3DH model (lis3dh.mjs) listens to the I2C block only; this answers the probe
// on the pins: the address byte read off the lines' levels (open drain: driven low, else pulled
// up), SDA held low through the ACK clock when it is the sensor's address.
const FUNCTION_SIO = 5;
const LOW = 0; // rp2040js GPIOPinState.Low: driven low

export function attachProbeAck(chip, { sda, scl, address }) {
  const S = chip.mcu.gpio[sda], C = chip.mcu.gpio[scl];
  let acking = false, active = false, bits = 0, byte = 0;
  let lastSda = 1, lastScl = 1;
  const stats = { probes: 0, acked: 0 };
  const release = () => { if (acking) { acking = false; S.setInputValue(true); } };
  const update = () => {
    if (S.functionSelect !== FUNCTION_SIO) { release(); active = false; lastSda = lastScl = 1; return; }
    const sdaLine = acking || S.value === LOW ? 0 : 1;
    const sclLine = C.value === LOW ? 0 : 1;
    if (sclLine && lastScl && sdaLine !== lastSda) { // START (falling) or STOP (rising)
      release();
      active = !sdaLine;
      bits = 0;
      byte = 0;
      if (active) stats.probes++;
    } else if (active && sclLine && !lastScl && bits < 8) { // a bit, on SCL rising
      byte = (byte << 1) | sdaLine;
      bits++;
    } else if (active && !sclLine && lastScl) { // SCL falling: the ACK clock starts or ends
      if (bits === 8) {
        bits = 9;
        if (byte >> 1 === address) { acking = true; S.setInputValue(false); stats.acked++; }
      } else if (bits === 9) {
        release();
        active = false;
      }
    }
    lastSda = acking ? 0 : sdaLine;
    lastScl = sclLine;
  };
  S.addListener(update);
  C.addListener(update);
  return stats;
}
