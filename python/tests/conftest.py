"""Fixtures of the Python tests: the CLI, and a small synthetic scene with a classical map built
by the CLI, so that every function is compared with the command that does the same."""
import json
import os
import pathlib
import subprocess

import pytest

REPO = pathlib.Path(__file__).resolve().parents[2]


def cli_path():
    return os.environ.get("FFLOC_CLI", str(REPO / "build" / "bin" / "ffloc"))


def run_cli(*args):
    """Runs the CLI and returns its stdout; fails the test with its stderr when it fails."""
    done = subprocess.run([cli_path(), *map(str, args)], capture_output=True, text=True)
    assert done.returncode in (0, 1), f"ffloc {' '.join(map(str, args))}: {done.stderr}"
    return done.stdout


@pytest.fixture(scope="session")
def cli():
    return run_cli


@pytest.fixture(scope="session")
def scene_dir(tmp_path_factory):
    out = tmp_path_factory.mktemp("synth")
    run_cli("synth", "--out", out, "--seed", 5, "--kind", "indoor", "--size", "320x240", "--mapping-frames", 16,
            "--query-frames", 4, "--quiet")
    return out / "scene_000_indoor"


@pytest.fixture(scope="session")
def cli_map(scene_dir, tmp_path_factory):
    path = tmp_path_factory.mktemp("maps") / "cli.ffmap"
    run_cli("map", "--dataset", scene_dir, "-o", path, "--threads", 1, "--quiet")
    return path


@pytest.fixture(scope="session")
def query(scene_dir):
    """The first query frame of the synthetic scene: (frame, CLI --json answer for it)."""
    import ffloc

    scene = ffloc.load_dataset(str(scene_dir))
    return scene.frames[scene.query_indices()[0]]


def localize_with_cli(map_path, frame, *extra):
    k = frame.intrinsics
    intrinsics = f"{k[0, 0]!r},{k[1, 1]!r},{k[0, 2]!r},{k[1, 2]!r}"
    out = run_cli("localize", "--map", map_path, "--image", frame.image_path, "--intrinsics", intrinsics, "--json",
                  "--threads", 1, *extra)
    return json.loads(out)


@pytest.fixture(scope="session")
def cli_answer(cli_map, query):
    return localize_with_cli(cli_map, query)


def without_timings(answer):
    return {key: value for key, value in answer.items() if key != "timings_ms"}
