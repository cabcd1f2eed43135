//! `penumbra._penumbra`: the Python module of penumbra, re-exported by the `penumbra` package.
//!
//! A thin binding: every number comes from the Rust library (`penumbra`), the same functions the
//! command line calls. Long calls release the GIL (`Python::allow_threads`) around the Rust work
//! and run in chunks between which they report progress to an optional callback and check for
//! Ctrl-C (`KeyboardInterrupt`). Bad arguments raise `penumbra.PenumbraError` (a `ValueError`)
//! with the command line's one-line message.

use std::path::PathBuf;
use std::sync::Arc;

use hifitime::Epoch;
use numpy::ndarray::Array2;
use numpy::{IntoPyArray, PyReadonlyArray1};
use penumbra::ephem::{self as eph, AbCorr, Kernels};
use penumbra::model::{EpochRange, ObserverHeight, Site};
use penumbra::terrain::TerrainStack;
use pyo3::create_exception;
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};

create_exception!(
    penumbra,
    PenumbraError,
    PyValueError,
    "A bad argument or input: the message is the command line's one error line."
);

/// The one-line error of the command line, as a Python exception.
fn py_err(e: anyhow::Error) -> PyErr {
    PenumbraError::new_err(penumbra::products::one_line(&e))
}

fn bad(msg: impl Into<String>) -> PyErr {
    PenumbraError::new_err(msg.into())
}

/// A value typed by the caller, refused: `<argument>: <the command line's message>`.
fn refused(argument: &str, e: penumbra::model::InputError) -> PyErr {
    bad(format!("{argument}: {e}"))
}

/// `observer_height_m` as the command line's `--observer-height-m` takes it.
fn observer_height(m: f64) -> PyResult<ObserverHeight> {
    ObserverHeight::new(m).map_err(|e| refused("observer_height_m", e))
}

// --- time ---------------------------------------------------------------------------------------

/// Days since 1970-01-01 of a proleptic Gregorian date (H. Hinnant's `days_from_civil`).
fn days_from_civil(y: i64, m: i64, d: i64) -> i64 {
    let y = if m <= 2 { y - 1 } else { y };
    let era = y.div_euclid(400);
    let yoe = y - era * 400;
    let doy = (153 * (m + if m > 2 { -3 } else { 9 }) + 2) / 5 + d - 1;
    let doe = yoe * 365 + yoe / 4 - yoe / 100 + doy;
    era * 146_097 + doe - 719_468
}

/// The proleptic Gregorian date of `days` since 1970-01-01 (`civil_from_days`).
fn civil_from_days(days: i64) -> (i64, i64, i64) {
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z - era * 146_097;
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let d = doy - (153 * mp + 2) / 5 + 1;
    let m = if mp < 10 { mp + 3 } else { mp - 9 };
    (yoe + era * 400 + i64::from(m <= 2), m, d)
}

const NS_PER_DAY: i64 = 86_400_000_000_000;

/// A numpy `datetime64[ns]` value (UTC wall clock, no leap seconds) as an epoch: the same epoch
/// as the command line's parse of the same date and time.
fn epoch_from_unix_ns(ns: i64) -> PyResult<Epoch> {
    if ns == i64::MIN {
        return Err(bad("NaT (not a time) among the times"));
    }
    let (days, rem) = (ns.div_euclid(NS_PER_DAY), ns.rem_euclid(NS_PER_DAY));
    let (y, m, d) = civil_from_days(days);
    let (h, rem) = (rem / 3_600_000_000_000, rem % 3_600_000_000_000);
    let (mi, rem) = (rem / 60_000_000_000, rem % 60_000_000_000);
    let (s, nanos) = (rem / 1_000_000_000, rem % 1_000_000_000);
    let year = i32::try_from(y).map_err(|_| bad(format!("year {y} is out of range")))?;
    Epoch::maybe_from_gregorian_utc(
        year,
        m as u8,
        d as u8,
        h as u8,
        mi as u8,
        s as u8,
        nanos as u32,
    )
    .map_err(|e| bad(format!("time {y:04}-{m:02}-{d:02}: {e}")))
}

/// An epoch as numpy `datetime64[ns]` (UTC wall clock; a leap second reads as the next day's
/// first second, as numpy has none).
fn epoch_to_unix_ns(epoch: Epoch) -> i64 {
    let (y, mo, d, h, mi, s, ns) = epoch.to_gregorian_utc();
    days_from_civil(i64::from(y), i64::from(mo), i64::from(d)) * NS_PER_DAY
        + i64::from(h) * 3_600_000_000_000
        + i64::from(mi) * 60_000_000_000
        + i64::from(s) * 1_000_000_000
        + i64::from(ns)
}

/// Epochs from `times`: one ISO string, a sequence of ISO strings (or of anything whose `str()`
/// is one: `datetime`, `numpy.datetime64`), or a numpy `datetime64` array.
fn epochs_from(times: &Bound<'_, PyAny>) -> PyResult<Vec<Epoch>> {
    if let Ok(text) = times.extract::<String>() {
        return Ok(vec![
            eph::time::parse_utc(&text).map_err(|e| bad(e.to_string()))?,
        ]);
    }
    if let Ok(dtype) = times.getattr("dtype") {
        let kind: String = dtype.getattr("kind")?.extract()?;
        if kind == "M" {
            let ns = times
                .call_method1("astype", ("datetime64[ns]",))?
                .call_method1("astype", ("int64",))?
                .call_method0("ravel")?;
            let ns: PyReadonlyArray1<'_, i64> = ns.extract()?;
            return ns
                .as_slice()?
                .iter()
                .map(|&n| epoch_from_unix_ns(n))
                .collect();
        }
    }
    let mut out = Vec::new();
    for item in times
        .try_iter()
        .map_err(|_| bad("times: give an ISO string, a list of them or a numpy datetime64 array"))?
    {
        let text: String = item?.str()?.extract()?;
        out.push(eph::time::parse_utc(&text).map_err(|e| bad(e.to_string()))?);
    }
    if out.is_empty() {
        return Err(bad("times: no epoch given"));
    }
    Ok(out)
}

/// Epochs as a numpy `datetime64[ns]` array.
fn datetime64<'py>(py: Python<'py>, epochs: &[Epoch]) -> PyResult<Bound<'py, PyAny>> {
    let ns: Vec<i64> = epochs.iter().map(|&e| epoch_to_unix_ns(e)).collect();
    ns.into_pyarray(py)
        .call_method1("astype", ("datetime64[ns]",))
}

/// `time_range(start, stop, step)`: the epochs `start`, `start + step`, … up to `stop`
/// (inclusive on the grid), as the command line's `--start --stop --step`, as `datetime64[ns]`.
#[pyfunction]
fn time_range<'py>(
    py: Python<'py>,
    start: &str,
    stop: &str,
    step: &str,
) -> PyResult<Bound<'py, PyAny>> {
    let range = EpochRange::parse(start, stop, step).map_err(|e| refused("time_range", e))?;
    datetime64(py, &range.epochs())
}

/// The range that `epochs` are (evenly spaced, in order), as the command line's
/// `--start --stop --step` would give them.
fn epoch_range(epochs: &[Epoch]) -> PyResult<EpochRange> {
    EpochRange::from_epochs(epochs).map_err(|e| refused("times", e))
}

// --- kernels, progress ----------------------------------------------------------------------------

fn load_kernels(kernels: Option<PathBuf>) -> PyResult<Kernels> {
    penumbra::products::KernelSource { dir: kernels }
        .load()
        .map_err(py_err)
}

fn abcorr(text: &str) -> PyResult<AbCorr> {
    AbCorr::parse(text).map_err(|e| bad(e.to_string()))
}

/// Reports `done` of `total` to the optional callback and raises `KeyboardInterrupt` on Ctrl-C
/// (called with the GIL, between chunks of work).
fn checkpoint(
    py: Python<'_>,
    progress: Option<&Bound<'_, PyAny>>,
    done: usize,
    total: usize,
) -> PyResult<()> {
    py.check_signals()?;
    if let Some(cb) = progress {
        cb.call1((done, total))?;
    }
    Ok(())
}

// --- terrain --------------------------------------------------------------------------------------

/// A terrain: DEM layers (the finest with data wins at each point) or the synthetic DEM.
#[pyclass(module = "penumbra", frozen)]
struct Terrain {
    stack: Arc<TerrainStack>,
    source: penumbra::products::TerrainSource,
    layers: Vec<String>,
}

#[pymethods]
impl Terrain {
    /// `Terrain.open(paths)`: DEM GeoTIFF layers, any order (sorted finest first).
    #[staticmethod]
    fn open(py: Python<'_>, paths: Vec<PathBuf>) -> PyResult<Self> {
        if paths.is_empty() {
            return Err(bad("Terrain.open: give at least one DEM file"));
        }
        let source = penumbra::products::TerrainSource::Dems(paths);
        let (stack, layers) = py.allow_threads(|| source.load()).map_err(py_err)?;
        Ok(Terrain {
            stack: Arc::new(stack),
            source,
            layers,
        })
    }

    /// `Terrain.synthetic(size_px=400, px_m=100.0, seed=1, far_field=False)`: penumbra's seeded
    /// synthetic south-polar DEM (the command line's `--synthetic`; with `far_field=True` also
    /// its far field, `--synthetic-far-field`).
    #[staticmethod]
    #[pyo3(signature = (size_px = 400, px_m = 100.0, seed = 1, far_field = false))]
    fn synthetic(
        py: Python<'_>,
        size_px: usize,
        px_m: f64,
        seed: u64,
        far_field: bool,
    ) -> PyResult<Self> {
        let params = penumbra::terrain::synth::SynthParams {
            size_px,
            px_m,
            seed,
        };
        let source = if far_field {
            penumbra::products::TerrainSource::SyntheticWithFarField(params)
        } else {
            penumbra::products::TerrainSource::Synthetic(params)
        };
        let (stack, layers) = py.allow_threads(|| source.load()).map_err(py_err)?;
        Ok(Terrain {
            stack: Arc::new(stack),
            source,
            layers,
        })
    }

    /// The layers, finest first (file paths, or a description of the synthetic DEM).
    #[getter]
    fn layers(&self) -> Vec<String> {
        self.layers.clone()
    }

    /// `(rows, cols)` of the finest layer: the grid of maps.
    #[getter]
    fn shape(&self) -> (usize, usize) {
        let g = self.stack.layers[0].grid;
        (g.rows, g.cols)
    }

    /// The finest layer's GDAL geotransform `(x_left_m, px_x_m, 0, y_top_m, 0, -px_y_m)`
    /// (rasterio: `Affine.from_gdal(*t)`).
    #[getter]
    fn transform(&self) -> (f64, f64, f64, f64, f64, f64) {
        geotransform(&self.stack.layers[0].grid)
    }

    /// The finest layer's CRS as WKT (a PROJ string is `crs_proj`).
    #[getter]
    fn crs_wkt(&self) -> String {
        wkt_of(&self.stack.layers[0].projection)
    }

    /// The finest layer's CRS as a PROJ string.
    #[getter]
    fn crs_proj(&self) -> String {
        self.stack.layers[0].projection.proj_string()
    }

    /// The finest layer's heights, metres above the 1737.4 km sphere (NaN = nodata), shape
    /// `(rows, cols)`, float32.
    fn heights_m<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let d = &self.stack.layers[0];
        let a = Array2::from_shape_vec((d.grid.rows, d.grid.cols), d.heights_m.clone())
            .map_err(|e| bad(e.to_string()))?;
        Ok(a.into_pyarray(py).into_any())
    }

    /// `height_m(lat_deg, lon_deg)`: the ground height (m above the sphere) from the finest layer
    /// with data there; NaN outside every layer. Scalars, or arrays of equal length.
    fn height_m<'py>(
        &self,
        py: Python<'py>,
        lat_deg: &Bound<'py, PyAny>,
        lon_deg: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyAny>> {
        let at = |lat: f64, lon: f64| {
            self.stack
                .height_at_lat_lon_m(lat, lon)
                .map_or(f64::NAN, |(h, _)| h)
        };
        if let (Ok(lat), Ok(lon)) = (lat_deg.extract::<f64>(), lon_deg.extract::<f64>()) {
            return Ok(at(lat, lon).into_pyobject(py)?.into_any());
        }
        let lat: Vec<f64> = lat_deg.extract()?;
        let lon: Vec<f64> = lon_deg.extract()?;
        if lat.len() != lon.len() {
            return Err(bad(format!(
                "height_m: {} latitudes but {} longitudes",
                lat.len(),
                lon.len()
            )));
        }
        let h: Vec<f64> = lat.iter().zip(&lon).map(|(&a, &b)| at(a, b)).collect();
        Ok(h.into_pyarray(py).into_any())
    }

    fn __repr__(&self) -> String {
        let (r, c) = self.shape();
        format!(
            "Terrain({} layer(s), finest {r} x {c} px: {})",
            self.layers.len(),
            self.layers[0]
        )
    }
}

fn geotransform(g: &penumbra::terrain::GridGeometry) -> (f64, f64, f64, f64, f64, f64) {
    (g.x_left_m, g.px_x_m, 0.0, g.y_top_m, 0.0, -g.px_y_m)
}

/// A WKT1 description of the map projection on the lunar sphere (rasterio / GDAL read it).
fn wkt_of(p: &penumbra::terrain::Projection) -> String {
    use penumbra::terrain::Projection;
    let r = p.radius_m();
    let geog = format!(
        "GEOGCS[\"Moon sphere\",DATUM[\"Moon\",SPHEROID[\"Moon\",{r},0]],PRIMEM[\"Reference meridian\",0],UNIT[\"degree\",0.0174532925199433]]"
    );
    match *p {
        Projection::PolarStereographic {
            south,
            lon0_deg,
            k0,
            ..
        } => format!(
            "PROJCS[\"{} polar stereographic on the lunar sphere\",{geog},PROJECTION[\"Polar_Stereographic\"],PARAMETER[\"latitude_of_origin\",{}],PARAMETER[\"central_meridian\",{lon0_deg}],PARAMETER[\"scale_factor\",{k0}],PARAMETER[\"false_easting\",0],PARAMETER[\"false_northing\",0],UNIT[\"metre\",1]]",
            if south { "South" } else { "North" },
            if south { -90.0 } else { 90.0 }
        ),
        Projection::Equirectangular {
            lon0_deg,
            lat_ts_deg,
            ..
        } => format!(
            "PROJCS[\"Equirectangular on the lunar sphere\",{geog},PROJECTION[\"Equirectangular\"],PARAMETER[\"standard_parallel_1\",{lat_ts_deg}],PARAMETER[\"central_meridian\",{lon0_deg}],PARAMETER[\"false_easting\",0],PARAMETER[\"false_northing\",0],UNIT[\"metre\",1]]"
        ),
    }
}

// --- ephemeris --------------------------------------------------------------------------------------

/// `ephem(sites, times, kernels=None, abcorr="lt+s")`: the Sun and the Earth seen from each site
/// (`(lat_deg, lon_deg, height_m)`, height above the 1737.4 km sphere) at each time; a dict of
/// float64 arrays of shape `(len(sites), len(times))` (`sun_az_deg`, `sun_el_deg`,
/// `sun_range_km`, `sun_radius_deg`, the same for `earth_`) and `utc` (datetime64[ns]).
#[pyfunction]
#[pyo3(signature = (sites, times, kernels = None, abcorr = "lt+s"))]
fn ephem<'py>(
    py: Python<'py>,
    sites: Vec<(f64, f64, f64)>,
    times: &Bound<'py, PyAny>,
    kernels: Option<PathBuf>,
    abcorr: &str,
) -> PyResult<Bound<'py, PyDict>> {
    let epochs = epochs_from(times)?;
    let ab = self::abcorr(abcorr)?;
    if sites.is_empty() {
        return Err(bad(
            "ephem: give at least one site (lat_deg, lon_deg, height_m)",
        ));
    }
    let sites: Vec<eph::Site> = sites
        .iter()
        .map(|&(lat, lon, h)| eph::Site::new(lat, lon, h).map_err(|e| bad(e.to_string())))
        .collect::<PyResult<_>>()?;
    let kernels = load_kernels(kernels)?;
    let sky = py
        .allow_threads(|| eph::sun_earth_series(&kernels, &sites, &epochs, ab))
        .map_err(|e| py_err(e.into()))?;
    let out = PyDict::new(py);
    let (n, m) = (sites.len(), epochs.len());
    let field = |f: &dyn Fn(&eph::topo::SunEarth) -> f64| -> PyResult<Bound<'py, PyAny>> {
        let v: Vec<f64> = sky.iter().flat_map(|row| row.iter().map(f)).collect();
        let a = Array2::from_shape_vec((n, m), v).map_err(|e| bad(e.to_string()))?;
        Ok(a.into_pyarray(py).into_any())
    };
    out.set_item("sun_az_deg", field(&|v| v.sun.az_deg)?)?;
    out.set_item("sun_el_deg", field(&|v| v.sun.el_deg)?)?;
    out.set_item("sun_range_km", field(&|v| v.sun.range_km)?)?;
    out.set_item("sun_radius_deg", field(&|v| v.sun.radius_deg)?)?;
    out.set_item("earth_az_deg", field(&|v| v.earth.az_deg)?)?;
    out.set_item("earth_el_deg", field(&|v| v.earth.el_deg)?)?;
    out.set_item("earth_range_km", field(&|v| v.earth.range_km)?)?;
    out.set_item("earth_radius_deg", field(&|v| v.earth.radius_deg)?)?;
    out.set_item("utc", datetime64(py, &epochs)?)?;
    Ok(out)
}

/// `station_elevations(site, times, stations="dsn", station_mask_deg=10.0, kernels=None)`: the
/// elevation (deg) of a lunar site (`(lat_deg, lon_deg, height_m)`, planetocentric, height above
/// the 1737.4 km sphere) seen from each ground station at each epoch, light-time corrected: a
/// dict with `station` (names), `lat_deg`, `lon_deg`, `height_m`, `mask_deg` (geodetic, WGS84),
/// `el_deg` (stations × epochs) and `utc`. The numbers behind `series`' `station_el_deg`.
#[pyfunction]
#[pyo3(signature = (site, times, stations = "dsn", station_mask_deg = 10.0, kernels = None))]
fn station_elevations<'py>(
    py: Python<'py>,
    site: (f64, f64, f64),
    times: &Bound<'py, PyAny>,
    stations: &str,
    station_mask_deg: f64,
    kernels: Option<PathBuf>,
) -> PyResult<Bound<'py, PyDict>> {
    let epochs = epochs_from(times)?;
    let list = penumbra::comms::Stations::parse(stations)
        .resolve(station_mask_deg)
        .map_err(|e| bad(e.to_string()))?
        .ok_or_else(|| bad("station_elevations: stations='none' gives no stations"))?;
    let site = eph::Site::new(site.0, site.1, site.2).map_err(|e| bad(e.to_string()))?;
    let kernels = load_kernels(kernels)?;
    let el = py
        .allow_threads(|| -> anyhow::Result<Vec<f64>> {
            let table = eph::moon_geometry_table(&kernels, &epochs)?;
            let at = penumbra::comms::stations_table(&list, &table);
            let (n, m) = (list.len(), table.len());
            let mut out = vec![0.0; n * m];
            let mut one = vec![0.0; n];
            for (k, (geo, a)) in table.iter().zip(&at).enumerate() {
                penumbra::comms::site_elevations_deg(geo, a, &site.pos_in_moon_me_km, &mut one);
                for (i, v) in one.iter().enumerate() {
                    out[i * m + k] = *v;
                }
            }
            Ok(out)
        })
        .map_err(py_err)?;
    let out = PyDict::new(py);
    let np = py.import("numpy")?;
    let names: Vec<&str> = list.iter().map(|s| s.name()).collect();
    out.set_item(
        "station",
        np.call_method1("array", (PyList::new(py, names)?,))?,
    )?;
    let col =
        |f: &dyn Fn(&penumbra::comms::Station) -> f64| -> Vec<f64> { list.iter().map(f).collect() };
    out.set_item("lat_deg", col(&|s| s.lat_deg()).into_pyarray(py))?;
    out.set_item("lon_deg", col(&|s| s.lon_deg()).into_pyarray(py))?;
    out.set_item("height_m", col(&|s| s.height_m()).into_pyarray(py))?;
    out.set_item("mask_deg", col(&|s| s.mask_deg()).into_pyarray(py))?;
    let a =
        Array2::from_shape_vec((list.len(), epochs.len()), el).map_err(|e| bad(e.to_string()))?;
    out.set_item("el_deg", a.into_pyarray(py))?;
    out.set_item("utc", datetime64(py, &epochs)?)?;
    Ok(out)
}

// --- horizon ----------------------------------------------------------------------------------------

/// `horizon(terrain, lat_deg, lon_deg, observer_height_m=2.0, az_step_deg=0.25, method="fast")`:
/// the site's horizon over every layer (the command line's `penumbra horizon`): a dict with
/// `az_deg`, `elevation_deg`, `distance_m` (float64 arrays), `ground_height_m`,
/// `min_distance_m`.
#[pyfunction]
#[pyo3(signature = (terrain, lat_deg, lon_deg, observer_height_m = 2.0, az_step_deg = 0.25, method = "fast"))]
fn horizon<'py>(
    py: Python<'py>,
    terrain: &Terrain,
    lat_deg: f64,
    lon_deg: f64,
    observer_height_m: f64,
    az_step_deg: f64,
    method: &str,
) -> PyResult<Bound<'py, PyDict>> {
    let method = match method {
        "fast" => penumbra::horizon::HorizonMethod::Fast,
        "exact" => penumbra::horizon::HorizonMethod::Exact,
        other => return Err(bad(format!("method '{other}': use fast or exact"))),
    };
    let params = penumbra::horizon::HorizonParams {
        observer_height_m: observer_height(observer_height_m)?.m(),
        az_step_deg,
        method,
        ..Default::default()
    };
    let stack = Arc::clone(&terrain.stack);
    let h = py
        .allow_threads(|| {
            penumbra::horizon::HorizonEngine::new(&stack).horizon(lat_deg, lon_deg, &params)
        })
        .map_err(|e| py_err(e.into()))?;
    let out = PyDict::new(py);
    out.set_item("az_deg", h.az_deg.into_pyarray(py))?;
    // `horizon_el_deg` as in horizon.csv; `elevation_deg` is its old name, kept for a while.
    out.set_item("horizon_el_deg", h.elevation_deg.clone().into_pyarray(py))?;
    out.set_item("elevation_deg", h.elevation_deg.into_pyarray(py))?;
    out.set_item("distance_m", h.distance_m.into_pyarray(py))?;
    out.set_item("ground_height_m", h.ground_height_m)?;
    out.set_item("min_distance_m", h.min_distance_m)?;
    Ok(out)
}

// --- series -----------------------------------------------------------------------------------------

/// The columns of a series table, in order (the CLI's `series.csv` after `site` and `utc`).
const SERIES_COLUMNS: [&str; 11] = [
    "sun_az_deg",
    "sun_el_deg",
    "sun_horizon_el_deg",
    "sun_visible_fraction",
    "sun_irradiance_normal_w_m2",
    "sun_irradiance_horizontal_w_m2",
    "sun_irradiance_vertical_tracking_w_m2",
    "earth_az_deg",
    "earth_el_deg",
    "earth_horizon_el_deg",
    "earth_visible_fraction",
];

/// One site's columns.
struct SiteColumns {
    columns: Vec<Vec<f64>>,
    sun: Vec<f64>,
    earth: Vec<f64>,
    links: Vec<penumbra::comms::LinkSample>,
    power: Vec<(f64, Option<f64>)>,
    power_stats: Option<penumbra::illum::power::PowerStats>,
}

/// `series(terrain, sites, times, …)`: hourly (or any) Sun and Earth visibility of named sites
/// (`(name, lat_deg, lon_deg, height_above_ground_m)`), as `penumbra series` computes it. Returns
/// `(table, stats)`: `table` a dict of equal-length columns (`site`: str, `utc`:
/// datetime64[ns], then the float64 columns of `series.csv`), one row per site and epoch;
/// `stats` the dict of the CLI's `stats.json` (needs evenly spaced times).
#[pyfunction]
#[pyo3(signature = (terrain, sites, times, kernels = None, abcorr = "lt+s", limb_darkening = "eddington", disc_method = "exact", az_step_deg = 0.25, horizon_method = "fast", stations = "dsn", station_mask_deg = 10.0, relays = Vec::new(), relay_spks = Vec::new(), relay_max_range_km = None, panel = None, panel_area_m2 = None, panel_efficiency = None, panel_degradation_pct_per_year = None, load_w = None, night_load_w = None, battery_wh = None, battery_start_pct = None, load_profile = None, neighbourhood_m = None, out_dir = None, progress = None))]
#[allow(clippy::too_many_arguments, reason = "Python keyword arguments")]
fn series<'py>(
    py: Python<'py>,
    terrain: &Terrain,
    sites: Vec<Bound<'py, PyAny>>,
    times: &Bound<'py, PyAny>,
    kernels: Option<PathBuf>,
    abcorr: &str,
    limb_darkening: &str,
    disc_method: &str,
    az_step_deg: f64,
    horizon_method: &str,
    stations: &str,
    station_mask_deg: f64,
    relays: Vec<String>,
    relay_spks: Vec<PathBuf>,
    relay_max_range_km: Option<f64>,
    panel: Option<&str>,
    panel_area_m2: Option<f64>,
    panel_efficiency: Option<f64>,
    panel_degradation_pct_per_year: Option<f64>,
    load_w: Option<f64>,
    night_load_w: Option<f64>,
    battery_wh: Option<f64>,
    battery_start_pct: Option<f64>,
    load_profile: Option<PathBuf>,
    neighbourhood_m: Option<f64>,
    out_dir: Option<PathBuf>,
    progress: Option<Bound<'py, PyAny>>,
) -> PyResult<(Bound<'py, PyDict>, Bound<'py, PyAny>)> {
    use penumbra::products::series::{self as ser, SeriesConfig};
    if let Some(r) = neighbourhood_m {
        ser::neighbourhood::check_radius_m(r).map_err(|e| bad(e.to_string()))?;
    }
    // The power options as the command line reads them: any one turns the panel on.
    let power =
        penumbra::illum::power::PowerConfig::from_options(&penumbra::illum::power::PowerOptions {
            panel,
            area_m2: panel_area_m2,
            efficiency: panel_efficiency,
            degradation_pct_per_year: panel_degradation_pct_per_year,
            load_w,
            night_load_w,
            battery_wh,
            battery_start_pct,
            load_profile: load_profile.as_deref(),
        })
        .map_err(|e| bad(e.to_string()))?;
    let relays = relays
        .iter()
        .map(|r| penumbra::comms::Relay::parse(r).map_err(|e| bad(e.to_string())))
        .collect::<PyResult<Vec<_>>>()?;
    let epochs = epochs_from(times)?;
    if let Some(p) = &power {
        p.loads(&epochs).map_err(|e| bad(e.to_string()))?;
    }
    let step_s = match epochs.len() {
        1 => 3600.0,
        _ => epoch_range(&epochs)?.step_s(),
    };
    let mut config = SeriesConfig {
        abcorr: self::abcorr(abcorr)?,
        az_step_deg,
        write_csv: true,
        plots: false,
        stations: penumbra::comms::Stations::parse(stations),
        station_mask_deg,
        relays,
        relay_spks,
        relay_max_range_km,
        power,
        neighbourhood_m,
        ..SeriesConfig::default()
    };
    // A bad station list fails before any work, with the command line's message.
    config
        .stations
        .resolve(config.station_mask_deg)
        .map_err(|e| bad(e.to_string()))?;
    config.limb_darkening = limb_law(limb_darkening)?;
    config.disc_method = match disc_method {
        "exact" => penumbra::illum::DiscMethod::Exact,
        "segment" => penumbra::illum::DiscMethod::Segment,
        "middle-value" => penumbra::illum::DiscMethod::MiddleValue,
        o => {
            return Err(bad(format!(
                "disc_method '{o}': use exact, segment or middle-value"
            )));
        }
    };
    config.horizon_method = match horizon_method {
        "fast" => penumbra::horizon::HorizonMethod::Fast,
        "exact" => penumbra::horizon::HorizonMethod::Exact,
        o => return Err(bad(format!("horizon_method '{o}': use fast or exact"))),
    };
    let specs: Vec<Site> = sites
        .iter()
        .enumerate()
        .map(|(i, t)| {
            let (name, lat_deg, lon_deg, height_m) = site_tuple(i, t)?;
            Site::new(&name, lat_deg, lon_deg, observer_height(height_m)?)
                .map_err(|e| refused("sites", e))
        })
        .collect::<PyResult<_>>()?;
    if specs.is_empty() {
        return Err(bad(
            "series: give at least one site (name, lat_deg, lon_deg, height_m)",
        ));
    }
    penumbra::model::check_distinct_sites(&specs).map_err(|e| refused("sites", e))?;
    let kernels_dir = kernels.clone();
    let kernels = load_kernels(kernels)?;
    let stack = Arc::clone(&terrain.stack);

    // Horizons and the shared ephemeris, then the sites in chunks (progress, Ctrl-C between).
    let (horizons, table, link) = py
        .allow_threads(|| -> anyhow::Result<_> {
            let (horizons, _) = penumbra::compute::horizons::site_horizons(
                penumbra::compute::Backend::Cpu,
                &stack,
                &specs,
                config.az_step_deg,
                config.horizon_method,
            )?;
            let table = eph::moon_geometry_table(&kernels, &epochs)?;
            let link = ser::LinkContext::new(&kernels, &config, &table)?;
            Ok((horizons, table, link))
        })
        .map_err(py_err)?;
    let chunk = rayon::current_num_threads().max(1) * 2;
    let mut results: Vec<SiteColumns> = Vec::with_capacity(specs.len());
    checkpoint(py, progress.as_ref(), 0, specs.len())?;
    for (specs_chunk, horizons_chunk) in specs.chunks(chunk).zip(horizons.chunks(chunk)) {
        let part = py
            .allow_threads(|| {
                use rayon::prelude::*;
                specs_chunk
                    .par_iter()
                    .zip(horizons_chunk)
                    .map(|(spec, horizon)| {
                        site_columns(&table, spec, horizon, &config, link.as_ref(), step_s)
                    })
                    .collect::<anyhow::Result<Vec<_>>>()
            })
            .map_err(py_err)?;
        results.extend(part);
        checkpoint(py, progress.as_ref(), results.len(), specs.len())?;
    }

    // The long table.
    let n_rows = specs.len() * epochs.len();
    let out = PyDict::new(py);
    let names: Vec<&str> = specs
        .iter()
        .flat_map(|s| std::iter::repeat_n(s.name(), epochs.len()))
        .collect();
    let np = py.import("numpy")?;
    out.set_item(
        "site",
        np.call_method1("array", (PyList::new(py, names)?,))?,
    )?;
    let utc_one: Vec<i64> = epochs.iter().map(|&e| epoch_to_unix_ns(e)).collect();
    let utc: Vec<i64> = (0..specs.len())
        .flat_map(|_| utc_one.iter().copied())
        .collect();
    out.set_item(
        "utc",
        utc.into_pyarray(py)
            .call_method1("astype", ("datetime64[ns]",))?,
    )?;
    for (c, name) in SERIES_COLUMNS.iter().enumerate() {
        let mut col = Vec::with_capacity(n_rows);
        for r in &results {
            col.extend_from_slice(&r.columns[c]);
        }
        out.set_item(*name, col.into_pyarray(py))?;
    }
    let samples = || results.iter().flat_map(|r| r.links.iter());
    if let Some(l) = link.as_ref().filter(|l| l.has_stations()) {
        // The columns series.csv gains with stations: dte (0/1), station_el_deg, station.
        let dte: Vec<u8> = samples().map(|s| u8::from(s.dte())).collect();
        let el: Vec<f64> = samples().map(|s| s.station_el_deg).collect();
        let names: Vec<&str> = samples()
            .map(|s| s.station.map_or("", |i| l.stations()[i].name()))
            .collect();
        out.set_item("dte", dte.into_pyarray(py))?;
        out.set_item("station_el_deg", el.into_pyarray(py))?;
        out.set_item(
            "station",
            np.call_method1("array", (PyList::new(py, names)?,))?,
        )?;
    }
    if let Some(p) = &config.power {
        // The columns series.csv gains with a panel: power_w, and battery_wh with a capacity.
        let power: Vec<f64> = results
            .iter()
            .flat_map(|r| r.power.iter().map(|x| x.0))
            .collect();
        out.set_item("power_w", power.into_pyarray(py))?;
        if p.battery_wh.is_some() {
            let b: Vec<f64> = results
                .iter()
                .flat_map(|r| r.power.iter().map(|x| x.1.unwrap_or(f64::NAN)))
                .collect();
            out.set_item("battery_wh", b.into_pyarray(py))?;
        }
    }
    if let Some(l) = link.as_ref().filter(|l| !l.relays().is_empty()) {
        // The columns series.csv gains with relays: relay_visible (0/1), relay_el_deg, relay.
        let visible: Vec<u8> = samples().map(|s| u8::from(s.relay_visible)).collect();
        let el: Vec<f64> = samples().map(|s| s.relay_el_deg).collect();
        let names: Vec<&str> = samples()
            .map(|s| s.relay.map_or("", |i| l.relays()[i].name.as_str()))
            .collect();
        out.set_item("relay_visible", visible.into_pyarray(py))?;
        out.set_item("relay_el_deg", el.into_pyarray(py))?;
        out.set_item(
            "relay",
            np.call_method1("array", (PyList::new(py, names)?,))?,
        )?;
    }

    // Statistics, as stats.json.
    let series_list: Vec<penumbra::illum::stats::SiteSeries<'_>> = specs
        .iter()
        .zip(&results)
        .map(|(s, r)| penumbra::illum::stats::SiteSeries {
            site: s.name(),
            start_utc: epochs[0],
            step_s,
            sun_fraction: &r.sun,
            earth_fraction: &r.earth,
        })
        .collect();
    let mut stats = penumbra::illum::stats::StatsFile::from_series(&series_list)
        .map_err(|e| py_err(e.into()))?;
    for (((s, spec), horizon), (series, r)) in stats
        .sites
        .iter_mut()
        .zip(&specs)
        .zip(&horizons)
        .zip(series_list.iter().zip(&results))
    {
        s.location = Some(ser::site_location(spec, horizon));
        if let Some(l) = &link {
            if l.has_stations() {
                s.link = Some(l.summary(series, &r.links).map_err(py_err)?.0);
            }
            s.relay = l.relay_summary(series, &r.links).map_err(py_err)?;
        }
        s.power = r.power_stats.clone();
    }
    let json = match out_dir {
        // The files `penumbra series` writes, by the same product: the returned statistics are
        // then those of the written stats.json (with each site's neighbourhood).
        Some(dir) => {
            let req = ser::SeriesRequest {
                terrain: terrain.source.clone(),
                sites: specs.clone(),
                epochs: match epochs.len() {
                    1 => penumbra::model::Epochs::One(epochs[0]),
                    _ => penumbra::model::Epochs::Range(epoch_range(&epochs)?),
                },
                config: config.clone(),
                kernels: penumbra::products::KernelSource {
                    dir: kernels_dir.clone(),
                },
                out_dir: dir.clone(),
            };
            py.allow_threads(|| ser::run(&req)).map_err(py_err)?;
            std::fs::read_to_string(dir.join("stats.json")).map_err(|e| bad(e.to_string()))?
        }
        None => {
            if config.neighbourhood_m.is_some_and(|r| r > 0.0) {
                return Err(bad(
                    "series: neighbourhood_m needs out_dir (the neighbourhood is written with the files)",
                ));
            }
            // The numbers as stats.json writes them.
            let mut value = serde_json::to_value(&stats).map_err(|e| bad(e.to_string()))?;
            penumbra::output::round_json_numbers(&mut value);
            value.to_string()
        }
    };
    let stats = py.import("json")?.call_method1("loads", (json,))?;
    Ok((out, stats))
}

/// A site as Python gives it: `(name, lat_deg, lon_deg)` (2 m above the ground, as the command
/// line's `--site NAME,LAT,LON`) or `(name, lat_deg, lon_deg, height_above_ground_m)`, with one
/// clear error naming the site's index otherwise.
fn site_tuple(i: usize, t: &Bound<'_, PyAny>) -> PyResult<(String, f64, f64, f64)> {
    let wrong = || {
        bad(format!(
            "sites[{i}]: expected (name, lat_deg, lon_deg) or (name, lat_deg, lon_deg, height_above_ground_m), got {}",
            t.repr().map_or_else(|_| "?".to_string(), |r| r.to_string())
        ))
    };
    if let Ok((name, lat, lon, h)) = t.extract::<(String, f64, f64, f64)>() {
        return Ok((name, lat, lon, h));
    }
    if let Ok((name, lat, lon)) = t.extract::<(String, f64, f64)>() {
        return Ok((name, lat, lon, penumbra::DEFAULT_OBSERVER_HEIGHT_M));
    }
    Err(wrong())
}

/// One site's rows, as `series.csv` has them.
fn site_columns(
    table: &[eph::topo::MoonGeometry],
    spec: &Site,
    horizon: &penumbra::horizon::Horizon,
    config: &penumbra::products::series::SeriesConfig,
    link: Option<&penumbra::products::series::LinkContext>,
    step_s: f64,
) -> anyhow::Result<SiteColumns> {
    use penumbra::products::series as ser;
    let site = eph::Site::new(
        spec.lat_deg(),
        spec.lon_deg(),
        horizon.ground_height_m + spec.height_above_ground_m(),
    )?;
    let mut columns = vec![Vec::with_capacity(table.len()); SERIES_COLUMNS.len()];
    let profile = penumbra::illum::HorizonProfile::new(&horizon.elevation_deg)?;
    let mut links = Vec::new();
    let mut scratch = ser::LinkScratch::default();
    let mut track = config
        .power
        .as_ref()
        .map(|p| {
            let epochs: Vec<_> = table.iter().map(|g| g.epoch).collect();
            ser::PowerTrack::new(p, &epochs, step_s)
        })
        .transpose()?;
    let mut power = Vec::new();
    let (sun, earth) = ser::site_fractions(
        table,
        &site,
        horizon,
        ser::SiteFractions::FromHorizon,
        config,
        |_| true,
        |k, r| {
            for (c, v) in columns.iter_mut().zip(ser::row_values(r)) {
                c.push(v);
            }
            if let Some(l) = link {
                links.push(l.sample(table, k, &site, &r.earth, &profile, &mut scratch));
            }
            if let Some(t) = track.as_mut() {
                power.push(t.sample(table[k].epoch, r));
            }
            Ok(())
        },
    )?;
    Ok(SiteColumns {
        columns,
        sun,
        earth,
        links,
        power,
        power_stats: track.as_ref().map(ser::PowerTrack::stats),
    })
}

// --- maps -------------------------------------------------------------------------------------------

/// `map_statistics(terrain, times, engine="auto", …)`: illumination statistics of every pixel of
/// the finest layer over evenly spaced `times` (the CLI's `penumbra map --start --stop --step`,
/// CPU). Returns a dict: one float32 array `(rows, cols)` per statistic (the CLI's file stems:
/// `sun_illumination_pct`, `sun_visible_pct`, `longest_dark_h`, `earth_visible_pct`,
/// `sun_and_earth_pct`, and with the horizons engine `sun_full_pct`, `longest_earth_hidden_h`,
/// `irradiance_horizontal_w_m2`, `irradiance_tracking_w_m2`), `psr_mask` (uint8), and
/// `transform`, `crs_wkt`, `descriptions`, `engine`. With the horizons engine `progress(done,
/// total)` hears the sweep's directions, then the statistics' rows, and Ctrl-C stops the run
/// between them.
/// `landing_windows(table, profile=None, stay_h=None, …)`: the landing windows of `penumbra
/// windows` in the long table `series()` returns (its `site`, `utc`, `sun_visible_fraction` and,
/// for DTE conditions, `dte` columns; evenly spaced times). `profile` is a preset (`artemis3`,
/// `clps`, `rover`); the other values override it. Returns a list of dicts, the windows of
/// `windows.json`.
#[pyfunction]
#[pyo3(signature = (table, profile = None, stay_h = None, min_sun_fraction = None, min_lit_pct = None, max_dark_h = None, min_dte_pct = None, max_blackout_h = None, min_touchdown_sun_el_deg = None, max_touchdown_sun_el_deg = None))]
#[allow(clippy::too_many_arguments, reason = "Python keyword arguments")]
fn landing_windows<'py>(
    py: Python<'py>,
    table: &Bound<'py, PyDict>,
    profile: Option<&str>,
    stay_h: Option<f64>,
    min_sun_fraction: Option<f64>,
    min_lit_pct: Option<f64>,
    max_dark_h: Option<f64>,
    min_dte_pct: Option<f64>,
    max_blackout_h: Option<f64>,
    min_touchdown_sun_el_deg: Option<f64>,
    max_touchdown_sun_el_deg: Option<f64>,
) -> PyResult<Bound<'py, PyAny>> {
    use penumbra::products::windows as win;
    let p = win::Profile::from_options(
        profile,
        win::ProfileOptions {
            stay_h,
            min_sun_fraction,
            min_lit_pct,
            max_dark_h,
            min_dte_pct,
            max_blackout_h,
            min_touchdown_sun_el_deg,
            max_touchdown_sun_el_deg,
        },
    )
    .map_err(|e| bad(penumbra::products::one_line(&e)))?;
    let column = |name: &str| -> PyResult<Bound<'py, PyAny>> {
        table.get_item(name)?.ok_or_else(|| {
            bad(format!(
                "landing_windows: the table has no '{name}' column (pass what series() returns)"
            ))
        })
    };
    let sites: Vec<String> = column("site")?.call_method0("tolist")?.extract()?;
    let sun: Vec<f64> = column("sun_visible_fraction")?
        .call_method0("tolist")?
        .extract()?;
    let sun_el_deg: Vec<f64> = column("sun_el_deg")?.call_method0("tolist")?.extract()?;
    let dte: Option<Vec<bool>> = match table.get_item("dte")? {
        Some(d) => Some(
            d.call_method0("tolist")?
                .extract::<Vec<i64>>()?
                .into_iter()
                .map(|x| x != 0)
                .collect(),
        ),
        None => None,
    };
    p.validate(dte.is_some())
        .map_err(|e| bad(penumbra::products::one_line(&e)))?;
    let utc = epochs_from(&column("utc")?)?;
    if sites.len() != sun.len() || sites.len() != utc.len() || sites.len() != sun_el_deg.len() {
        return Err(bad("landing_windows: the table's columns differ in length"));
    }
    let mut out = Vec::new();
    let mut a = 0;
    while a < sites.len() {
        let mut b = a;
        while b < sites.len() && sites[b] == sites[a] {
            b += 1;
        }
        let step_s = match b - a {
            1 => 3600.0,
            _ => epoch_range(&utc[a..b])?.step_s(),
        };
        win::check_stay(&p, b - a, step_s).map_err(|e| bad(penumbra::products::one_line(&e)))?;
        let x = win::SiteSamples {
            sun: &sun[a..b],
            sun_el_deg: &sun_el_deg[a..b],
            dte: dte.as_ref().map(|d| &d[a..b]),
        };
        out.extend(win::site_windows(&sites[a], x, utc[a], step_s, &p));
        a = b;
    }
    let json = serde_json::to_string(&out).map_err(|e| bad(e.to_string()))?;
    py.import("json")?.call_method1("loads", (json,))
}

#[pyfunction]
#[pyo3(signature = (terrain, times, engine = "auto", observer_height_m = 2.0, kernels = None, abcorr = "lt+s", horizons = None, azimuths = 720, max_step = 16, limb_darkening = "eddington", stations = "none", station_mask_deg = 10.0, panel = None, panel_area_m2 = None, panel_efficiency = None, panel_degradation_pct_per_year = None, load_w = None, night_load_w = None, load_profile = None, progress = None))]
fn map_statistics<'py>(
    py: Python<'py>,
    terrain: &Terrain,
    times: &Bound<'py, PyAny>,
    engine: &str,
    observer_height_m: f64,
    kernels: Option<PathBuf>,
    abcorr: &str,
    horizons: Option<PathBuf>,
    azimuths: usize,
    max_step: u32,
    limb_darkening: &str,
    stations: &str,
    station_mask_deg: f64,
    panel: Option<&str>,
    panel_area_m2: Option<f64>,
    panel_efficiency: Option<f64>,
    panel_degradation_pct_per_year: Option<f64>,
    load_w: Option<f64>,
    night_load_w: Option<f64>,
    load_profile: Option<PathBuf>,
    progress: Option<Bound<'py, PyAny>>,
) -> PyResult<Bound<'py, PyDict>> {
    use penumbra::compute::range::{HorizonsFrom, RangeHooks, RangeInputs};
    use penumbra::products::map as pm;
    // The power options as `penumbra map` reads them: any one adds the power maps.
    let power =
        penumbra::illum::power::PowerConfig::from_options(&penumbra::illum::power::PowerOptions {
            panel,
            area_m2: panel_area_m2,
            efficiency: panel_efficiency,
            degradation_pct_per_year: panel_degradation_pct_per_year,
            load_w,
            night_load_w,
            load_profile: load_profile.as_deref(),
            ..Default::default()
        })
        .map_err(|e| bad(e.to_string()))?;
    let epochs = epoch_range(&epochs_from(times)?)?;
    let settings = pm::MapSettings {
        observer_height: observer_height(observer_height_m)?,
        engine: engine_choice(engine)?,
        backend: penumbra::compute::Backend::Cpu,
        horizons: match horizons {
            Some(p) => HorizonsFrom::File(p),
            None => HorizonsFrom::Sweep { azimuths, max_step },
        },
        limb: limb_law(limb_darkening)?,
        stations: penumbra::comms::Stations::parse(stations),
        station_mask_deg,
        power,
        ..pm::MapSettings::default()
    };
    let ab = self::abcorr(abcorr)?;
    let kernels = load_kernels(kernels)?;
    let stack = Arc::clone(&terrain.stack);
    let (source, layers) = (terrain.source.clone(), terrain.layers.clone());
    // Progress and Ctrl-C from inside the Rust run: the GIL is taken back for each report.
    let callback: Option<Py<PyAny>> = progress.map(Bound::unbind);
    let mut stopped: Option<PyErr> = None;
    let mut report = |done: usize, total: usize| -> bool {
        Python::with_gil(|py| {
            match checkpoint(py, callback.as_ref().map(|c| c.bind(py)), done, total) {
                Ok(()) => true,
                Err(e) => {
                    stopped = Some(e);
                    false
                }
            }
        })
    };
    let result = py.allow_threads(|| -> anyhow::Result<_> {
        let inputs = RangeInputs {
            stack: &stack,
            kernels: &kernels,
            epochs: &epochs,
            abcorr: ab,
        };
        let hooks = RangeHooks {
            report: &mut report,
            store: &mut penumbra::horizon::statistics::NoStore,
        };
        let result = pm::statistics(&settings, inputs, hooks)?;
        let (rasters, psr) =
            pm::range_rasters(&stack.layers[0], result.model.as_ref(), &result.stats)?;
        let span = pm::span_text(&epochs.epochs());
        let mut items = pm::range_metadata(&span, &result.stats);
        // How the maps were made, as the command line's GeoTIFFs say it.
        let mut prov = penumbra::output::Provenance::new();
        prov.dem_layers = layers.clone();
        prov.dem_files = source.dem_files()?;
        prov.kernels = kernels.files.clone();
        let made = penumbra::output::MadeWith::new(
            &prov,
            settings.observer_height.m(),
            result.engine.name(),
            &result.stats.limb_law(),
            &span,
        );
        items.extend(made.items());
        Ok((rasters, psr, result.note, items))
    });
    let (rasters, psr, note, items) = match (result, stopped) {
        (_, Some(e)) => return Err(e),
        (r, None) => r.map_err(py_err)?,
    };
    let g = stack.layers[0].grid;
    let out = PyDict::new(py);
    let descriptions = PyDict::new(py);
    let units = PyDict::new(py);
    for r in rasters {
        let a =
            Array2::from_shape_vec((g.rows, g.cols), r.values).map_err(|e| bad(e.to_string()))?;
        out.set_item(r.name, a.into_pyarray(py))?;
        descriptions.set_item(r.name, r.description)?;
        units.set_item(r.name, pm::geotiff_unit(r.name))?;
    }
    let a = Array2::from_shape_vec((g.rows, g.cols), psr).map_err(|e| bad(e.to_string()))?;
    out.set_item("psr_mask", a.into_pyarray(py))?;
    descriptions.set_item("psr_mask", pm::PSR_DESCRIPTION)?;
    units.set_item("psr_mask", "")?;
    out.set_item("descriptions", descriptions)?;
    out.set_item("units", units)?;
    out.set_item("metadata", metadata_dict(py, &items)?)?;
    out.set_item("transform", geotransform(&g))?;
    out.set_item("crs_wkt", wkt_of(&stack.layers[0].projection))?;
    out.set_item("engine", note)?;
    out.set_item("epochs", epochs.len())?;
    Ok(out)
}

/// `map_light(terrain, utc=None, sun_az_deg=None, sun_el_deg=None, …)`: one light over the
/// finest layer's pixels, as `penumbra map --utc` or `--sun-az-deg/--sun-el-deg` computes it (CPU,
/// rays from each pixel's own surface point): a dict with `sun_fraction` (float32, NaN = nodata),
/// `sun_mask` (uint8: 1 lit, 0 shadow, 255 nodata), with `utc` also `earth_fraction`, and
/// `transform`, `crs_wkt`, `descriptions`. Give `utc`, or `sun_az_deg` and `sun_el_deg` (at the
/// map centre) with `sun_radius_deg`.
#[pyfunction]
#[pyo3(signature = (terrain, utc = None, sun_az_deg = None, sun_el_deg = None, sun_radius_deg = 0.2666, engine = "auto", observer_height_m = 2.0, kernels = None, abcorr = "lt+s"))]
fn map_light<'py>(
    py: Python<'py>,
    terrain: &Terrain,
    utc: Option<&str>,
    sun_az_deg: Option<f64>,
    sun_el_deg: Option<f64>,
    sun_radius_deg: f64,
    engine: &str,
    observer_height_m: f64,
    kernels: Option<PathBuf>,
    abcorr: &str,
) -> PyResult<Bound<'py, PyDict>> {
    use penumbra::products::map as pm;
    let engine = match engine_choice(engine)? {
        Some(penumbra::model::MapEngineKind::Horizons) => {
            return Err(bad(
                "engine 'horizons' makes statistics over an epoch range: use map_statistics",
            ));
        }
        other => other,
    };
    let settings = pm::MapSettings {
        observer_height: observer_height(observer_height_m)?,
        engine,
        backend: penumbra::compute::Backend::Cpu,
        ..pm::MapSettings::default()
    };
    let light = match (utc, sun_az_deg, sun_el_deg) {
        (Some(t), None, None) => {
            pm::Light::Epoch(eph::time::parse_utc(t).map_err(|e| bad(e.to_string()))?)
        }
        (None, Some(az_deg), Some(el_deg)) => pm::Light::AzElAtCentre {
            az_deg,
            el_deg,
            radius_deg: sun_radius_deg,
        }
        .checked()
        .map_err(|e| bad(format!("sun_az_deg, sun_el_deg, sun_radius_deg: {e}")))?,
        _ => {
            return Err(bad(
                "give the light: utc, or sun_az_deg and sun_el_deg (not both)",
            ));
        }
    };
    let ab = self::abcorr(abcorr)?;
    let kernels = match light {
        pm::Light::Epoch(_) => Some(load_kernels(kernels)?),
        _ => None,
    };
    let stack = Arc::clone(&terrain.stack);
    let every = pm::OneLightOutputs {
        sun_fraction: true,
        sun_mask: true,
        earth_fraction: true,
    };
    let maps = py
        .allow_threads(|| pm::one_light(&settings, &stack, (light, kernels.as_ref(), ab), every))
        .map_err(py_err)?;
    // The layers and kernels, as the command line records them.
    let mut prov = penumbra::output::Provenance::new();
    prov.dem_layers = terrain.layers.clone();
    prov.dem_files = terrain.source.dem_files().map_err(py_err)?;
    if let Some(k) = &kernels {
        prov.kernels = k.files.clone();
    }
    let mut items = maps.metadata;
    items.extend(pm::made_with_items(&prov, kernels.is_some()));
    let (sun_f, mask, earth_f) = (
        maps.sun_fraction.unwrap_or_default(),
        maps.sun_mask.unwrap_or_default(),
        maps.earth_fraction,
    );
    let g = stack.layers[0].grid;
    let out = PyDict::new(py);
    let descriptions = PyDict::new(py);
    let grid2 =
        |v: Vec<f32>| Array2::from_shape_vec((g.rows, g.cols), v).map_err(|e| bad(e.to_string()));
    out.set_item("sun_fraction", grid2(sun_f)?.into_pyarray(py))?;
    descriptions.set_item("sun_fraction", pm::SUN_FRACTION_DESCRIPTION)?;
    let m = Array2::from_shape_vec((g.rows, g.cols), mask).map_err(|e| bad(e.to_string()))?;
    out.set_item("sun_mask", m.into_pyarray(py))?;
    descriptions.set_item("sun_mask", pm::SUN_MASK_DESCRIPTION)?;
    if let Some(e) = earth_f {
        out.set_item("earth_fraction", grid2(e)?.into_pyarray(py))?;
        descriptions.set_item("earth_fraction", pm::EARTH_FRACTION_DESCRIPTION)?;
    }
    out.set_item("descriptions", descriptions)?;
    out.set_item("metadata", metadata_dict(py, &items)?)?;
    out.set_item("transform", geotransform(&g))?;
    out.set_item("crs_wkt", wkt_of(&stack.layers[0].projection))?;
    Ok(out)
}

/// The `name` → value items of a GeoTIFF's metadata as a Python dict (insertion order kept).
fn metadata_dict<'py>(py: Python<'py>, items: &[(String, String)]) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    for (k, v) in items {
        d.set_item(k, v)?;
    }
    Ok(d)
}

/// `write_geotiff(path, array, terrain, description, unit="", metadata=None)`: writes a
/// `(rows, cols)` float32 (NaN = nodata) or uint8 (255 = nodata) array on the terrain's finest
/// grid as the CLI writes its maps (a Cloud-Optimized GeoTIFF with the same georeferencing, band
/// description, unit and metadata items, in the dict's order; atomically). With a map's
/// `descriptions[name]`, `units[name]` and `metadata`, the file is the CLI's byte for byte.
#[pyfunction]
#[pyo3(signature = (path, array, terrain, description, unit = "", metadata = None))]
fn write_geotiff(
    py: Python<'_>,
    path: PathBuf,
    array: &Bound<'_, PyAny>,
    terrain: &Terrain,
    description: &str,
    unit: &str,
    metadata: Option<&Bound<'_, PyDict>>,
) -> PyResult<()> {
    let mut items: Vec<(String, String)> = Vec::new();
    if let Some(md) = metadata {
        for (k, v) in md.iter() {
            items.push((k.extract()?, v.str()?.extract()?));
        }
    }
    let info = penumbra::model::RasterInfo {
        description,
        unit,
        items,
    };
    let dem = &terrain.stack.layers[0];
    let (rows, cols) = (dem.grid.rows, dem.grid.cols);
    let shape: (usize, usize) = array.getattr("shape")?.extract()?;
    if shape != (rows, cols) {
        return Err(bad(format!(
            "write_geotiff: array of shape {shape:?} on a {rows} x {cols} grid"
        )));
    }
    let kind: String = array.getattr("dtype")?.getattr("kind")?.extract()?;
    let flat = array.call_method0("ravel")?;
    if kind == "u" {
        let v: Vec<u8> = flat.call_method1("astype", ("uint8",))?.extract()?;
        py.allow_threads(|| penumbra::model::write_on(dem, &path, &v, &info))
            .map_err(py_err)
    } else {
        let v: Vec<f32> = flat.call_method1("astype", ("float32",))?.extract()?;
        py.allow_threads(|| penumbra::model::write_on(dem, &path, &v, &info))
            .map_err(py_err)
    }
}

// --- render -----------------------------------------------------------------------------------------

/// `exposure=`: `"sequence"` (the default; for one frame: its own, never brighter than polar
/// daylight), `"auto"` (per frame, no floor) or a number in 1/(W m⁻² sr⁻¹).
#[derive(FromPyObject)]
enum ExposureArg {
    Value(f64),
    Name(String),
}

/// `render(terrain, utc, lat_deg, lon_deg, camera="site", …)`: a frame of the terrain at one
/// epoch, as `penumbra render` draws it (the same code, through a temporary file): `(image,
/// radiance)`, `image` an `(height, width, 3)` uint8 array (the PNG), `radiance` an
/// `(height, width)` float32 array of terrain radiance, W m⁻² sr⁻¹ (NaN = sky). Site camera:
/// `height_m` above the ground, `look_az_deg`, `look_el_deg`; orbit camera: `altitude_km` above
/// the sphere, looking at (`target_lat_deg`, `target_lon_deg`).
#[pyfunction]
#[pyo3(signature = (terrain, utc, lat_deg, lon_deg, camera = "site", height_m = 2.0, look_az_deg = 0.0, look_el_deg = 0.0, altitude_km = None, target_lat_deg = None, target_lon_deg = None, fov_deg = 60.0, width = 640, height = 400, brdf = "hapke", exposure = None, kernels = None, abcorr = "lt+s", backend = "auto", observer_height_m = None, width_px = None, height_px = None, annotate = true))]
fn render<'py>(
    py: Python<'py>,
    terrain: &Terrain,
    utc: &str,
    lat_deg: f64,
    lon_deg: f64,
    camera: &str,
    height_m: f64,
    look_az_deg: f64,
    look_el_deg: f64,
    altitude_km: Option<f64>,
    target_lat_deg: Option<f64>,
    target_lon_deg: Option<f64>,
    fov_deg: f64,
    width: u32,
    height: u32,
    brdf: &str,
    exposure: Option<ExposureArg>,
    kernels: Option<PathBuf>,
    abcorr: &str,
    backend: &str,
    observer_height_m: Option<f64>,
    width_px: Option<u32>,
    height_px: Option<u32>,
    annotate: bool,
) -> PyResult<(Bound<'py, PyAny>, Bound<'py, PyAny>)> {
    use penumbra::products::render::{BrdfChoice, CameraKind, CameraSpec, RenderOptions};
    // The command line's names (`observer_height_m`, `width_px`, `height_px`) win over the old
    // ones (`height_m`, `width`, `height`), which stay accepted.
    let height_m = observer_height_m.unwrap_or(height_m);
    let width = width_px.unwrap_or(width);
    let height = height_px.unwrap_or(height);
    let kind = match camera {
        "site" => CameraKind::Site,
        "orbit" => CameraKind::Orbit,
        o => return Err(bad(format!("camera '{o}': use site or orbit"))),
    };
    let brdf = match brdf {
        "hapke" => BrdfChoice::Hapke,
        "lambert" => BrdfChoice::Lambert,
        o => return Err(bad(format!("brdf '{o}': use hapke or lambert"))),
    };
    let backend: penumbra::gpu::Backend = backend
        .parse()
        .map_err(|_| bad(format!("backend '{backend}': use cpu, gpu or auto")))?;
    let epoch = eph::time::parse_utc(utc).map_err(|e| bad(e.to_string()))?;
    let dir = tempfile::tempdir().map_err(|e| bad(e.to_string()))?;
    let (png, tif) = (dir.path().join("frame.png"), dir.path().join("frame.tif"));
    let opts = RenderOptions {
        terrain: terrain.source.clone(),
        width,
        height,
        brdf,
        albedo: None,
        exposure: match exposure {
            None => penumbra::render::Exposure::default(),
            Some(ExposureArg::Value(e)) => e.to_string().parse().map_err(bad)?,
            Some(ExposureArg::Name(n)) => n.parse().map_err(bad)?,
        },
        out: png.clone(),
        out_radiance: Some(tif.clone()),
        abcorr: self::abcorr(abcorr)?,
        backend,
        kernels: penumbra::products::KernelSource { dir: kernels },
        annotate,
    };
    let spec = CameraSpec {
        kind,
        lat_deg,
        lon_deg,
        height_m,
        look_az_deg,
        look_el_deg,
        altitude_km,
        target_lat_deg,
        target_lon_deg,
        fov_deg,
    };
    let (rgb, radiance) = py
        .allow_threads(|| -> anyhow::Result<_> {
            let pose = spec.pose()?;
            penumbra::products::render::render_frames(&opts, &[(epoch, pose)])?;
            let rgb = image::open(&png)?.to_rgb8().into_raw();
            let mut dec = tiff::decoder::Decoder::new(std::fs::File::open(&tif)?)?;
            let radiance = match dec.read_image()? {
                tiff::decoder::DecodingResult::F32(v) => v,
                _ => anyhow::bail!("the radiance TIFF is not float32"),
            };
            Ok((rgb, radiance))
        })
        .map_err(py_err)?;
    let (h, w) = (height as usize, width as usize);
    let rgb =
        numpy::ndarray::Array3::from_shape_vec((h, w, 3), rgb).map_err(|e| bad(e.to_string()))?;
    let radiance = Array2::from_shape_vec((h, w), radiance).map_err(|e| bad(e.to_string()))?;
    Ok((
        rgb.into_pyarray(py).into_any(),
        radiance.into_pyarray(py).into_any(),
    ))
}

/// The limb darkening law named `text`.
fn limb_law(text: &str) -> PyResult<penumbra::illum::LimbLaw> {
    use penumbra::illum::LimbLaw;
    Ok(match text {
        "none" => LimbLaw::None,
        "eddington" => LimbLaw::Eddington,
        "allen550nm" => LimbLaw::Allen550nm,
        o => {
            return Err(bad(format!(
                "limb_darkening '{o}': use none, eddington or allen550nm"
            )));
        }
    })
}

/// The map engine named `name` (`auto`: `None`), as the command line's `--engine` takes it.
fn engine_choice(name: &str) -> PyResult<Option<penumbra::model::MapEngineKind>> {
    penumbra::model::MapEngineKind::parse_choice(name).map_err(bad)
}

// --- sharded maps -----------------------------------------------------------------------------------

/// `map_shard(terrain, start, stop, step, out_dir, shard, shards, …)`: shard `shard` of `shards`
/// of a map over `start` … `stop` every `step` (UTC strings and a step such as `"1h"`): the CLI's
/// `penumbra map --start --stop --step --shard I/N --out-dir` (horizons engine), writing the
/// partial (`shard.json`, `shard.pnbstat`) into `out_dir`. Returns the manifest as a dict.
/// Shards made here and by the CLI with the same parameters and inputs merge together.
#[pyfunction]
#[pyo3(signature = (terrain, start, stop, step, out_dir, shard, shards, observer_height_m = 2.0, kernels = None, abcorr = "lt+s", horizons = None, azimuths = 720, max_step = 16, limb_darkening = "eddington", stations = "none", station_mask_deg = 10.0, resume = false))]
fn map_shard<'py>(
    py: Python<'py>,
    terrain: &Terrain,
    start: &str,
    stop: &str,
    step: &str,
    out_dir: PathBuf,
    shard: usize,
    shards: usize,
    observer_height_m: f64,
    kernels: Option<PathBuf>,
    abcorr: &str,
    horizons: Option<PathBuf>,
    azimuths: usize,
    max_step: u32,
    limb_darkening: &str,
    stations: &str,
    station_mask_deg: f64,
    resume: bool,
) -> PyResult<Bound<'py, PyAny>> {
    use penumbra::compute::range::HorizonsFrom;
    use penumbra::products::map as pm;
    let shard = pm::shard::Shard::parse(&format!("{shard}/{shards}"))
        .map_err(|e| bad(e.replace("--shard", "map_shard")))?;
    if !(4..=100_000).contains(&azimuths) || !(1..=64).contains(&max_step) {
        return Err(bad(
            "map_shard: azimuths must be 4 … 100000 and max_step 1 … 64",
        ));
    }
    let epochs = EpochRange::parse(start, stop, step).map_err(|e| refused("map_shard", e))?;
    let req = pm::MapRequest {
        terrain: terrain.source.clone(),
        kernels: penumbra::products::KernelSource { dir: kernels },
        abcorr: self::abcorr(abcorr)?,
        settings: pm::MapSettings {
            observer_height: observer_height(observer_height_m)?,
            horizons: match horizons {
                Some(p) => HorizonsFrom::File(p),
                None => HorizonsFrom::Sweep { azimuths, max_step },
            },
            limb: limb_law(limb_darkening)?,
            stations: penumbra::comms::Stations::parse(stations),
            station_mask_deg,
            ..pm::MapSettings::default()
        },
        task: pm::MapTask::Range {
            epochs,
            files: pm::RangeFiles {
                out_dir: out_dir.clone(),
                resume,
                shard: Some(shard),
            },
        },
    };
    py.allow_threads(|| penumbra::products::map::run(&req))
        .map_err(py_err)?;
    let text = std::fs::read_to_string(out_dir.join(penumbra::products::map::shard::MANIFEST))
        .map_err(|e| bad(format!("reading the shard's manifest: {e}")))?;
    let json = py.import("json")?;
    json.call_method1("loads", (text,))
}

/// `merge_shards(out_dir, shard_dirs)`: `penumbra merge --out-dir OUT DIR…`: combines the
/// partials of all shards of one job into its maps (the bytes of a single-machine run).
#[pyfunction]
fn merge_shards(py: Python<'_>, out_dir: PathBuf, shard_dirs: Vec<PathBuf>) -> PyResult<()> {
    py.allow_threads(|| penumbra::products::map::shard::merge(&out_dir, &shard_dirs))
        .map_err(py_err)
}

// --- scenarios --------------------------------------------------------------------------------------

/// `run_scenario(path, out_dir=None, kernels=None, resume=False)`: runs a scenario file as
/// `penumbra run` (`resume=True`: `--resume`, carrying on an unfinished run in the folder).
#[pyfunction]
#[pyo3(signature = (path, out_dir = None, kernels = None, resume = false))]
fn run_scenario(
    py: Python<'_>,
    path: PathBuf,
    out_dir: Option<PathBuf>,
    kernels: Option<PathBuf>,
    resume: bool,
) -> PyResult<()> {
    let req = penumbra::scenario::run::RunRequest {
        scenario: path,
        out_dir,
        kernels,
        resume,
    };
    py.allow_threads(|| penumbra::scenario::run::run_file(&req))
        .map_err(py_err)
}

/// The module.
#[pymodule]
fn _penumbra(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("PenumbraError", m.py().get_type::<PenumbraError>())?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    m.add_class::<Terrain>()?;
    m.add_function(wrap_pyfunction!(time_range, m)?)?;
    m.add_function(wrap_pyfunction!(ephem, m)?)?;
    m.add_function(wrap_pyfunction!(station_elevations, m)?)?;
    m.add_function(wrap_pyfunction!(horizon, m)?)?;
    m.add_function(wrap_pyfunction!(series, m)?)?;
    m.add_function(wrap_pyfunction!(landing_windows, m)?)?;
    m.add_function(wrap_pyfunction!(map_statistics, m)?)?;
    m.add_function(wrap_pyfunction!(map_light, m)?)?;
    m.add_function(wrap_pyfunction!(map_shard, m)?)?;
    m.add_function(wrap_pyfunction!(merge_shards, m)?)?;
    m.add_function(wrap_pyfunction!(write_geotiff, m)?)?;
    m.add_function(wrap_pyfunction!(render, m)?)?;
    m.add_function(wrap_pyfunction!(run_scenario, m)?)?;
    Ok(())
}
