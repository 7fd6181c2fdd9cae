# The ESP32 family, MicroPython's esp32 port (checked against v1.28.0's sources): LIS3DH on I2C0.
# One file for every chip: `deploy` compiles the package for the arch the board reports
# (xtensawin on an ESP32 or ESP32-S3, rv32imc on an ESP32-C3/C6), and the pins follow the chip
# (sys.implementation._machine ends with MicroPython's MCU name, e.g. "ESP32C3 module with ESP32C3").
#   ESP32 (e.g. ESP32-WROOM-32 DevKitC): GPIO21 = SDA, GPIO22 = SCL, the DevKit convention (the
#     port's own I2C0 default is SDA 19 / SCL 18; any GPIO works through the GPIO matrix but 6-11,
#     the flash, and 34-39, inputs only).
#   ESP32-S3 and ESP32-C3: GPIO8 = SDA, GPIO9 = SCL, the port's own I2C0 default on these two
#     (ports/esp32/machine_i2c.h): neither has a GPIO22, and GPIO21 is the C3's UART0 TX (its REPL
#     on boards with a USB-UART bridge); 18/19 are the C3's USB. The C3 has one I2C controller (0).
#   Other chips (S2, C6, ...): the port's I2C0 default pins for that chip (SDA_PIN None).
# SPI, on the ESP32 only: its VSPI, machine.SPI(2), on VSPI's IO_MUX pins (ESP32 datasheet, the
#   IO_MUX table: GPIO18 VSPICLK -> SPC, GPIO23 VSPID -> SDA/SDI, GPIO19 VSPIQ <- SDO/SA0, GPIO5
#   VSPICS0 -> CS, driven here as a plain output), mode 3 at the LIS3DH's 10 MHz (DocID17530
#   6.2).  BUS stays "i2c" (with nothing on SPI an ESP32's MISO floats: "auto" could read
#   anything there); `deploy --bus spi` or BUS = "spi" for a sensor wired so.  SPI keeps the core
#   awake less than I2C (docs/boards-and-logs.md, "What each bus costs").
# The clock: time.ticks_us is the esp_timer's microseconds since boot (not the CPU clock, 160 MHz
# by default on an ESP32 and a C3), wrapping at 2^30 us as on an RP2040: the app's RealClock.
import sys

RUNTIME = "micropython"
ARCH = "xtensawin"
CHIP = getattr(sys.implementation, "_machine", "").rsplit(" ", 1)[-1]   # "ESP32", "ESP32C3", ...
I2C_ID = 0
if CHIP == "ESP32":
    SDA_PIN, SCL_PIN = 21, 22
elif CHIP in ("ESP32S3", "ESP32C3"):
    SDA_PIN, SCL_PIN = 8, 9
else:
    SDA_PIN = SCL_PIN = None
I2C_FREQ = 400000
I2C_ADDRESS = 0x18   # SDO/SA0 to GND; 0x19 when tied high
BUS = "i2c"
if CHIP == "ESP32":
    SPI_ID, SCK_PIN, MOSI_PIN, MISO_PIN, CS_PIN = 2, 18, 23, 19, 5
    SPI_BAUD = 10000000
else:
    SPI_ID = None   # not offered: the app refuses --bus spi in one line
# The chip's own temperature is the die's, not the wrist's: on an S2/S3/C3/C6
# esp32.mcu_temperature() gives calibrated whole degC (the port sets its range to -10..80 degC),
# a thermometer good enough to set TEMP_REF_C (its reading minus the first OUT_ADC3 reading, the
# board cold); an ESP32's esp32.raw_temperature() is uncalibrated and no thermometer.
TEMP_REF_C = None
# The supply (for a model that follows it, supply_offset): DevKits bring no supply to an ADC pin.
# Wired through a divider to an ADC1 pin (ESP32: GPIO32-39; C3: GPIO0-4; ADC2 is shared with
# Wi-Fi), set SUPPLY_PIN and SUPPLY_DIVIDE (supply / pin voltage, an int): supply_mv() reads it
# with the port's calibrated ADC.read_uv() at its widest attenuation (11 dB: to ~3.1 V on an
# ESP32, ~2.5 V on a C3).
SUPPLY_PIN = None
SUPPLY_DIVIDE = 2


def i2c():
    from machine import I2C, Pin
    if SDA_PIN is None:
        return I2C(I2C_ID, freq=I2C_FREQ)
    return I2C(I2C_ID, sda=Pin(SDA_PIN), scl=Pin(SCL_PIN), freq=I2C_FREQ)


if SPI_ID is not None:
    def spi():
        """The LIS3DH's registers over VSPI, mode 3 (DocID17530 6.2), CS on CS_PIN."""
        from machine import SPI, Pin
        from acal.logger.lis3dh_spi import SPIRegisters
        return SPIRegisters(SPI(SPI_ID, baudrate=SPI_BAUD, polarity=1, phase=1,
                                sck=Pin(SCK_PIN), mosi=Pin(MOSI_PIN), miso=Pin(MISO_PIN)),
                            Pin(CS_PIN, Pin.OUT, value=1))

    def sensor_bus(bus=None):
        """The LIS3DH's register bus: bus, or BUS when None (lis3dh.open_bus)."""
        from acal.logger.lis3dh import open_bus
        return open_bus(bus or BUS, spi, i2c)


if SUPPLY_PIN is not None:
    _adc = None

    def supply_mv():
        """The supply in mV, an int < 2**30 (read_uv: microvolts, below 2**22)."""
        global _adc
        if _adc is None:
            from machine import ADC, Pin
            _adc = ADC(Pin(SUPPLY_PIN), atten=ADC.ATTN_11DB)
        return _adc.read_uv() * SUPPLY_DIVIDE // 1000
