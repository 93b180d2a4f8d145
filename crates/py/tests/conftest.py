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


@pytest.fixture(scope="session")
def read_recording():
    """Reads a `--record` MCAP file through the MCAP project's own Python reader, as Foxglove
    would, checking every channel's Foxglove schema (`schemas`: topic -> schema name), its JSON
    encoding and that log times never go back; returns the message counts and the first and
    last message per topic."""
    reader_module = pytest.importorskip("mcap.reader")

    def read(path, schemas: dict) -> tuple[dict, dict, dict]:
        counts, first, last, last_time = {}, {}, {}, 0
        with open(path, "rb") as f:
            reader = reader_module.make_reader(f)
            for schema, channel, message in reader.iter_messages(log_time_order=False):
                assert schema.name == schemas[channel.topic], channel.topic
                assert channel.message_encoding == "json"
                assert message.log_time >= last_time  # written in time order
                last_time = message.log_time
                counts[channel.topic] = counts.get(channel.topic, 0) + 1
                first.setdefault(channel.topic, message)
                last[channel.topic] = message
        assert set(counts) == set(schemas)
        return counts, first, last

    return read
