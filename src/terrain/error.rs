//! The terrain subsystem's error type. Every variant prints as one line that names the file (or
//! the point) and what was wrong, so the binary can show it as is.

use crate::output::OutputError;

/// Errors of the terrain subsystem (DEM reading and writing, layers, model space).
#[derive(Debug, thiserror::Error)]
pub enum DemError {
    /// The file could not be opened or read.
    #[error("reading DEM {path}: {source}")]
    Io {
        /// The file.
        path: String,
        /// The underlying I/O error.
        #[source]
        source: std::io::Error,
    },
    /// The file is not a TIFF (bad signature).
    #[error("reading DEM {path}: not a TIFF file ({detail})")]
    NotTiff {
        /// The file.
        path: String,
        /// What the decoder saw.
        detail: String,
    },
    /// The file ends before the data its header announces (truncated download or copy).
    #[error("reading DEM {path}: file is truncated ({detail})")]
    Truncated {
        /// The file.
        path: String,
        /// What the decoder was reading.
        detail: String,
    },
    /// The TIFF structure or its compressed data is invalid.
    #[error("reading DEM {path}: invalid TIFF: {detail}")]
    Decode {
        /// The file.
        path: String,
        /// The decoder's message.
        detail: String,
    },
    /// The sample type is not one penumbra reads (float64, float32, int32, int16, uint16, uint8).
    #[error(
        "reading DEM {path}: unsupported sample format {detail} (supported: float64, float32, int32, int16, uint16, uint8)"
    )]
    UnsupportedSampleFormat {
        /// The file.
        path: String,
        /// The sample format found, e.g. `64-bit float`.
        detail: String,
    },
    /// The raster has more than one band.
    #[error("reading DEM {path}: {bands} bands; a DEM must have exactly one band")]
    MultiBand {
        /// The file.
        path: String,
        /// Number of samples per pixel.
        bands: u16,
    },
    /// The GeoTIFF georeferencing (pixel scale, tie point, transformation) is missing or unusable.
    #[error("reading DEM {path}: georeferencing: {detail}")]
    Georeferencing {
        /// The file.
        path: String,
        /// What is missing or unsupported.
        detail: String,
    },
    /// The coordinate reference system is not polar stereographic or equirectangular on a lunar
    /// sphere.
    #[error(
        "reading DEM {path}: unknown or unsupported CRS: {detail} (supported: polar stereographic, equirectangular on the lunar sphere)"
    )]
    UnknownCrs {
        /// The file.
        path: String,
        /// What the GeoKeys say.
        detail: String,
    },
    /// The file's content is refused: sizes it declares beyond the file or the memory budget,
    /// heights that are not heights above the lunar sphere (infinite, radii, out of bounds).
    #[error("reading DEM {path}: {detail}")]
    Rejected {
        /// The file.
        path: String,
        /// What is wrong.
        detail: String,
    },
    /// Every pixel is nodata.
    #[error("reading DEM {path}: every pixel is nodata")]
    AllNodata {
        /// The file.
        path: String,
    },
    /// No layer of the terrain stack has a surface at a point.
    #[error("no DEM layer covers latitude {lat_deg:.6} deg, longitude {lon_deg:.6} deg")]
    OutsideLayers {
        /// Planetocentric latitude, degrees.
        lat_deg: f64,
        /// East longitude, degrees.
        lon_deg: f64,
    },
    /// A multi-band file is not laid out as penumbra writes them.
    #[error(
        "{path}: {detail}: not a penumbra multi-band file (write one with `penumbra horizon-map sweep`)"
    )]
    NotPenumbraMultiBand {
        /// The file.
        path: String,
        /// What differs.
        detail: String,
    },
    /// An argument (grid size, pixel size, data length) is invalid.
    #[error("invalid terrain parameter: {0}")]
    InvalidParameter(String),
    /// Encoding a GeoTIFF failed.
    #[error("writing GeoTIFF {path}: {detail}")]
    Encode {
        /// The file.
        path: String,
        /// The encoder's message.
        detail: String,
    },
    /// Writing an output file failed.
    #[error(transparent)]
    Output(#[from] OutputError),
}

/// Result type of the terrain subsystem.
pub type Result<T, E = DemError> = std::result::Result<T, E>;
