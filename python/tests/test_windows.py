"""Landing windows (penumbra windows, docs/power.md "Landing windows") against a brute-force
scan of every start epoch in numpy, over the full-precision series of the Python module."""

from __future__ import annotations

import subprocess
from pathlib import Path

import numpy as np
import pytest

import penumbra

from conftest import run_cli

pd = pytest.importorskip("pandas")

START, STOP = "2025-01-01", "2025-06-30T23:00"
SITE = ("a", -89.5, 30.0)


def _longest(x: np.ndarray) -> int:
    best = cur = 0
    for v in x:
        cur = cur + 1 if v else 0
        best = max(best, cur)
    return best


def _brute(sun, dte, m, lit_min, dark_max, dte_min, blackout_max, el=None, el_min=None,
           el_max=None):
    valid = []
    for k in range(len(sun) - m + 1):
        s, d = sun[k:k + m], dte[k:k + m]
        ok = (100 * np.mean(s > 0) >= lit_min - 1e-9
              and (el_min is None or el[k] >= el_min)
              and (el_max is None or el[k] <= el_max)
              and (dark_max is None or _longest(s <= 0) <= dark_max + 1e-9)
              and 100 * np.mean(d) >= dte_min - 1e-9
              and (blackout_max is None or _longest(~d) <= blackout_max + 1e-9))
        if ok:
            valid.append(k)
    runs = []
    for k in valid:
        if runs and runs[-1][1] + 1 == k:
            runs[-1][1] = k
        else:
            runs.append([k, k])
    return runs


@pytest.mark.parametrize(
    "flags, m, crit",
    [
        (["--profile", "artemis3"], 156, (100.0, None, 50.0, 48)),
        (["--stay-h", "240", "--min-lit-pct", "70", "--max-dark-h", "48", "--min-dte-pct", "60"],
         240, (70.0, 48, 60.0, None)),
        (["--stay-h", "72", "--min-lit-pct", "90", "--min-touchdown-sun-el-deg", "0.6",
          "--max-touchdown-sun-el-deg", "1.4", "--stations", "none"],
         72, (90.0, None, 0.0, None, 0.6, 1.4)),
    ],
)
def test_windows_match_a_brute_force_scan(cli: Path, tmp_path: Path, flags, m, crit) -> None:
    run_cli(cli, tmp_path, "windows", "--synthetic", "--site", ",".join(map(str, SITE)),
            "--start", START, "--stop", STOP, "--step", "1h", *flags, "--out-dir", "w")
    got = pd.read_csv(tmp_path / "w" / "windows.csv")
    touchdown = len(crit) > 4
    table, _ = penumbra.series(penumbra.Terrain.synthetic(), [(*SITE, 2.0)],
                               penumbra.time_range(START, STOP, "1h"),
                               stations="none" if touchdown else "dsn")
    utc = table["utc"]
    dte = (np.ones(len(utc), bool) if touchdown else table["dte"].astype(bool))
    el_crit = (table["sun_el_deg"], *crit[4:]) if touchdown else ()
    runs = _brute(table["sun_visible_fraction"], dte, m, *crit[:4], *el_crit)
    assert runs, "the scan finds windows: the test compares something"
    want_first = [str(utc[a])[:19] + "Z" for a, _ in runs]
    want_last = [str(utc[b])[:19] + "Z" for _, b in runs]
    print(f"{len(runs)} windows, {sum(b - a + 1 for a, b in runs)} valid starts")
    assert list(got.first_start_utc) == want_first
    assert list(got.last_start_utc) == want_last
    assert list(got.starts) == [b - a + 1 for a, b in runs]
    if touchdown:
        el = table["sun_el_deg"]
        lo = [el[a:b + 1].min() for a, b in runs]
        assert np.allclose(got.min_touchdown_sun_el_deg, lo, atol=5e-4)
        assert (got.min_touchdown_sun_el_deg >= 0.6).all()
        assert (got.max_touchdown_sun_el_deg <= 1.4).all()
    # The timeline: one PNG.
    assert (tmp_path / "w" / "windows.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    # Python on the same table: the same windows.
    kw = {"profile": "artemis3"} if flags[0] == "--profile" else {
        "stay_h": 240.0, "min_lit_pct": 70.0, "max_dark_h": 48.0, "min_dte_pct": 60.0}
    if touchdown:
        kw = {"stay_h": 72.0, "min_lit_pct": 90.0, "min_touchdown_sun_el_deg": 0.6,
              "max_touchdown_sun_el_deg": 1.4}
    py = penumbra.landing_windows(table, **kw)
    assert [w["first_start_utc"] for w in py] == want_first
    assert [w["rank"] for w in py] == list(got["rank"])
    # A scenario's [windows] table: the same windows.
    from conftest import ROOT
    spec = ('profile = "artemis3"\n' if flags[0] == "--profile" else
            "stay_h = 240.0\nmin_lit_pct = 70.0\nmax_dark_h = 48.0\nmin_dte_pct = 60.0\n")
    if touchdown:
        spec = ("stay_h = 72.0\nmin_lit_pct = 90.0\nmin_touchdown_sun_el_deg = 0.6\n"
                "max_touchdown_sun_el_deg = 1.4\n")
    (tmp_path / "s.toml").write_text(
        f'name = "w"\nkernels = "{ROOT / "kernels"}"\n'
        f'[time]\nstart = "{START}"\nstop = "{STOP}"\nstep = "1h"\n'
        "[terrain]\nsynthetic = { size_px = 400, px_m = 100.0, seed = 1 }\n"
        "[series]\nplots = false\nwrite_csv = false\n"
        + ('stations = "none"\n' if touchdown else "")
        + f"[windows]\n{spec}"
        f'[[sites]]\nname = "{SITE[0]}"\nlat_deg = {SITE[1]}\nlon_deg = {SITE[2]}\n'
    )
    run_cli(cli, tmp_path, "run", "s.toml", "--out-dir", "scn")
    scn = pd.read_csv(tmp_path / "scn" / "windows.csv")
    assert scn.equals(got), (scn, got)
    # Ranks: 1 = the most valid starts.
    assert got.sort_values("rank").starts.is_monotonic_decreasing
    ics = (tmp_path / "w" / "windows.ics").read_text()
    assert ics.count("BEGIN:VEVENT") == len(runs)
    # The series' files are there too, the same as `penumbra series` writes.
    assert (tmp_path / "w" / "a" / "series.csv").is_file()


@pytest.mark.parametrize(
    "extra, message",
    [
        (["--stay-h", "0"], "stay 0 h"),
        (["--stay-h", "100000"], "longer than the period"),
        (["--stay-h", "10", "--min-sun-fraction", "1.5"], "minimum Sun fraction 1.5"),
        (["--profile", "moonwalk"], "profile 'moonwalk'"),
        (["--profile", "artemis3", "--stations", "none"], "no ground stations"),
        (["--stay-h", "10", "--min-touchdown-sun-el-deg", "2", "--max-touchdown-sun-el-deg",
          "1"], "the minimum 2 deg is above the maximum 1 deg"),
        ([], "give a stay (--stay-h H)"),
    ],
)
def test_bad_windows_input_gets_one_line_and_exit_2(cli: Path, tmp_path: Path, extra,
                                                    message) -> None:
    out = tmp_path / "o"
    r = subprocess.run(
        [str(cli), "windows", "--synthetic", "--site", "a,-89.5,0", "--start", START,
         "--stop", "2025-01-10", "--step", "1h", "--out-dir", str(out), *extra],
        capture_output=True, text=True)
    assert r.returncode == 2, r.stderr
    lines = [line for line in r.stderr.splitlines() if line.strip()]
    assert len(lines) == 1 and message in lines[0], r.stderr
    assert not out.exists()


def test_landing_windows_refuses_like_the_cli() -> None:
    table, _ = penumbra.series(penumbra.Terrain.synthetic(), [(*SITE, 2.0)],
                               penumbra.time_range(START, "2025-01-10", "1h"), stations="none")
    with pytest.raises(penumbra.PenumbraError, match="no ground stations"):
        penumbra.landing_windows(table, profile="artemis3")
    with pytest.raises(penumbra.PenumbraError, match="profile 'moonwalk'"):
        penumbra.landing_windows(table, profile="moonwalk")
    with pytest.raises(penumbra.PenumbraError, match="stay 0 h"):
        penumbra.landing_windows(table, stay_h=0.0)
    with pytest.raises(penumbra.PenumbraError, match="longer than the period"):
        penumbra.landing_windows(table, stay_h=100000.0)


@pytest.mark.parametrize(
    "windows, series, message",
    [
        ('profile = "moonwalk"\n', "[series]\n", "profile 'moonwalk'"),
        ("stay_h = 100000.0\n", "[series]\n", "longer than the period"),
        ('profile = "artemis3"\n', '[series]\nstations = "none"\n', "no ground stations"),
        ('profile = "artemis3"\n', "", "[windows] needs [series]"),
    ],
)
def test_a_bad_windows_table_gets_one_line_and_exit_2(cli: Path, tmp_path: Path, windows, series,
                                                     message) -> None:
    from conftest import ROOT

    (tmp_path / "s.toml").write_text(
        f'name = "w"\nkernels = "{ROOT / "kernels"}"\n'
        f'[time]\nstart = "{START}"\nstop = "2025-01-10"\nstep = "1h"\n'
        "[terrain]\nsynthetic = { size_px = 64, px_m = 100.0, seed = 1 }\n"
        f"{series}[windows]\n{windows}"
        '[[sites]]\nname = "a"\nlat_deg = -89.9\nlon_deg = 0.0\n'
    )
    r = subprocess.run([str(cli), "run", "s.toml", "--out-dir", "o"], cwd=tmp_path,
                       capture_output=True, text=True)
    assert r.returncode == 2, r.stderr
    lines = [line for line in r.stderr.splitlines() if line.strip()]
    assert len(lines) == 1 and message in lines[0], r.stderr
    assert not (tmp_path / "o").exists()
