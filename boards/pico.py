# Raspberry Pi Pico (RP2040), MicroPython: the LIS3DH on SPI0 (GP18 = SCK -> SPC, GP19 = MOSI ->
# SDA/SDI, GP16 = MISO <- SDO/SA0, GP17 -> CS) or on I2C0 (GP4 = SDA, GP5 = SCL, CS tied high).
# BUS: "auto" (SPI when the LIS3DH answers there, else I2C: a board wired for either works
# unchanged), "spi" or "i2c"; the app's bus setting (deploy --bus) overrides it.  SPI keeps the
# core awake far less: a 25-sample FIFO drain is ~150 bytes, 0.14 ms on the wire at 8.9 MHz against
# 3.4 ms at 400 kHz, which machine.I2C and machine.SPI both wait out awake (docs/boards-and-logs.md).
RUNTIME = "micropython"
ARCH = "armv6m"
BUS = "auto"
SPI_ID = 0
SCK_PIN = 18
MOSI_PIN = 19
MISO_PIN = 16
CS_PIN = 17
SPI_BAUD = 10000000  # the LIS3DH's fastest SPC (10 MHz); the RP2040 gives 125 MHz / 14 = 8.93 MHz
I2C_ID = 0
SDA_PIN = 4
SCL_PIN = 5
I2C_FREQ = 400000
I2C_ADDRESS = 0x18   # SDO/SA0 to GND; 0x19 when tied high (I2C only)
TEMP_REF_C = None    # set to (thermometer degC - first OUT_ADC3 reading) for absolute temperature


def i2c():
    from machine import I2C, Pin
    return I2C(I2C_ID, sda=Pin(SDA_PIN), scl=Pin(SCL_PIN), freq=I2C_FREQ)


def spi():
    """The LIS3DH's registers over SPI0, mode 3 (DocID17530 6.2), CS on CS_PIN."""
    from machine import SPI, Pin
    from acal.logger.lis3dh_spi import SPIRegisters
    return SPIRegisters(SPI(SPI_ID, baudrate=SPI_BAUD, polarity=1, phase=1, sck=Pin(SCK_PIN),
                            mosi=Pin(MOSI_PIN), miso=Pin(MISO_PIN)), Pin(CS_PIN, Pin.OUT, value=1))


def sensor_bus(bus=None):
    """The LIS3DH's register bus: bus, or BUS when None (lis3dh.open_bus)."""
    from acal.logger.lis3dh import open_bus
    return open_bus(bus or BUS, spi, i2c)


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
