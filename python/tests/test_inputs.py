"""The same bad value typed into the command line, a scenario and the Python module is refused
with the same message and the same bound (penumbra.model's ObserverHeight, Site, EpochRange).

Each case runs the three: the binary (exit code 2, one line on stderr), `penumbra run` on a
scenario that holds the value (exit code 2), and the Python call (PenumbraError). The expected
message is the documented bound, written here, not read back from the code.
"""

from __future__ import annotations

import os
import subprocess
from pathlib import Path

import pytest

import penumbra

OBSERVER_1E6 = "observer height 1e6 m must be a finite number from 0 to 100000 m"
OBSERVER_NEG = "observer height -1 m must be a finite number from 0 to 100000 m"
LATITUDE_95 = "site 'a': latitude 95 deg must lie in -90 .. 90"
SITE_NAME = "site name 'a/b' must be 1 … 100 letters"
STOP_BEFORE_START = "stop 2027-01-01T00:00:00 is before start 2027-02-01T00:00:00"

SCENARIO_HEAD = """
name = "bad"
[time]
start = "{start}"
stop = "{stop}"
step = "6h"
"""
SITE = """
[[sites]]
name = "{name}"
lat_deg = {lat}
lon_deg = 0.0
height_above_ground_m = {height}
"""
MAP = """
[terrain]
synthetic = {{ size_px = 64, px_m = 100.0, seed = 1 }}
[map]
step = "1d"
observer_height_m = {height}
"""


def cli_error(cli: Path, cwd: Path, *args: str) -> str:
    """The one error line of a refused command line (exit code 2)."""
    env = dict(os.environ)
    env.setdefault("XDG_RUNTIME_DIR", "/tmp")
    r = subprocess.run([str(cli), *args], cwd=cwd, capture_output=True, text=True, env=env)
    assert r.returncode == 2, f"penumbra {' '.join(args)}: exit {r.returncode}, {r.stderr}"
    lines = [line for line in r.stderr.splitlines() if line.strip()]
    assert len(lines) == 1, r.stderr
    return lines[0]


def scenario_error(cli: Path, tmp: Path, text: str) -> str:
    """The error of `penumbra run` on a scenario holding `text`, which must write nothing."""
    path = tmp / "bad.toml"
    path.write_text(text)
    line = cli_error(cli, tmp, "run", str(path), "--out-dir", str(tmp / "out"))
    assert not (tmp / "out").exists(), "a refused scenario wrote its folder"
    # The Python module runs the same scenario with the same message.
    with pytest.raises(penumbra.PenumbraError) as e:
        penumbra.run_scenario(path, out_dir=tmp / "out-py")
    assert str(e.value) in line, (str(e.value), line)
    return line


def python_error(call) -> str:
    with pytest.raises(penumbra.PenumbraError) as e:
        call()
    return str(e.value)


@pytest.fixture(scope="module")
def terrain() -> penumbra.Terrain:
    return penumbra.Terrain.synthetic(size_px=64)


def test_observer_height_is_refused_alike_everywhere(cli: Path, tmp_path: Path, terrain) -> None:
    one_light = ["--synthetic", "--sun-az-deg", "10", "--sun-el-deg", "1"]
    out = ["--out-fraction", str(tmp_path / "f.tif")]
    messages = {
        "map": cli_error(cli, tmp_path, "map", *one_light, *out, "--observer-height-m", "1e6"),
        "series": cli_error(
            cli, tmp_path, "series", "--synthetic", "--site", "a,-89.6,0",
            "--utc", "2027-01-01", "--out-dir", str(tmp_path / "s"), "--observer-height-m", "1e6",
        ),
        "horizon-map": cli_error(
            cli, tmp_path, "horizon-map", "sweep", "--synthetic", "--observer-height-m", "1e6",
            "--out", str(tmp_path / "h.tif"),
        ),
        "scenario [map]": scenario_error(
            cli, tmp_path,
            SCENARIO_HEAD.format(start="2027-01-01", stop="2027-01-02")
            + SITE.format(name="a", lat=-89.6, height=2.0)
            + MAP.format(height=1e6),
        ),
        "python map_light": python_error(
            lambda: penumbra.map_light(terrain, sun_az_deg=10.0, sun_el_deg=1.0, observer_height_m=1e6)
        ),
        "python map_statistics": python_error(
            lambda: penumbra.map_statistics(
                terrain, penumbra.time_range("2027-01-01", "2027-01-02", "6h"), observer_height_m=1e6
            )
        ),
        "python horizon": python_error(
            lambda: penumbra.horizon(terrain, -89.9, 0.0, observer_height_m=1e6)
        ),
        "python series": python_error(
            lambda: penumbra.series(terrain, [("a", -89.9, 0.0, 1e6)], "2027-01-01")
        ),
    }
    for where, msg in messages.items():
        assert OBSERVER_1E6 in msg, f"{where}: {msg}"
    # A negative height: the same bound at the other end.
    negative = {
        "series --site": cli_error(
            cli, tmp_path, "series", "--synthetic", "--site", "a,-89.6,0,-1",
            "--utc", "2027-01-01", "--out-dir", str(tmp_path / "s"),
        ),
        "scenario [[sites]]": scenario_error(
            cli, tmp_path,
            SCENARIO_HEAD.format(start="2027-01-01", stop="2027-01-02")
            + SITE.format(name="a", lat=-89.6, height=-1.0),
        ),
        "python series": python_error(
            lambda: penumbra.series(terrain, [("a", -89.9, 0.0, -1.0)], "2027-01-01")
        ),
    }
    for where, msg in negative.items():
        assert OBSERVER_NEG in msg, f"{where}: {msg}"


def test_a_site_is_refused_alike_everywhere(cli: Path, tmp_path: Path, terrain) -> None:
    def series_cli(site: str) -> str:
        return cli_error(
            cli, tmp_path, "series", "--synthetic", "--site", site,
            "--utc", "2027-01-01", "--out-dir", str(tmp_path / "s"),
        )

    def scenario(name: str, lat: float) -> str:
        return scenario_error(
            cli, tmp_path,
            SCENARIO_HEAD.format(start="2027-01-01", stop="2027-01-02")
            + SITE.format(name=name, lat=lat, height=2.0),
        )

    for expected, (name, lat) in [(LATITUDE_95, ("a", 95.0)), (SITE_NAME, ("a/b", -89.6))]:
        messages = {
            "series --site": series_cli(f"{name},{lat},0"),
            "scenario [[sites]]": scenario(name, lat),
            "python series": python_error(
                lambda: penumbra.series(terrain, [(name, lat, 0.0, 2.0)], "2027-01-01")
            ),
        }
        for where, msg in messages.items():
            assert expected in msg, f"{where}: {msg}"


def test_an_epoch_range_is_refused_alike_everywhere(cli: Path, tmp_path: Path, terrain) -> None:
    messages = {
        "map": cli_error(
            cli, tmp_path, "map", "--synthetic", "--start", "2027-02-01", "--stop", "2027-01-01",
            "--step", "1h", "--out-dir", str(tmp_path / "m"),
        ),
        "series": cli_error(
            cli, tmp_path, "series", "--synthetic", "--site", "a,-89.6,0", "--start", "2027-02-01",
            "--stop", "2027-01-01", "--step", "1h", "--out-dir", str(tmp_path / "s"),
        ),
        "scenario [time]": scenario_error(
            cli, tmp_path,
            SCENARIO_HEAD.format(start="2027-02-01", stop="2027-01-01")
            + SITE.format(name="a", lat=-89.6, height=2.0),
        ),
        "python time_range": python_error(
            lambda: penumbra.time_range("2027-02-01", "2027-01-01", "1h")
        ),
        "python map_shard": python_error(
            lambda: penumbra.map_shard(
                terrain, "2027-02-01", "2027-01-01", "1h", tmp_path / "sh", 0, 2
            )
        ),
    }
    for where, msg in messages.items():
        assert STOP_BEFORE_START in msg, f"{where}: {msg}"


MASK_NEG = "elevation mask -5 deg is outside [0, 90)"
STATION_LAT_95 = "station 'x': latitude 95 deg is outside [-90, 90]"


def test_stations_are_refused_alike_everywhere(cli: Path, tmp_path: Path, terrain) -> None:
    stations = tmp_path / "stations.csv"
    stations.write_text("name,lat_deg,lon_deg,height_m,mask_deg\nx,95,0,0,10\n")
    series_args = ["series", "--synthetic", "--site", "a,-89.6,0", "--utc", "2027-01-01",
                   "--out-dir", str(tmp_path / "s")]
    series_table = """
[terrain]
synthetic = {{ size_px = 64, px_m = 100.0, seed = 1 }}
[series]
{line}
"""
    for expected, flag, value, line, kwargs in [
        (MASK_NEG, "--station-mask-deg", "-5", "station_mask_deg = -5.0",
         {"station_mask_deg": -5.0}),
        (STATION_LAT_95, "--stations", str(stations), f'stations = "{stations}"',
         {"stations": str(stations)}),
    ]:
        messages = {
            "series": cli_error(cli, tmp_path, *series_args, flag, value),
            "scenario [series]": scenario_error(
                cli, tmp_path,
                SCENARIO_HEAD.format(start="2027-01-01", stop="2027-01-02")
                + SITE.format(name="a", lat=-89.6, height=2.0)
                + series_table.format(line=line),
            ),
            "python series": python_error(
                lambda: penumbra.series(terrain, [("a", -89.6, 0.0, 2.0)], "2027-01-01", **kwargs)
            ),
            "python station_elevations": python_error(
                lambda: penumbra.station_elevations((-89.6, 0.0, 0.0), "2027-01-01", **kwargs)
            ),
        }
        for where, msg in messages.items():
            assert expected in msg, f"{where}: {msg}"
