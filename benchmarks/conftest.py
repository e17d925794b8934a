"""The benchmarks' JSON (``--benchmark-json F``) as the docs' performance page reads it: what the
figures were measured on kept with them, the rounds' raw timings left out (their statistics stay:
a file of kilobytes, not megabytes, to commit under docs/data/)."""

from __future__ import annotations

import sys


def pytest_benchmark_update_json(config, benchmarks, output_json):
    """pytest-benchmark's hook, called before it writes the file."""
    from cnc_twin.studies.bench_context import measurement_context

    output_json["measured"] = measurement_context(["python", "-m", "pytest", *sys.argv[1:]])
    for bench in output_json["benchmarks"]:
        bench["stats"].pop("data", None)
