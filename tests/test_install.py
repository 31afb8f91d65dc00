"""The package as a user installs it: the wheel, in a fresh virtual environment outside the
checkout, runs `shapes`, a small `pick` and a one-table sweep (its models inside it). Slow
(it installs drake and the rest): CI runs it after the suite (`make test-extras`)."""

import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

pytestmark = pytest.mark.extras
ROOT = Path(__file__).resolve().parents[1]


def _run(cmd, cwd, timeout=1200):
    p = subprocess.run(cmd, cwd=cwd, capture_output=True, text=True, timeout=timeout)
    assert p.returncode == 0, (cmd, p.stdout[-2000:], p.stderr[-2000:])
    return p.stdout


def test_the_wheel_installed_elsewhere_runs_with_its_models(tmp_path):
    _run(
        [sys.executable, "-m", "pip", "wheel", "--no-deps", "-q", "-w", str(tmp_path / "dist"), str(ROOT)],
        ROOT,
    )
    (wheel,) = (tmp_path / "dist").glob("mog_drake-*.whl")
    names = set(zipfile.ZipFile(wheel).namelist())
    sources = {str(p.relative_to(ROOT)) for p in (ROOT / "mog_drake").rglob("*.py")}
    models = {
        f"mog_drake/models/{p.name}" for p in (ROOT / "models").iterdir() if p.suffix in (".yaml", ".urdf")
    }
    assert sources <= names and models <= names, sorted((sources | models) - names)
    venv = tmp_path / "venv"
    _run([sys.executable, "-m", "venv", str(venv)], tmp_path)
    _run([str(venv / "bin" / "python"), "-m", "pip", "install", "-q", str(wheel)], tmp_path)
    work = tmp_path / "elsewhere"
    work.mkdir()
    exe = str(venv / "bin" / "mog-drake")
    assert "thin_bar" in _run([exe, "shapes"], work)
    out = _run(
        [exe, "pick", "--objects", "6", "--seed", "1", "--time-limit", "60", "--scenario", "realistic"], work
    )
    assert "attempt   1" in out
    _run(
        [
            exe,
            "eval",
            "picking",
            "--scenes",
            "1",
            "--modes",
            "mog",
            "--objects",
            "3",
            "--time-limit",
            "30",
            "--out",
            "sweep",
        ],
        work,
    )
    assert (work / "sweep" / "results.jsonl").read_text().count("\n") == 1
