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
