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


def test_the_package_gives_the_api_functions_on_first_use():
    import neurotac_cli
    from neurotac_cli import api

    assert neurotac_cli.frame is api.frame and neurotac_cli.Stepper is api.Stepper
    with pytest.raises(AttributeError, match="no attribute 'nothing_here'"):
        neurotac_cli.nothing_here  # noqa: B018


def test_every_api_name_is_listed_in_the_package():
    import inspect

    import neurotac_cli
    from neurotac_cli import api

    public = {name for name, value in vars(api).items() if not name.startswith("_")
              and (inspect.isfunction(value) or inspect.isclass(value))
              and value.__module__ in ("neurotac_cli.api", "neurotac_cli.ops.augment")}
    assert public | {"TONIC_DTYPE"} == set(neurotac_cli.API)
