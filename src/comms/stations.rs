//! Ground stations: the three DSN complexes' reference antennas, or a user's CSV table.

use std::path::{Path, PathBuf};

use nalgebra::Vector3;

use crate::ephem::earth;

/// A station list could not be built.
#[derive(Debug, thiserror::Error)]
pub enum StationError {
    /// A value is out of range or malformed.
    #[error("station '{name}': {why}")]
    Bad {
        /// The station.
        name: String,
        /// What is wrong.
        why: String,
    },
    /// The stations file is unreadable or malformed.
    #[error("stations file {path}: {why}")]
    File {
        /// The file.
        path: String,
        /// What is wrong.
        why: String,
    },
}

/// A ground station: geodetic position on WGS84 and an elevation mask.
#[derive(Debug, Clone, PartialEq)]
pub struct Station {
    name: String,
    lat_deg: f64,
    lon_deg: f64,
    height_m: f64,
    mask_deg: f64,
    itrs_m: Vector3<f64>,
}

impl Station {
    /// A station at geodetic latitude / east longitude (deg) and height above the WGS84
    /// ellipsoid (m) with an elevation mask (deg). Latitude in [−90, 90], longitude in
    /// [−360, 360], height within −1 km … 100 km, mask in [0, 90).
    pub fn new(
        name: &str,
        lat_deg: f64,
        lon_deg: f64,
        height_m: f64,
        mask_deg: f64,
    ) -> Result<Self, StationError> {
        let bad = |why: String| StationError::Bad {
            name: name.to_string(),
            why,
        };
        if name.trim().is_empty() || name.contains(['\n', '\r']) {
            return Err(bad("a station needs a one-line name".into()));
        }
        if !(lat_deg.is_finite() && (-90.0..=90.0).contains(&lat_deg)) {
            return Err(bad(format!("latitude {lat_deg} deg is outside [-90, 90]")));
        }
        if !(lon_deg.is_finite() && (-360.0..=360.0).contains(&lon_deg)) {
            return Err(bad(format!(
                "longitude {lon_deg} deg is outside [-360, 360]"
            )));
        }
        if !(height_m.is_finite() && (-1000.0..=100_000.0).contains(&height_m)) {
            return Err(bad(format!(
                "height {height_m} m is outside -1000 .. 100000 m"
            )));
        }
        check_mask(name, mask_deg)?;
        Ok(Station {
            name: name.trim().to_string(),
            lat_deg,
            lon_deg,
            height_m,
            mask_deg,
            itrs_m: earth::itrs_from_geodetic_m(lat_deg, lon_deg, height_m),
        })
    }

    /// A station at an ITRS position (m), its geodetic coordinates computed (WGS84).
    fn from_itrs_m(name: &str, itrs_m: Vector3<f64>, mask_deg: f64) -> Result<Self, StationError> {
        let (lat_deg, lon_deg, height_m) = geodetic_from_itrs(&itrs_m);
        let mut s = Station::new(name, lat_deg, lon_deg, height_m, mask_deg)?;
        s.itrs_m = itrs_m;
        Ok(s)
    }

    /// The name.
    pub fn name(&self) -> &str {
        &self.name
    }
    /// Geodetic latitude, degrees.
    pub fn lat_deg(&self) -> f64 {
        self.lat_deg
    }
    /// East longitude, degrees.
    pub fn lon_deg(&self) -> f64 {
        self.lon_deg
    }
    /// Height above the WGS84 ellipsoid, metres.
    pub fn height_m(&self) -> f64 {
        self.height_m
    }
    /// Elevation mask, degrees.
    pub fn mask_deg(&self) -> f64 {
        self.mask_deg
    }
    /// Position in the ITRS, metres.
    pub fn itrs_m(&self) -> Vector3<f64> {
        self.itrs_m
    }
    /// The local up (ellipsoid normal) in the ITRS.
    pub fn itrs_up(&self) -> Vector3<f64> {
        earth::itrs_up(self.lat_deg, self.lon_deg)
    }
}

fn check_mask(name: &str, mask_deg: f64) -> Result<(), StationError> {
    if mask_deg.is_finite() && (0.0..90.0).contains(&mask_deg) {
        Ok(())
    } else {
        Err(StationError::Bad {
            name: name.to_string(),
            why: format!("elevation mask {mask_deg} deg is outside [0, 90)"),
        })
    }
}

/// Geodetic latitude, longitude (deg) and height (m) on WGS84 of an ITRS position (m), by
/// Bowring's iteration (converged to < 1 mm in three steps for points near the surface).
fn geodetic_from_itrs(p: &Vector3<f64>) -> (f64, f64, f64) {
    let (a, f) = (earth::WGS84_A_M, earth::WGS84_F);
    let e2 = f * (2.0 - f);
    let rho = p.x.hypot(p.y);
    let mut lat = p.z.atan2(rho * (1.0 - e2));
    let mut h = 0.0;
    for _ in 0..6 {
        let s = lat.sin();
        let n = a / (1.0 - e2 * s * s).sqrt();
        h = rho / lat.cos() - n;
        lat = p.z.atan2(rho * (1.0 - e2 * n / (n + h)));
    }
    (lat.to_degrees(), p.y.atan2(p.x).to_degrees(), h)
}

/// Where the DSN reference antennas' coordinates come from.
pub const DSN_SOURCE: &str = "DSN 810-005 Module 301 (ITRF, epoch 2003.0) as tabulated by Lee et \
     al. 2023, J. Astron. Space Sci. 40(2), 79, table 1; DSS 14 and DSS 43 agree with JPL's \
     ITRF2005 list (IAU Commission 4, 2008) to 6 cm";

/// The DSN's three complexes by their 70 m reference antennas (DSS 14 Goldstone, DSS 43
/// Canberra, DSS 63 Madrid, about 4.25° W), all with `mask_deg`. Source: [`DSN_SOURCE`].
pub fn dsn(mask_deg: f64) -> Result<Vec<Station>, StationError> {
    [
        ("DSS-14", [-2_353_621.420, -4_641_341.472, 3_677_052.318]),
        ("DSS-43", [-4_460_894.917, 2_682_361.507, -3_674_748.152]),
        ("DSS-63", [4_849_092.518, -360_180.348, 4_115_109.251]),
    ]
    .into_iter()
    .map(|(name, xyz)| Station::from_itrs_m(name, Vector3::from(xyz), mask_deg))
    .collect()
}

/// Which stations a run uses: `dsn`, `none` or a CSV file (`--stations`, scenario `stations`,
/// Python `stations=`).
#[derive(Debug, Clone, PartialEq, Default)]
pub enum Stations {
    /// The three DSN complexes ([`dsn`]).
    #[default]
    Dsn,
    /// No stations: no link columns or statistics.
    None,
    /// A CSV table ([`read_stations_file`]).
    File(PathBuf),
}

impl Stations {
    /// `dsn`, `none` or a file path.
    pub fn parse(text: &str) -> Self {
        match text {
            "dsn" => Stations::Dsn,
            "none" => Stations::None,
            path => Stations::File(PathBuf::from(path)),
        }
    }

    /// The text [`Stations::parse`] reads back.
    pub fn label(&self) -> String {
        match self {
            Stations::Dsn => "dsn".into(),
            Stations::None => "none".into(),
            Stations::File(p) => p.display().to_string(),
        }
    }

    /// The stations, with `mask_deg` for DSN and for file rows without a mask; `None` for
    /// [`Stations::None`]. A file must hold at least one station.
    pub fn resolve(&self, mask_deg: f64) -> Result<Option<Vec<Station>>, StationError> {
        check_mask("default", mask_deg).map_err(|_| StationError::Bad {
            name: "--station-mask-deg".into(),
            why: format!("elevation mask {mask_deg} deg is outside [0, 90)"),
        })?;
        match self {
            Stations::Dsn => dsn(mask_deg).map(Some),
            Stations::None => Ok(None),
            Stations::File(p) => read_stations_file(p, mask_deg).map(Some),
        }
    }
}

impl serde::Serialize for Stations {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_str(&self.label())
    }
}

impl<'de> serde::Deserialize<'de> for Stations {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let text = <String as serde::Deserialize>::deserialize(d)?;
        Ok(Stations::parse(&text))
    }
}

/// The stations as `run.json` records them: name, geodetic position, mask, and where they come
/// from (`dsn` and its source, or the file with its sha256).
pub fn stations_record(choice: &Stations, stations: &[Station]) -> serde_json::Value {
    let source = match choice {
        Stations::Dsn => serde_json::json!({ "dsn": DSN_SOURCE }),
        Stations::None => serde_json::Value::Null,
        Stations::File(p) => match crate::output::InputFile::of(p) {
            Ok(f) => serde_json::json!({ "file": f }),
            Err(_) => serde_json::json!({ "file": p.display().to_string() }),
        },
    };
    serde_json::json!({
        "source": source,
        "stations": stations.iter().map(|s| serde_json::json!({
            "name": s.name(),
            "lat_deg": s.lat_deg(),
            "lon_deg": s.lon_deg(),
            "height_m": s.height_m(),
            "mask_deg": s.mask_deg(),
        })).collect::<Vec<_>>(),
        "frame": "geodetic, WGS84; ITRS to GCRS by IAU 2006/2000B, UT1 = UTC (docs/comms.md)",
    })
}

/// Most stations in one file.
const MAX_STATIONS: usize = 1000;

/// Reads a stations CSV: a header with `name`, `lat_deg`, `lon_deg`, `height_m` (geodetic,
/// WGS84) and optionally `mask_deg` (else `default_mask_deg`), one station per row. Errors name
/// the file and the row.
pub fn read_stations_file(
    path: &Path,
    default_mask_deg: f64,
) -> Result<Vec<Station>, StationError> {
    let file_err = |why: String| StationError::File {
        path: path.display().to_string(),
        why,
    };
    let text = crate::output::guard::read_small_text(path, 1 << 20)
        .map_err(|e| file_err(e.to_string()))?;
    let mut rdr = csv::ReaderBuilder::new()
        .trim(csv::Trim::All)
        .comment(Some(b'#'))
        .from_reader(text.as_bytes());
    let header: Vec<String> = rdr
        .headers()
        .map_err(|e| file_err(e.to_string()))?
        .iter()
        .map(|h| h.to_ascii_lowercase())
        .collect();
    let col = |name: &str| header.iter().position(|h| h == name);
    let (Some(ni), Some(lai), Some(loi), Some(hi)) =
        (col("name"), col("lat_deg"), col("lon_deg"), col("height_m"))
    else {
        return Err(file_err(format!(
            "the header must name name, lat_deg, lon_deg, height_m (and optionally mask_deg); it has {}",
            header.join(",")
        )));
    };
    let mi = col("mask_deg");
    let mut out = Vec::new();
    for (i, rec) in rdr.records().enumerate() {
        let row = i + 2;
        let rec = rec.map_err(|e| file_err(format!("row {row}: {e}")))?;
        let field = |c: usize| rec.get(c).unwrap_or("");
        let num = |c: usize, what: &str| -> Result<f64, StationError> {
            field(c)
                .parse::<f64>()
                .map_err(|_| file_err(format!("row {row}: {what} '{}' is not a number", field(c))))
        };
        let mask = match mi {
            Some(c) if !field(c).is_empty() => num(c, "mask_deg")?,
            _ => default_mask_deg,
        };
        let s = Station::new(
            field(ni),
            num(lai, "lat_deg")?,
            num(loi, "lon_deg")?,
            num(hi, "height_m")?,
            mask,
        )
        .map_err(|e| file_err(format!("row {row}: {e}")))?;
        if out.iter().any(|o: &Station| o.name() == s.name()) {
            return Err(file_err(format!(
                "row {row}: station '{}' appears twice",
                s.name()
            )));
        }
        out.push(s);
        if out.len() > MAX_STATIONS {
            return Err(file_err(format!("more than {MAX_STATIONS} stations")));
        }
    }
    if out.is_empty() {
        return Err(file_err(
            "no stations (an empty list; use --stations none for no link)".into(),
        ));
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dsn_complexes_are_where_they_should_be() {
        let s = dsn(10.0).unwrap();
        let near = |st: &Station, lat: f64, lon: f64| {
            (st.lat_deg() - lat).abs() < 0.01 && (st.lon_deg() - lon).abs() < 0.01
        };
        // Goldstone 35.426° N 116.890° W, Canberra 35.402° S 148.981° E, Madrid 40.431° N 4.248° W.
        assert!(near(&s[0], 35.426, -116.890), "{:?}", s[0]);
        assert!(near(&s[1], -35.402, 148.981), "{:?}", s[1]);
        assert!(near(&s[2], 40.431, -4.248), "{:?}", s[2]);
        for st in &s {
            assert!((0.0..1100.0).contains(&st.height_m()), "{st:?}");
            let back = earth::itrs_from_geodetic_m(st.lat_deg(), st.lon_deg(), st.height_m());
            assert!((back - st.itrs_m()).norm() < 1e-3, "{st:?}");
        }
    }

    #[test]
    fn bad_stations_are_refused() {
        assert!(Station::new("x", 95.0, 0.0, 0.0, 10.0).is_err());
        assert!(Station::new("x", 0.0, 0.0, 0.0, -5.0).is_err());
        assert!(Station::new("", 0.0, 0.0, 0.0, 5.0).is_err());
        assert!(Stations::Dsn.resolve(-5.0).is_err());
    }
}
