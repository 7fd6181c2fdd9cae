# ESP32 dev board (ESP32-WROOM-32), MicroPython: LIS3DH on I2C0, GPIO21 = SDA, GPIO22 = SCL.
RUNTIME = "micropython"
ARCH = "xtensawin"
I2C_ID = 0
SDA_PIN = 21
SCL_PIN = 22
I2C_FREQ = 400000
I2C_ADDRESS = 0x18
TEMP_REF_C = None


def i2c():
    from machine import I2C, Pin
    return I2C(I2C_ID, sda=Pin(SDA_PIN), scl=Pin(SCL_PIN), freq=I2C_FREQ)
