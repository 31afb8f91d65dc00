"""Sweeps on a real local Ray cluster (the `ray` extra): the same results as `--jobs 1`, the
package shipped with the tasks. Run by CI after the default suite (`make test-extras`)."""

import json
import shutil
import socket
import subprocess
import sys
from pathlib import Path

import pytest

pytestmark = pytest.mark.extras
ray = pytest.importorskip("ray")


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.fixture(scope="module")
def cluster(tmp_path_factory):
    """`ray start --head` on this machine, stopped at the end."""
    ray_bin = shutil.which("ray") or str(Path(sys.executable).parent / "ray")
    port = _free_port()
    temp = tmp_path_factory.mktemp("ray")
    subprocess.run(
        [
            ray_bin,
            "start",
            "--head",
            f"--port={port}",
            "--num-cpus=2",
            "--include-dashboard=false",
            f"--temp-dir={temp}",
        ],
        check=True,
        capture_output=True,
        timeout=120,
    )
    try:
        yield f"127.0.0.1:{port}"
    finally:
        subprocess.run([ray_bin, "stop", "--force"], capture_output=True, timeout=120)


def _records(folder: Path) -> dict:
    return {
        json.loads(line)["key"]: json.loads(line)
        for line in (folder / "results.jsonl").read_text().splitlines()
    }


def _sweep(argv, out: Path, where: list[str]) -> dict:
    from mog_drake.cli import main

    assert main([*argv, "--out", str(out), *where]) == 0
    return _records(out)


def test_a_ray_sweep_gives_the_results_of_jobs_1(cluster, tmp_path):
    conditions = ["eval", "conditions", "--classes", "2", "--scenes-per-class", "2"]
    a = _sweep(conditions, tmp_path / "c_ray", ["--ray", cluster])
    b = _sweep(conditions, tmp_path / "c_one", ["--jobs", "1"])
    assert a.keys() == b.keys() and len(a) == 2
    for k in a:
        assert {f: v for f, v in a[k].items() if f != "wall_time"} == {
            f: v for f, v in b[k].items() if f != "wall_time"
        }
    fixed = tmp_path / "fixed.yaml"
    fixed.write_text("latency: {mode: fixed}\n")
    picking = ["eval", "picking", "--scenes", "1", "--modes", "mog", "--objects", "3", "--time-limit", "30"]
    picking += ["--scenario", str(fixed)]
    a = _sweep(picking, tmp_path / "p_ray", ["--ray", cluster])
    b = _sweep(picking, tmp_path / "p_one", ["--jobs", "1"])
    assert a.keys() == b.keys() == {"s0-mog"}

    def same(rec):
        s = rec["summary"]
        return (
            [(t["group"], t["grasp"], t["picked"]) for t in rec["attempts"]],
            {
                k: s[k]
                for k in ("attempts", "success_rate", "picked_pct", "pph", "cycle_time_s", "robot_time_s")
            },
        )

    assert same(a["s0-mog"]) == same(b["s0-mog"]) and a["s0-mog"]["summary"]["attempts"] >= 1


def test_a_wrong_address_is_one_line_and_no_hang(cluster, tmp_path):
    """An address that is no cluster's (no answer, or nonsense) ends in one line, exit 2: Ray's
    own connection would retry for minutes (the subprocess's timeout fails a hang)."""
    for address in ("notanaddress", f"127.0.0.1:{_free_port()}"):
        argv = [
            "eval",
            "conditions",
            "--classes",
            "2",
            "--scenes-per-class",
            "1",
            "--out",
            str(tmp_path / "x"),
        ]
        p = subprocess.run(
            [sys.executable, "-m", "mog_drake.cli", *argv, "--ray", address],
            capture_output=True,
            text=True,
            timeout=60,
        )
        assert (
            p.returncode == 2 and p.stderr.startswith("mog-drake: error: --ray") and p.stderr.count("\n") == 1
        )
