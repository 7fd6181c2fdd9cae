"""`accelcal bench`'s paths script (bridge/scripts/mp_paths_bench.py) on the MicroPython unix
port: what the FIFO's conversion tables a board file asks for with FIFO_TABLES
(boards/feather_rp2040.py) take of the heap the app with the largest model leaves, and the
bench's line for CircuitPython's figure."""
from accelcal.studies import bench_chip


def test_the_fifo_tables_take_their_two_arrays_of_the_apps_heap():
    """lis3dh_cp.fifo_tables: 1024 16-bit values and 1024 16-bit carries, 4096 bytes of data; the
    rest is the two array objects and the heap's 16-byte blocks."""
    kv = bench_chip._unix_paths()
    assert 4096 <= kv["fifo_tables_bytes"] <= 4096 + 256, kv
    assert kv["heap_free_app_largest"] < kv["heap_free_before_app"] < kv["heap_total"]


def test_the_bench_prints_circuitpythons_heap_with_the_tables():
    m = {}
    for fw, free in ((bench_chip.MP, 154560), (bench_chip.CP, 97024)):
        m.update({fw + "heap_total_bytes": 2 * free, fw + "heap_free_before_app_bytes": free,
                  fw + "heap_free_app_largest_bytes": free - 28000, fw + "fifo_tables_bytes": 4160})
    lines = bench_chip.format_chip(m).splitlines()
    i = next(n for n, ln in enumerate(lines) if ln.startswith("CircuitPython heap: total"))
    assert lines[i].endswith("194,048 / 97,024 / 69,024 bytes")
    assert lines[i + 1].split() == ["the", "FIFO", "tables", "(the", "Feather's", "FIFO_TABLES)",
                                    "4,160", "bytes", "more"]
    assert sum("FIFO tables" in ln for ln in lines) == 1   # MicroPython's boards convert by viper
