"""Shared pytest fixtures."""
import pytest


@pytest.fixture(scope="session")
def built_fmu(tmp_path_factory):
    """``HammerBitRock.fmu`` built once per session into a temporary directory (``build_fmu.py``)."""
    from build_fmu import build_fmu
    return build_fmu(tmp_path_factory.mktemp("fmu"))
