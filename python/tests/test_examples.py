"""The examples in examples/ run as a planner would run them (quick settings) and type-check."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest


def run_example(root: Path, name: str, tmp_path: Path, *args: str) -> str:
    env = dict(os.environ, PENUMBRA_EXAMPLE_QUICK="1", MPLBACKEND="Agg")
    r = subprocess.run([sys.executable, str(root / "examples" / name), *args], cwd=tmp_path,
                       capture_output=True, text=True, env=env)
    assert r.returncode == 0, r.stderr
    return r.stdout


def test_rank_sites(root: Path, tmp_path: Path, lola: Path) -> None:
    out = run_example(root, "rank_sites.py", tmp_path, "--out", "ranking.csv", "--data", str(lola))
    lines = (tmp_path / "ranking.csv").read_text().splitlines()
    assert lines[0].startswith("rank,site,lat_deg,lon_deg")
    assert len(lines) >= 6
    assert "best site" in out


def test_mast_heights(root: Path, tmp_path: Path, lola: Path) -> None:
    out = run_example(root, "mast_heights.py", tmp_path, "--out", "mast.csv", "--data", str(lola))
    lines = (tmp_path / "mast.csv").read_text().splitlines()
    assert lines[0].startswith("height_m,sun_lit_pct")
    pct = [float(l.split(",")[1]) for l in lines[1:]]
    # A taller mast never sees less Sun.
    assert all(b >= a - 1e-9 for a, b in zip(pct, pct[1:])), pct


def test_examples_type_check(root: Path) -> None:
    if shutil.which("mypy") is None and not _has_module("mypy"):
        pytest.skip("mypy is not installed")
    r = subprocess.run([sys.executable, "-m", "mypy", "--ignore-missing-imports",
                        str(root / "examples")], capture_output=True, text=True)
    assert r.returncode == 0, r.stdout + r.stderr


def _has_module(name: str) -> bool:
    import importlib.util
    return importlib.util.find_spec(name) is not None
