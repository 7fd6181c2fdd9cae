# Raspberry Pi Pico (RP2040), MicroPython: LIS3DH on I2C0, GP4 = SDA, GP5 = SCL.
RUNTIME = "micropython"
ARCH = "armv6m"
I2C_ID = 0
SDA_PIN = 4
SCL_PIN = 5
I2C_FREQ = 400000
I2C_ADDRESS = 0x18   # SDO/SA0 to GND; 0x19 when tied high
TEMP_REF_C = None    # set to (thermometer degC - first OUT_ADC3 reading) for absolute temperature


def i2c():
    from machine import I2C, Pin
    return I2C(I2C_ID, sda=Pin(SDA_PIN), scl=Pin(SCL_PIN), freq=I2C_FREQ)


_vsys = None


def supply_mv():
    """VSYS in mV, for a model that follows the board's supply (supply_offset): ADC3 (GP29)
    reads VSYS / 3 against 3.3 V, 16 bits (read_u16); integers only, < 2**30.  (On a Pico W
    GP29 is shared with the radio: leave this out there, or read it with the radio idle.)"""
    global _vsys
    if _vsys is None:
        from machine import ADC
        _vsys = ADC(3)
    return (_vsys.read_u16() * 9900) >> 16
