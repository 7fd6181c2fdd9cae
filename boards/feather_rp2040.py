# Adafruit Feather RP2040, CircuitPython: LIS3DH on the STEMMA QT / board.I2C() bus.
RUNTIME = "circuitpython"
ARCH = None          # CircuitPython runs the sources (its .mpy format differs from MicroPython's)
I2C_ADDRESS = 0x18
TEMP_REF_C = None


def i2c():
    import board
    from acal.lis3dh_cp import BusioRegisters
    return BusioRegisters(board.I2C(), I2C_ADDRESS)
