"""Shared pytest fixtures."""
import pytest


@pytest.fixture(scope="session")
def built_fmu(tmp_path_factory):
    """``HammerBitRock.fmu`` built once per session (``hammerbit fmu build``) into a temporary directory."""
    from hammerbit.fmu_build import build_fmu
    return build_fmu(tmp_path_factory.mktemp("fmu") / "HammerBitRock.fmu")
