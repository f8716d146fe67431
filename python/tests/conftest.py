"""Shared fixtures: the repository's root, its assets and the `nimbus` CLI the Python renders are compared with."""

import os
import pathlib
import subprocess

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[2]


@pytest.fixture(scope="session")
def root() -> pathlib.Path:
    return ROOT


@pytest.fixture(scope="session")
def cloud() -> pathlib.Path:
    """The bundled demo: a VDB cloud over a ground plane."""
    return ROOT / "assets" / "cloud.gltf"


@pytest.fixture(scope="session")
def cli() -> pathlib.Path:
    """The `nimbus` binary: NIMBUS_CLI, else the debug build in the Cargo target folder (built when missing)."""
    given = os.environ.get("NIMBUS_CLI")
    if given:
        return pathlib.Path(given)
    target = pathlib.Path(os.environ.get("CARGO_TARGET_DIR", ROOT / "target"))
    if not target.is_absolute():
        target = ROOT / target
    binary = target / "debug" / "nimbus"
    if not binary.exists():
        subprocess.run(["cargo", "build", "--bin", "nimbus"], cwd=ROOT, check=True)
    return binary


def run_cli(cli, *args):
    """Runs the CLI; returns (exit status, stderr)."""
    done = subprocess.run([str(cli), *map(str, args)], capture_output=True, text=True)
    return done.returncode, done.stderr


def cli_error_line(stderr: str) -> str:
    """The message of the CLI's `nimbus: error: ...` line."""
    lines = [l for l in stderr.splitlines() if l.startswith("nimbus: error: ")]
    assert len(lines) == 1, stderr
    return lines[0][len("nimbus: error: "):]
