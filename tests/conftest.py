import os
import pathlib

import pytest

ROOT = pathlib.Path(__file__).resolve().parent.parent
REAL_DATA = pathlib.Path(os.environ.get("NEUROTAC_REAL_DATA", ROOT.parent / "shared" / "data" / "real"))


@pytest.fixture(scope="session")
def real_data() -> pathlib.Path:
    """The folder of real camera recordings (../shared/data/real, or $NEUROTAC_REAL_DATA)."""
    if not REAL_DATA.is_dir():
        pytest.skip(f"real recordings not found at {REAL_DATA} (set NEUROTAC_REAL_DATA to their folder)")
    return REAL_DATA


def real_file(name: str) -> pathlib.Path:
    path = REAL_DATA / name
    if not path.is_file():
        pytest.skip(f"real recording {name} not found in {REAL_DATA} (set NEUROTAC_REAL_DATA)")
    return path


# Subprocess tests run the `neurotac` installed beside this interpreter, whatever PATH says.
os.environ["PATH"] = str(pathlib.Path(__import__("sys").executable).parent) + os.pathsep + os.environ.get("PATH", "")
