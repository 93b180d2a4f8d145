"""Shared fixtures: the real data (SLAMKIT_DATA) and the CLI binary (SLAMKIT_BIN) the Python
results are compared with."""

import os
import pathlib
import subprocess

import pytest


@pytest.fixture(scope="session")
def data() -> pathlib.Path:
    root = os.environ.get("SLAMKIT_DATA")
    if not root:
        pytest.skip("SLAMKIT_DATA is not set: the real-data tests need it")
    return pathlib.Path(root)


@pytest.fixture(scope="session")
def cli():
    """Runs the slamkit CLI; returns its completed process (output as text)."""
    binary = os.environ.get("SLAMKIT_BIN")
    if not binary:
        pytest.skip("SLAMKIT_BIN is not set: the comparisons with the CLI need it")

    def run(*args: str) -> subprocess.CompletedProcess:
        return subprocess.run([binary, *map(str, args)], check=True, capture_output=True, text=True)

    return run
