"""The module's API: dtypes and shapes, time handling, errors, progress, the GIL and Ctrl-C."""

from __future__ import annotations

import _thread
from pathlib import Path
import threading
import time

import numpy as np
import pytest

import penumbra

SITE = ("ridge", -89.6, 0.0, 2.0)


@pytest.fixture(scope="module")
def terrain() -> penumbra.Terrain:
    return penumbra.Terrain.synthetic(size_px=300)


def test_time_range_matches_iso_strings() -> None:
    t = penumbra.time_range("2027-01-01", "2027-01-02", "6h")
    assert t.dtype == np.dtype("datetime64[ns]")
    assert list(t.astype(str)) == [
        f"2027-01-{d}T{h}:00:00.000000000" for d, h in
        [("01", "00"), ("01", "06"), ("01", "12"), ("01", "18"), ("02", "00")]
    ]
    # The same epochs as strings, as numpy datetime64[s] or as a list of datetime64.
    e1 = penumbra.ephem([(-89.5, 0.0, 0.0)], t)
    e2 = penumbra.ephem([(-89.5, 0.0, 0.0)], [str(x)[:19] for x in t])
    e3 = penumbra.ephem([(-89.5, 0.0, 0.0)], t.astype("datetime64[s]"))
    for k in ("sun_el_deg", "earth_az_deg"):
        assert np.array_equal(e1[k], e2[k]) and np.array_equal(e1[k], e3[k])


def test_ephem_shapes_and_dtypes() -> None:
    t = penumbra.time_range("2027-01-01", "2027-01-03", "1h")
    e = penumbra.ephem([(-89.45, -137.3, 1957.0), (-85.99, 2.93, 0.0)], t)
    for k in ("sun_az_deg", "sun_el_deg", "sun_range_km", "sun_radius_deg",
              "earth_az_deg", "earth_el_deg", "earth_range_km", "earth_radius_deg"):
        assert e[k].dtype == np.float64 and e[k].shape == (2, 49), k
    assert np.all((e["sun_az_deg"] >= 0) & (e["sun_az_deg"] < 360))
    assert np.all(np.abs(e["sun_el_deg"]) < 8)
    assert np.all((e["sun_radius_deg"] > 0.26) & (e["sun_radius_deg"] < 0.28))
    assert e["utc"].shape == (49,)


def test_ephem_from_a_meta_kernel(tmp_path: Path) -> None:
    """A SPICE meta-kernel (.tm) gives the same numbers as the folder it lists."""
    kdir = Path(__file__).resolve().parents[2] / "kernels"
    names = sorted(p.name for p in kdir.iterdir() if p.suffix != ".md")
    listed = "\n".join(f"  '$K/{n}'" for n in names)
    mk = tmp_path / "set.tm"
    mk.write_text(
        "KPL/MK\n\\begindata\n"
        f"PATH_VALUES = ( '{kdir}' )\nPATH_SYMBOLS = ( 'K' )\n"
        f"KERNELS_TO_LOAD = (\n{listed}\n)\n\\begintext\n"
    )
    t = penumbra.time_range("2027-01-01", "2027-01-02", "5h")
    a = penumbra.ephem([(-89.45, -137.3, 0.0)], t, kernels=mk)
    b = penumbra.ephem([(-89.45, -137.3, 0.0)], t, kernels=kdir)
    for k in ("sun_az_deg", "sun_el_deg", "earth_range_km"):
        assert np.array_equal(a[k], b[k]), k
    bad = tmp_path / "bad.tm"
    bad.write_text("\\begindata\nKERNELS_TO_LOAD = ( 'nowhere.bsp' )\n")
    with pytest.raises(ValueError, match="nowhere.bsp"):
        penumbra.ephem([(-89.45, -137.3, 0.0)], t, kernels=bad)


def test_terrain(terrain: penumbra.Terrain) -> None:
    assert terrain.shape == (300, 300)
    x0, px, _, y0, _, py_ = terrain.transform
    assert (x0, px, y0, py_) == (-15000.0, 100.0, 15000.0, -100.0)
    assert "Polar_Stereographic" in terrain.crs_wkt
    z = terrain.heights_m()
    assert z.dtype == np.float32 and z.shape == (300, 300)
    h = terrain.height_m(-89.6, 0.0)
    assert isinstance(h, float) and np.isfinite(h)
    hs = terrain.height_m(np.array([-89.6, -80.0]), np.array([0.0, 0.0]))
    assert hs.shape == (2,) and hs[0] == h and np.isnan(hs[1])


def test_horizon(terrain: penumbra.Terrain) -> None:
    h = penumbra.horizon(terrain, -89.6, 0.0, az_step_deg=1.0)
    assert h["az_deg"].shape == h["elevation_deg"].shape == h["distance_m"].shape == (360,)
    assert h["elevation_deg"].dtype == np.float64
    assert np.isfinite(h["ground_height_m"])


def test_series_table_and_stats(terrain: penumbra.Terrain) -> None:
    t = penumbra.time_range("2027-01-01", "2027-01-05", "2h")
    calls = []
    table, stats = penumbra.series(
        terrain, [SITE, ("b", -89.7, 90.0, 10.0)], t, progress=lambda d, n: calls.append((d, n))
    )
    n = 2 * len(t)
    assert table["site"].shape == (n,) and table["site"].dtype.kind == "U"
    assert table["utc"].dtype == np.dtype("datetime64[ns]")
    for k, v in table.items():
        assert v.shape == (n,), k
    assert calls[0] == (0, 2) and calls[-1] == (2, 2)
    assert [s["site"] for s in stats["sites"]] == ["ridge", "b"]
    df = penumbra.to_pandas(table)
    assert list(df.columns)[:3] == ["site", "utc", "sun_az_deg"]


@pytest.mark.parametrize(
    "call, needle",
    [
        (lambda t: penumbra.series(t, [("x", -95.0, 0.0, 2.0)], "2027-01-01"), "latitude"),
        (lambda t: penumbra.series(t, [SITE], "2027-13-01"), "2027-13-01"),
        (lambda t: penumbra.series(t, [SITE], ["2027-01-01", "2027-01-03", "2027-01-04"]), "evenly"),
        (lambda t: penumbra.series(t, [], "2027-01-01"), "at least one site"),
        (lambda t: penumbra.series(t, [SITE, SITE], "2027-01-01"), "ridge"),
        (lambda t: penumbra.series(t, [SITE], "2027-01-01", limb_darkening="x"), "limb_darkening"),
        (lambda t: penumbra.series(t, [SITE], "2027-01-01", abcorr="cn"), "cn"),
        (lambda t: penumbra.series(t, [SITE], "2027-01-01", kernels="/nonexistent"), "kernel"),
        (lambda t: penumbra.series(t, [SITE], "1900-01-01"), "1900"),
        (lambda t: penumbra.ephem([], "2027-01-01"), "at least one site"),
        (lambda t: penumbra.ephem([(-89.0, 0.0, 1e9)], "2027-01-01"), "height"),
        (lambda t: penumbra.ephem([(-89.0, 0.0, 0.0)], 5), "times"),
        (lambda t: penumbra.horizon(t, -89.6, 0.0, method="slow"), "method"),
        (lambda t: penumbra.horizon(t, -80.0, 0.0), "outside"),
        (lambda t: penumbra.horizon(t, -89.6, 0.0, observer_height_m=-1.0), "observer height"),
        (lambda t: penumbra.map_statistics(t, penumbra.time_range("2027-01-01", "2027-01-02", "6h"), engine="fast"), "engine"),
        (lambda t: penumbra.map_statistics(t, "2027-01-01"), "at least two"),
        (lambda t: penumbra.map_statistics(t, penumbra.time_range("2027-01-01", "2027-01-02", "6h"), engine="horizons", horizons="/nonexistent.tif"), "nonexistent"),
        (lambda t: penumbra.map_statistics(t, penumbra.time_range("2027-01-01", "2027-01-02", "6h"), observer_height_m=float("nan")), "observer_height_m"),
        (lambda t: penumbra.map_light(t), "give the light"),
        (lambda t: penumbra.map_light(t, utc="2027-01-01", sun_az_deg=10.0, sun_el_deg=1.0), "give the light"),
        (lambda t: penumbra.map_light(t, sun_az_deg=10.0, sun_el_deg=1.0, engine="horizons"), "map_statistics"),
        (lambda t: penumbra.map_light(t, sun_az_deg=10.0, sun_el_deg=1.0, sun_radius_deg=0.0), "sun_radius_deg"),
        (lambda t: penumbra.Terrain.open([]), "at least one"),
        (lambda t: penumbra.Terrain.open(["/nonexistent.tif"]), "nonexistent"),
        (lambda t: penumbra.Terrain.synthetic(size_px=0), "synthetic"),
        (lambda t: penumbra.time_range("2027-01-02", "2027-01-01", "1h"), "before"),
        (lambda t: penumbra.time_range("2027-01-01", "2027-01-02", "1x"), "1x"),
        (lambda t: penumbra.write_geotiff("/tmp/x.tif", np.zeros((3, 3), np.float32), t, "x"), "shape"),
        (lambda t: penumbra.run_scenario("/nonexistent.toml"), "nonexistent"),
    ],
)
def test_bad_arguments_raise_one_line_errors(terrain: penumbra.Terrain, call, needle: str) -> None:
    with pytest.raises(penumbra.PenumbraError) as e:
        call(terrain)
    msg = str(e.value)
    assert isinstance(e.value, ValueError)
    assert "\n" not in msg, msg
    assert needle.lower() in msg.lower(), msg


def test_the_gil_is_released_during_long_calls(terrain: penumbra.Terrain) -> None:
    ticks = 0
    running = True

    def count() -> None:
        nonlocal ticks
        while running:
            ticks += 1
            time.sleep(0.001)

    th = threading.Thread(target=count)
    th.start()
    try:
        time.sleep(0.05)
        before = ticks
        t0 = time.time()
        penumbra.map_statistics(
            terrain, penumbra.time_range("2027-01-01", "2027-03-01", "1h"),
            engine="horizons", azimuths=90, max_step=6,
        )
        elapsed = time.time() - t0
        during = ticks - before
    finally:
        running = False
        th.join()
    # With the GIL held the thread would not tick at all during the call.
    assert elapsed > 0.2, elapsed
    assert during > 0.2 * elapsed / 0.001 * 0.1, (during, elapsed)


def test_progress_errors_and_ctrl_c_stop_a_series(terrain: penumbra.Terrain) -> None:
    t = penumbra.time_range("2027-01-01", "2027-01-10", "1h")
    sites = [(f"s{i}", -89.6 + 0.004 * (i % 20), 3.0 * i, 2.0) for i in range(40)]

    def boom(done: int, total: int) -> None:
        if done > 0:
            raise RuntimeError("stop here")

    with pytest.raises(RuntimeError, match="stop here"):
        penumbra.series(terrain, sites, t, progress=boom)
    # Ctrl-C: SIGINT delivered to the main thread while the call runs.
    timer = threading.Timer(0.05, _thread.interrupt_main)
    timer.start()
    with pytest.raises(KeyboardInterrupt):
        for _ in range(200):  # until the interrupt lands inside (or between) calls
            penumbra.series(terrain, sites, t)
    timer.cancel()


def test_map_statistics_progress_and_stop(terrain: penumbra.Terrain) -> None:
    times = penumbra.time_range("2027-01-01", "2027-01-15", "6h")
    seen = []
    penumbra.map_statistics(terrain, times, engine="horizons", azimuths=32, max_step=3,
                            progress=lambda d, n: seen.append((d, n)))
    # The sweep's directions (0 .. n), then the statistics' rows (.. 300 of 300).
    assert seen[-1] == (300, 300) and seen[0][1] != 300
    assert any(n != 300 for _, n in seen)

    def stop(done: int, total: int) -> None:
        if done > 0:
            raise RuntimeError("enough")

    with pytest.raises(RuntimeError, match="enough"):
        penumbra.map_statistics(terrain, times, engine="horizons", azimuths=32, max_step=3,
                                progress=stop)


def test_map_light_from_a_direction(terrain: penumbra.Terrain) -> None:
    m = penumbra.map_light(terrain, sun_az_deg=135.0, sun_el_deg=1.5)
    assert set(m) >= {"sun_fraction", "sun_mask", "transform", "crs_wkt", "descriptions"}
    assert "earth_fraction" not in m
    assert m["sun_fraction"].shape == terrain.shape


def test_run_scenario_resumes_a_killed_cli_run(tmp_path: Path, cli: Path) -> None:
    """A `penumbra run` killed part-way (test hook: exit after 5 checkpoints) is finished by
    `run_scenario(..., resume=True)`: the same bytes as an uninterrupted CLI run."""
    import os
    import subprocess

    kdir = Path(__file__).resolve().parents[2] / "kernels"
    (tmp_path / "s.toml").write_text(
        f'name = "r"\nkernels = "{kdir}"\n'
        '[time]\nstart = "2025-01-01"\nstop = "2025-01-15"\nstep = "12h"\n'
        "[terrain]\nsynthetic = { size_px = 64, px_m = 250.0, seed = 2 }\n"
        '[series]\nplots = false\n[map]\nstep = "12h"\nengine = "horizons"\nazimuths = 90\n'
        '[[sites]]\nname = "a"\nlat_deg = -89.8\nlon_deg = 0.0\n'
    )
    env = dict(os.environ, PENUMBRA_TEST_EXIT_AFTER_CHECKPOINTS="5")
    env.pop("PENUMBRA_KERNELS", None)
    run = [str(cli), "run", "s.toml", "--out-dir"]
    killed = subprocess.run([*run, "killed"], cwd=tmp_path, env=env, capture_output=True)
    assert killed.returncode == 137, killed.stderr
    assert not (tmp_path / "killed" / "run.json").exists()
    env.pop("PENUMBRA_TEST_EXIT_AFTER_CHECKPOINTS")
    whole = subprocess.run([*run, "whole"], cwd=tmp_path, env=env, capture_output=True)
    assert whole.returncode == 0, whole.stderr
    penumbra.run_scenario(tmp_path / "s.toml", out_dir=tmp_path / "killed", resume=True)
    files = sorted(
        p.relative_to(tmp_path / "whole")
        for p in (tmp_path / "whole").rglob("*")
        if p.is_file() and p.name != "run.json"
    )
    assert files and files == sorted(
        p.relative_to(tmp_path / "killed")
        for p in (tmp_path / "killed").rglob("*")
        if p.is_file() and p.name != "run.json"
    )
    for f in files:
        assert (tmp_path / "whole" / f).read_bytes() == (tmp_path / "killed" / f).read_bytes(), f


@pytest.mark.parametrize(
    "text",
    [
        "2024-02-01T12:01:09.184 TDB",
        "2024-02-01T12:01:09.184 ET",
        "2024 FEB 01 12:00:00",
        "2024-032T12:00:00",
        "2024-02-01T14:00:00+02:00",
    ],
)
def test_time_inputs_match_spice_str2et(text: str) -> None:
    """Epoch strings in the forms SPICE users type give the UTC instant SPICE's str2et gives
    (within 20 microseconds: hifitime's and SPICE's TDB - TT series differ by less)."""
    spice = pytest.importorskip("spiceypy")
    kdir = Path(__file__).resolve().parents[2] / "kernels"
    spice.furnsh(str(kdir / "naif0012.tls"))
    try:
        # str2et knows no UTC offsets: give it the same instant in UTC.
        spice_text = "2024-02-01T12:00:00" if text.endswith("+02:00") else text
        # str2et takes a time system label after a space-separated date, not after ISO's T,
        # and calls ET "TDB".
        if text.endswith(("TDB", "ET")):
            spice_text = text.replace("T", " ", 1).replace(" ET", " TDB")
        want = np.datetime64(spice.et2utc(spice.str2et(spice_text), "ISOC", 6), "ns")
    finally:
        spice.kclear()
    got = penumbra.time_range(text, text, "1h")[0]
    assert abs((got - want) / np.timedelta64(1, "ns")) < 20_000, (got, want)
