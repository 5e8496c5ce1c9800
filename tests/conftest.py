"""Test session set-up: DDS on localhost only, with a ROS_DOMAIN_ID held by this session alone."""

import os
import sys
from pathlib import Path

import pytest

# Small matrices everywhere: BLAS threads only oversubscribe the 2 cores (set before numpy is imported).
for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
os.environ.setdefault("MPLBACKEND", "Agg")

from amb_ros.env import ensure_localhost_dds, reserve_domain_id

# One domain per test session, locked so that concurrent sessions never share it.
os.environ["ROS_DOMAIN_ID"] = str(reserve_domain_id())
ensure_localhost_dds()

REPO = Path(__file__).resolve().parents[1]
VENV_BIN = Path(sys.executable).parent


@pytest.fixture(scope="session")
def repo() -> Path:
    return REPO


@pytest.fixture(scope="session")
def seed_config_path() -> Path:
    """The paper's idealised rotor: every test that quotes the paper's numbers runs on it."""
    return REPO / "config" / "seed_paper.yaml"


@pytest.fixture(scope="session")
def venv_bin() -> Path:
    return VENV_BIN
