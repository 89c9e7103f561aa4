"""Collect the benchmarks (`bench_*.py`) when `make bench` runs `pytest tests/bench`: pytest's default
file pattern (`test_*.py`) would skip them, and they are kept out of `make test` on purpose."""

import pytest


def pytest_collect_file(file_path, parent):
    if file_path.suffix == ".py" and file_path.name.startswith("bench_") and not parent.session.isinitpath(file_path):
        return pytest.Module.from_parent(parent, path=file_path)
    return None
