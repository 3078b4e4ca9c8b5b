"""Shared test fixtures: the ngspice referee and temporary output folders."""

import shutil

import pytest

NGSPICE = shutil.which("ngspice")

requires_ngspice = pytest.mark.skipif(
    NGSPICE is None,
    reason="ngspice is not installed (apt-get install -y ngspice; CI installs it)",
)
