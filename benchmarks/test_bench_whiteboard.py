"""Whiteboard speed figures (``python -m pytest benchmarks/ --benchmark-only``).

Targets (issue #3): exchange round trip median <= 5 us on this 2-core machine; streaming faster
than the 132 MB/s burst rate of the card's 32-bit / 33 MHz PCI bus.
"""

from __future__ import annotations

from cnc_twin.studies.bench_whiteboard import exchange_round_trip, stream_throughput


def test_exchange_round_trip(benchmark):
    figures = benchmark.pedantic(exchange_round_trip, kwargs={"n": 20000}, rounds=1)
    benchmark.extra_info.update(figures)
    print(f"\nround trip median {figures['median_us']:.2f} us, p99 {figures['p99_us']:.2f} us")


def test_stream_4k_blocks(benchmark):
    figures = benchmark.pedantic(stream_throughput, kwargs={"kind": "block", "count": 4000}, rounds=1)
    benchmark.extra_info.update(figures)
    print(f"\n4 KB blocks: {figures['mb_per_s']:.0f} MB/s = {figures['ratio_to_pci']:.2f} x PCI burst")


def test_stream_move_records(benchmark):
    figures = benchmark.pedantic(stream_throughput, kwargs={"kind": "move", "count": 20000}, rounds=1)
    benchmark.extra_info.update(figures)
    print(f"\nMove records: {figures['mb_per_s']:.1f} MB/s, {figures['records'] / figures['seconds']:.0f} records/s")
