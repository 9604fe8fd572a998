"""Shared fixtures of the Python module's tests: where the source tree and the `moreau` executable are.
CTest passes them (tests/python/CMakeLists.txt); run by hand:
    PYTHONPATH=build/python MOREAU_SOURCE_DIR=. MOREAU_CLI=build/client/moreau python3 -m pytest tests/python
"""

import os
import pathlib

import pytest


@pytest.fixture(scope="session")
def source_dir() -> pathlib.Path:
    return pathlib.Path(os.environ.get("MOREAU_SOURCE_DIR", pathlib.Path(__file__).resolve().parents[2])).resolve()


@pytest.fixture(scope="session")
def cli(source_dir) -> pathlib.Path:
    path = pathlib.Path(os.environ.get("MOREAU_CLI", source_dir / "build" / "client" / "moreau"))
    assert path.exists(), "the moreau executable %s is not built (set MOREAU_CLI)" % path
    return path
