"""The Python API: docs/python.md's examples run, in order, in an empty folder."""

import pathlib
import re

import pytest

DOC = pathlib.Path(__file__).resolve().parent.parent / "docs" / "python.md"


def test_the_python_page_runs(tmp_path, monkeypatch):
    pytest.importorskip("tonic")
    monkeypatch.chdir(tmp_path)
    blocks = re.findall(r"```python\n(.*?)```", DOC.read_text(), flags=re.S)
    assert len(blocks) >= 4
    namespace = {}
    for block in blocks:
        exec(compile(block, str(DOC), "exec"), namespace)
    for made in ("frames.parquet", "rotated.png", "slices.png", "predictions.csv", "force.model"):
        assert (tmp_path / made).stat().st_size > 0


def test_the_package_is_cheap_to_import():
    import subprocess
    import sys

    code = "import sys, neurotac_cli; print(sorted(m for m in ('pyarrow', 'torch', 'numpy') if m in sys.modules))"
    assert subprocess.run([sys.executable, "-c", code], capture_output=True, text=True).stdout.strip() == "[]"
